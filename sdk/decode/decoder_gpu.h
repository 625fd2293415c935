// Internal: the decoder's GPU half (sdk/decode/decoder.h): its device state and the decode,
// upload and stack-check pipeline on a GPU. Declared in every build, without CUDA's headers
// (decoder.cpp dispatches here); defined in cuda/decoder.cu, or in a build without CUDA by
// sdk/decode/no_cuda.cpp, where making one throws kUnsupported (a decoder on a GPU is refused
// before: require_device). Kept free of Eigen and the public headers that carry it, so nvcc sees
// only the plain per-pixel structs.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>

#include "sdk/core/gpu_stream.h"
#include "sdk/core/image.h"
#include "sdk/core/math_shared.h"
#include "sdk/core/ray_map.h"
#include "sdk/decode/decode_shared.h"
#include "sdk/decode/stack_check_shared.h"
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

// What the decoder's stack check reads (Decoder::decode), on the host once wait_check returns.
struct StackCheckInputs {
  int largest = 0;                         // white - black's maximum, or the brightest pixel
  std::size_t lit = 0;                     // pixels judged
  const std::uint32_t* counts = nullptr;   // the histograms; nullptr without a grid or a usable plan
};

// The decoder's device state: the ray map, an upload buffer for host stacks, the outputs and
// a stream, allocated once per Decoder and reused for every frame.
class DecoderGpu {
 public:
  // `rays`: the camera's shared ray map, on this device. Decodes on `stream`, uploads on
  // `upload_stream` (both valid). Selects nothing: the caller has made the decoder's device
  // current (require_device).
  DecoderGpu(const DecodeParams& decode, const TriangulationParams& triangulation,
                    std::shared_ptr<const SharedRayMap> rays, const GpuStream& stream, const GpuStream& upload_stream);
  ~DecoderGpu();
  DecoderGpu(const DecoderGpu&) = delete;
  DecoderGpu& operator=(const DecoderGpu&) = delete;

  // Decodes a stack already on the device into outputs() on stream(); asynchronous: the
  // ≤ 2 ms path, no host traffic.
  void decode_resident(const std::uint16_t* stack_device, std::size_t plane_stride);
  // Uploads planes[0 .. pattern_count) (width * height pixels each), decodes, downloads into
  // `host` and waits.
  void decode_host(const std::uint16_t* const* planes, const DecodeOutputsHost& host);

  // The live pipeline: two upload slots, so the upload of stack n + 1 (on the context's copy
  // stream) overlaps the decode of stack n (on the compute stream), as a 12-megapixel scanner
  // needs: a 22-image stack takes ~10 ms to upload and < 1 ms to decode.
  //   int slot = context.upload_async(planes);   // returns at once; planes must stay valid
  //   context.decode_slot(slot);                 // waits for that upload on the GPU, not here
  // upload_async first waits (on the GPU) until the decode that last read the slot it reuses
  // has finished; a slot holds its stack until decode_slot (at most two uploaded, not decoded).
  // Planes in pinned host memory (cudaMallocHost) are copied by the copy engine directly and
  // upload_async returns at once; pageable planes are staged through pinned planes by the
  // host's threads, and upload_async returns when the last is staged.
  // Outputs are those of the last decode_slot, on stream().
  int upload_async(const std::uint16_t* const* planes);
  void decode_slot(int slot);

  // A live scan's next stack, uploaded ahead from another thread while this one decodes (and
  // the session fuses) the frame before (Decoder::prefetch): into a free slot, returning when it
  // has been staged; false when both slots are held. A newer prefetch replaces an older one not
  // taken yet. take_prefetched() gives the slot of a prefetched stack with these same planes
  // (waiting while its upload is still under way), ready for decode_slot, or -1.
  bool prefetch(const std::uint16_t* const* planes);
  int take_prefetched(const std::uint16_t* const* planes);

  // The stack check's inputs from an uploaded slot, gathered on the GPU and downloaded on
  // stream() before what is queued next (the decode); wait_check() waits for them alone, so the
  // host judges the stack while the GPU decodes it. An empty `grid`: only `largest`.
  void gather_check_async(int slot, const StackCheckGrid& grid, const StackCheckPlan& plan);
  StackCheckInputs wait_check();
  // Queues the download of the last decode's depth and/or confidence into pinned landing
  // planes (what download() then copies out), so that it runs while the host works.
  void queue_landing(bool depth, bool confidence);
  // Downloads the last decode's outputs into `host` (those not queued: now) and waits.
  void download(const DecodeOutputsHost& host);
  // Waits for everything queued on stream().
  void synchronize();

  DecodeOutputsDevice outputs() const;
  // The last decode's depth and confidence maps, on the device (MemoryType::kDevice).
  const Image32f& depth_image() const;
  const Image32f& confidence_image() const;
  const GpuStream& stream() const;  // the decode's (cuda_stream() gives CUDA's handle)
  int width() const;
  int height() const;

 private:
  int claim_slot(bool prefetch, const std::uint16_t* const* planes);
  void release_slot(int slot);
  void require_uploaded(int slot, const char* caller);  // throws unless the slot holds an uploaded stack
  void upload_into(int slot, const std::uint16_t* const* planes);

  struct State;
  State* state_;
};

}  // namespace sls::detail
