# CHOLMOD (SuiteSparse; Debian: libsuitesparse-dev): the supernodal Cholesky of the direct linear
# solver (server/sim/solver/direct_solver.cpp), through Eigen's CholmodSupport module. Debian's
# SuiteSparse 5 ships no CMake config or pkg-config file: the header and library are found by name.
find_path(CHOLMOD_INCLUDE_DIR cholmod.h PATH_SUFFIXES suitesparse REQUIRED)
find_library(CHOLMOD_LIBRARY cholmod REQUIRED)
add_library(gd_cholmod INTERFACE)
target_include_directories(gd_cholmod INTERFACE ${CHOLMOD_INCLUDE_DIR})
target_link_libraries(gd_cholmod INTERFACE ${CHOLMOD_LIBRARY})
