# The CPU backend runs per-element loops with OpenMP threads.
find_package(OpenMP REQUIRED COMPONENTS CXX)
