// Turns CUDA runtime errors into sls::Error (device, or out of memory) naming the call and
// where it was made. Only CUDA backend sources include this.
#pragma once

#include <cuda_runtime_api.h>

#include "sdk/core/error.h"

namespace sls {

[[noreturn]] inline void throw_cuda_error(cudaError_t status, const char* call, const char* file, int line) {
  const ErrorCode code = (status == cudaErrorMemoryAllocation) ? ErrorCode::kOutOfMemory : ErrorCode::kDevice;
  throw_error(code, "CUDA error {} ({}) in {} at {}:{}", cudaGetErrorName(status), cudaGetErrorString(status),
              call, file, line);
}

}  // namespace sls

#define SLS_CUDA_CHECK(call)                                                        \
  do {                                                                              \
    const cudaError_t sls_cuda_status_ = (call);                                    \
    if (sls_cuda_status_ != cudaSuccess) {                                          \
      (void)cudaGetLastError();                                                     \
      ::sls::throw_cuda_error(sls_cuda_status_, #call, __FILE__, __LINE__);         \
    }                                                                               \
  } while (0)

// After a kernel launch: reports launch-configuration errors at once.
#define SLS_CUDA_CHECK_LAUNCH() SLS_CUDA_CHECK(cudaGetLastError())
