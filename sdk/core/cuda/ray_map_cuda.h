// Internal: the CUDA loop of the ray map (sdk/core/ray_map.h). Only built, and only included,
// when SLS_HAVE_CUDA is defined; ray_map.cpp dispatches here.
#pragma once

#include <cstdint>

#include "sdk/core/camera_model_shared.h"
#include "sdk/core/device.h"
#include "sdk/core/gpu_stream.h"
#include "sdk/core/math_shared.h"

namespace sls::detail {

// Fills width*height rays and valid flags (memory of `device`) on `stream`; asynchronous.
void fill_ray_map_cuda(const Device& device, const CameraIntrinsics& intrinsics, Vec3f* rays_device,
                       std::uint8_t* valid_device, const GpuStream& stream);

}  // namespace sls::detail
