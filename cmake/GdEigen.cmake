find_package(Eigen3 3.3 REQUIRED NO_MODULE)
