// The cudaStream_t behind a GpuStream (sdk/core/gpu_stream.h), for CUDA backend sources.
#pragma once

#include <cuda_runtime_api.h>

#include "sdk/core/gpu_stream.h"

namespace sls {

inline cudaStream_t cuda_stream(const GpuStream& stream) { return static_cast<cudaStream_t>(stream.native()); }

}  // namespace sls
