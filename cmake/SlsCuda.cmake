# CUDA is optional at configure time: the CUDA backends build when nvcc is found
# (/usr/local/cuda on our machines); without it every stage still has its CPU backend.
set(SLS_HAVE_CUDA OFF)
if(SLS_WITH_CUDA)
  if(NOT CMAKE_CUDA_COMPILER AND EXISTS /usr/local/cuda/bin/nvcc)
    set(CMAKE_CUDA_COMPILER /usr/local/cuda/bin/nvcc)
  endif()
  include(CheckLanguage)
  check_language(CUDA)
  if(CMAKE_CUDA_COMPILER)
    if(NOT DEFINED CMAKE_CUDA_ARCHITECTURES)
      # "90": sm_90 machine code (H100, H200) plus compute_90 PTX for later GPUs to JIT;
      # "87-real": sm_87 machine code for Jetson Orin, the scanner heads' embedded GPU (issue 22).
      # Xavier's sm_72 cannot be added: CUDA 13 builds for sm_75 and later only.
      set(CMAKE_CUDA_ARCHITECTURES 87-real 90)
    endif()
    enable_language(CUDA)
    set(CMAKE_CUDA_STANDARD 17)
    set(CMAKE_CUDA_STANDARD_REQUIRED ON)
    find_package(CUDAToolkit REQUIRED)
    set(SLS_HAVE_CUDA ON)
  else()
    message(STATUS "nvcc not found: building CPU backends only")
  endif()
endif()
