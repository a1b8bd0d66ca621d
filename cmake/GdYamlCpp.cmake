# yaml-cpp (Debian: libyaml-cpp-dev): RGBench's experiment library and cloth-parameter files.
find_package(yaml-cpp REQUIRED)
