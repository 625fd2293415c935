// Marks functions that compile for both the CPU and CUDA backends (DESIGN.md section 6).
// Per-element math lives in *_shared.h headers as SLS_HOST_DEVICE inline free functions
// over plain structs, so nvcc and the host compiler see one body of code.
#pragma once

#if defined(__CUDACC__)
#define SLS_HOST_DEVICE __host__ __device__
#define SLS_DEVICE __device__
#else
#define SLS_HOST_DEVICE
#define SLS_DEVICE
#endif

// The body handed to parallel_for (sdk/core/parallel_for.h): a lambda taking the element's
// index that captures by value and, in CUDA sources, also runs on the device (nvcc's
// --extended-lambda). `parallel_for(device, n, SLS_LAMBDA(std::size_t i) { ... }, stream)`.
#if defined(__CUDACC__)
#define SLS_LAMBDA [=] __host__ __device__
#else
#define SLS_LAMBDA [=]
#endif

// A read of memory no thread writes while the kernel runs, through the GPU's read-only data
// path (__ldg) in device code; a plain read on the CPU. The same value either way.
template <typename T>
SLS_HOST_DEVICE inline T load_read_only(const T* p) {
#if defined(__CUDA_ARCH__)
  return __ldg(p);
#else
  return *p;
#endif
}
