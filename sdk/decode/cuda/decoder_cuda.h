// Internal: the CUDA launchers of the decoder (sdk/decode/decoder_gpu.h's GPU half). Only
// built, and only included, when SLS_HAVE_CUDA is defined.
#pragma once

#include <cstddef>
#include <cstdint>

#include <cuda_runtime_api.h>

#include "sdk/decode/decoder_gpu.h"

namespace sls::detail {

// One thread per pixel: decode_pixel + decode_and_triangulate_pixel over a device-resident
// stack (image k of the set at stack + k * plane_stride, row-major width * height pixels),
// the ray map's rays and valid flags. Asynchronous on `stream`.
void launch_decode_cuda(const DecodeParams& decode, const TriangulationParams& triangulation, int width, int height,
                        const std::uint16_t* stack, std::size_t plane_stride, const Vec3f* rays,
                        const std::uint8_t* ray_valid, const DecodeOutputsDevice& outputs, cudaStream_t stream);

// The stack check where the stack is (stack_check.cu): into *largest (which the caller set to
// INT_MIN) the largest white - black (both indices >= 0) or else the brightest pixel of any
// image; and, for a usable plan and a grid, one thread per grid pixel judged as the CPU judges
// it (judge_stack_pixel) into `counts` (plan.slot_count x kStackCheckBins, zeroed by the
// caller) and the lit pixels into *lit (zeroed). Asynchronous on `stream`.
void launch_stack_check(const std::uint16_t* stack, std::size_t plane_stride, int images, const StackCheckGrid& grid,
                        const StackCheckPlan& plan, int* largest, std::uint32_t* counts, unsigned long long* lit,
                        cudaStream_t stream);

}  // namespace sls::detail
