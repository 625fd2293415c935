// Internal: the CUDA launchers of the ray map (sdk/core/ray_map.h). Only built, and only
// included, when SLS_HAVE_CUDA is defined; ray_map.cpp dispatches here.
#pragma once

#include <cstdint>

#include <cuda_runtime_api.h>

#include "sdk/core/camera_model_shared.h"
#include "sdk/core/math_shared.h"

namespace sls::detail {

// Fills width*height rays and valid flags (device memory) on `stream`; asynchronous.
void launch_ray_map_cuda(const CameraIntrinsics& intrinsics, Vec3f* rays_device, std::uint8_t* valid_device,
                    cudaStream_t stream);

// Computes the whole map on the current device into host arrays of width*height entries,
// on a stream of its own, and waits for it.
void compute_ray_map_cuda(const CameraIntrinsics& intrinsics, Vec3f* rays_host, std::uint8_t* valid_host);

}  // namespace sls::detail
