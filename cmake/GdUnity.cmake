# Unity builds (docs/build.md, "Build time"): gd_unity(target BATCH n) compiles the target's C++
# sources n at a time as one translation unit, so the headers they share (Eigen, gtest, gRPC, the
# solver's) are parsed and their templates instantiated once per batch. GD_UNITY=OFF compiles
# every source on its own (what a sanitizer or a debugging session may prefer).
option(GD_UNITY "Compile the libraries' and tests' sources in unity batches" ON)

function(gd_unity target)
  cmake_parse_arguments(arg "" "BATCH" "" ${ARGN})
  if(NOT arg_BATCH)
    set(arg_BATCH 4)
  endif()
  set_target_properties(${target} PROPERTIES UNITY_BUILD ${GD_UNITY} UNITY_BUILD_BATCH_SIZE ${arg_BATCH})
endfunction()
