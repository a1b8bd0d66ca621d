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

  find_package(CUDAToolkit REQUIRED)
  message(STATUS "GarmentDynamics: CUDA backend ON (${CMAKE_CUDA_COMPILER})")
else()
  message(STATUS "GarmentDynamics: CUDA backend OFF")
endif()
