# GD_WITH_CUDA defaults to ON when nvcc can be found; the CPU build never needs the toolkit.
include(CheckLanguage)
if(NOT DEFINED GD_WITH_CUDA)
  if(NOT CMAKE_CUDA_COMPILER)
    find_program(GD_NVCC nvcc HINTS /usr/local/cuda/bin ENV CUDA_HOME PATH_SUFFIXES bin)
    if(GD_NVCC)
      set(CMAKE_CUDA_COMPILER ${GD_NVCC} CACHE FILEPATH "nvcc")
    endif()
  endif()
  check_language(CUDA)
  if(CMAKE_CUDA_COMPILER)
    set(_gd_cuda_default ON)
  else()
    set(_gd_cuda_default OFF)
  endif()
  option(GD_WITH_CUDA "Build the CUDA backend" ${_gd_cuda_default})
endif()
if(GD_WITH_CUDA)
  # Hopper (H100/H200) is the deployment target: sm_90 machine code and compute_90 PTX, one
  # device pass (a second architecture costs the 2-core CI build about 150 s more). Set before
  # enable_language(CUDA), which otherwise fills in nvcc's own default (sm_75 with CUDA 13: on
  # Hopper the driver then JIT-compiled compute_75 PTX). For an A100 configure with
  # -DCMAKE_CUDA_ARCHITECTURES=80 (or set the CUDAARCHS environment variable).
  if(NOT DEFINED CMAKE_CUDA_ARCHITECTURES AND NOT DEFINED ENV{CUDAARCHS})
    set(CMAKE_CUDA_ARCHITECTURES 90)
  endif()
  enable_language(CUDA)
  # A test build on a machine without a GPU (scripts/test sets it there) only proves the device
  # code compiles: nvcc's fast-compile mode (CUDA 12.8 and later) skips device optimizations and
  # takes ~25% off the CUDA object, the longest compile of the CI build (docs/build.md). Never for
  # binaries that run on a GPU: the kernels are slower.
  option(GD_CUDA_FAST_COMPILE "Compile device code with nvcc -Ofc=max (a CI build without a GPU)" OFF)
  if(GD_CUDA_FAST_COMPILE)
    if(CMAKE_CUDA_COMPILER_VERSION VERSION_GREATER_EQUAL 12.8)
      string(APPEND CMAKE_CUDA_FLAGS " -Ofc=max")
      message(STATUS "GarmentDynamics: CUDA device code compiled fast, unoptimized (GD_CUDA_FAST_COMPILE)")
    else()
      message(STATUS "GarmentDynamics: GD_CUDA_FAST_COMPILE needs nvcc 12.8 or later; ignored")
    endif()
  endif()

  find_package(CUDAToolkit REQUIRED)
  message(STATUS "GarmentDynamics: CUDA backend ON (${CMAKE_CUDA_COMPILER})")
else()
  message(STATUS "GarmentDynamics: CUDA backend OFF")
endif()
