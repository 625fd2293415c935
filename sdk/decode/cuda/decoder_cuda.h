// Internal: the CUDA backend of the decoder (sdk/decode/decoder.h). Only built, and only
// included, when SLS_HAVE_CUDA is defined; decoder.cpp dispatches here. Kept free of Eigen
// and the public headers that carry it, so nvcc sees only the plain per-pixel structs.
#pragma once

#include <cstddef>
#include <cstdint>

#include <cuda_runtime_api.h>

#include "sdk/core/math_shared.h"
#include "sdk/decode/decode_shared.h"
#include "sdk/decode/triangulate_shared.h"

namespace sls::detail {

// Device pointers of the decode outputs, width * height elements each, row-major.
struct DecodeOutputsDevice {
  float* u = nullptr;
  float* v = nullptr;
  float* confidence = nullptr;
  std::uint8_t* mask = nullptr;
  float* depth = nullptr;
};

// Host pointers the outputs are downloaded into (width * height elements each); nullptr: that
// output stays on the device only.
struct DecodeOutputsHost {
  float* u = nullptr;
  float* v = nullptr;
  float* confidence = nullptr;
  std::uint8_t* mask = nullptr;
  float* depth = nullptr;
};

// One thread per pixel: decode_pixel + decode_and_triangulate_pixel over a device-resident
// stack (image k of the set at stack + k * plane_stride, row-major width * height pixels),
// the ray map's rays and valid flags. Asynchronous on `stream`.
void launch_decode_cuda(const DecodeParams& decode, const TriangulationParams& triangulation, int width, int height,
                        const std::uint16_t* stack, std::size_t plane_stride, const Vec3f* rays,
                        const std::uint8_t* ray_valid, const DecodeOutputsDevice& outputs, cudaStream_t stream);

// The decoder's device state: the ray map, an upload buffer for host stacks, the outputs and
// a stream, allocated once per Decoder and reused for every frame.
class CudaDecodeContext {
 public:
  // `rays` / `ray_valid`: host ray map (width * height). Selects nothing: the caller has
  // made the decoder's device current (require_device).
  CudaDecodeContext(const DecodeParams& decode, const TriangulationParams& triangulation, int width, int height,
                    const Vec3f* rays, const std::uint8_t* ray_valid);
  ~CudaDecodeContext();
  CudaDecodeContext(const CudaDecodeContext&) = delete;
  CudaDecodeContext& operator=(const CudaDecodeContext&) = delete;

  // Decodes a stack already on the device into outputs() on `stream` (nullptr: the
  // context's own stream); asynchronous: the ≤ 2 ms path, no host traffic.
  void decode_resident(const std::uint16_t* stack_device, std::size_t plane_stride, cudaStream_t stream = nullptr);
  // Uploads planes[0 .. pattern_count) (width * height pixels each), decodes, downloads into
  // `host` and waits.
  void decode_host(const std::uint16_t* const* planes, const DecodeOutputsHost& host);

  // The live pipeline: two upload slots, so the upload of stack n + 1 (on the context's copy
  // stream) overlaps the decode of stack n (on the compute stream), as a 12-megapixel scanner
  // needs: a 22-image stack takes ~10 ms to upload and < 1 ms to decode.
  //   int slot = context.upload_async(planes);   // returns at once; planes must stay valid
  //   context.decode_slot(slot);                 // waits for that upload on the GPU, not here
  // upload_async first waits (on the GPU) until the decode that last read the slot it reuses
  // has finished. Planes in pinned host memory (cudaMallocHost) are copied by the copy engine
  // directly and upload_async returns at once; pageable planes are staged through pinned
  // planes by the host's threads, and upload_async returns when the last is staged.
  // Outputs are those of the last decode_slot, on stream().
  int upload_async(const std::uint16_t* const* planes);
  void decode_slot(int slot);

  DecodeOutputsDevice outputs() const;
  cudaStream_t stream() const;
  int width() const;
  int height() const;

 private:
  struct State;
  State* state_;
};

}  // namespace sls::detail
