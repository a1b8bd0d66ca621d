# Use ccache when present: rebuilds after a clean checkout or a branch switch stay cheap.
find_program(GD_CCACHE ccache)
if(GD_CCACHE)
  set(CMAKE_C_COMPILER_LAUNCHER ${GD_CCACHE})
  set(CMAKE_CXX_COMPILER_LAUNCHER ${GD_CCACHE})
  set(CMAKE_CUDA_COMPILER_LAUNCHER ${GD_CCACHE})
endif()
