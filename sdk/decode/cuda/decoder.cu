// CUDA backend of the decoder: a thin launcher, one thread per pixel, around decode_pixel
// and triangulate_decoded_pixel, the same per-pixel code the CPU loop runs.
#include "sdk/decode/cuda/decoder_cuda.h"

#include <algorithm>
#include <condition_variable>
#include <cstring>
#include <limits>
#include <mutex>
#include <utility>
#include <vector>

#include "sdk/core/cuda/cuda_check.h"
#include "sdk/core/cuda/cuda_stream.h"
#include "sdk/core/cuda/device_buffer.h"
#include "sdk/core/error.h"
#include "sdk/core/host_memory.h"
#include "sdk/core/kernel_profile.h"
#include "sdk/core/pinned_memory.h"

namespace sls::detail {
namespace {

// One pixel: decode, triangulate, write. Parameters by value: a few KB, within the kernel
// parameter space, and read from the constant bank by every thread.
template <int Unwrap>
__device__ __forceinline__ void decode_and_store(const DecodeParams& decode, const TriangulationParams& triangulation,
                                                 int width, int height, const std::uint16_t* __restrict__ stack,
                                                 std::uint32_t plane_stride, const Vec3f* __restrict__ rays,
                                                 const std::uint8_t* __restrict__ ray_valid,
                                                 const DecodeOutputsDevice& out) {
  const int x = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  const int y = static_cast<int>(blockIdx.y * blockDim.y + threadIdx.y);
  if (x >= width || y >= height) return;
  const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x);
  // Plane-major stack: neighbouring threads read neighbouring pixels of each image (coalesced).
  const StridedStackSamples samples{stack + i, plane_stride};
  PixelDecode pixel = decode_pixel_unwrapped<Unwrap>(decode, samples);
  out.depth[i] = triangulate_decoded_pixel(decode.layout, triangulation, &pixel, rays[i], ray_valid[i] != 0);
  out.u[i] = pixel.u;
  out.v[i] = pixel.v;
  out.confidence[i] = pixel.confidence;
  out.mask[i] = pixel.mask;
}

constexpr int kDecodeBlockThreads = 256;  // 32 x 8

// One kernel per unwrapping (DecodeUnwrap), so that each carries only its own code and registers.
template <int Unwrap>
__global__ void decode_kernel(DecodeParams decode, TriangulationParams triangulation, int width, int height,
                              const std::uint16_t* __restrict__ stack, std::uint32_t plane_stride,
                              const Vec3f* __restrict__ rays, const std::uint8_t* __restrict__ ray_valid,
                              DecodeOutputsDevice out) {
  decode_and_store<Unwrap>(decode, triangulation, width, height, stack, plane_stride, rays, ray_valid, out);
}

// Micro phase shifting: its candidate search is arithmetic, one dependent chain per pixel, and
// the set of most single images wants ~105 registers, which leaves 16 warps per SM to hide the
// latency. Capped at 64 (4 blocks, 32 warps): the sets of up to ~5 images keep theirs in registers
// (decode_micro_singles is sized per count); larger ones spill a few, outside the search loop.
__global__ void __launch_bounds__(kDecodeBlockThreads, 4)
    decode_micro_phase_kernel(DecodeParams decode, TriangulationParams triangulation, int width, int height,
                              const std::uint16_t* __restrict__ stack, std::uint32_t plane_stride,
                              const Vec3f* __restrict__ rays, const std::uint8_t* __restrict__ ray_valid,
                              DecodeOutputsDevice out) {
  decode_and_store<kUnwrapMicroPhase>(decode, triangulation, width, height, stack, plane_stride, rays, ray_valid,
                                      out);
}

}  // namespace

void launch_decode_cuda(const DecodeParams& decode, const TriangulationParams& triangulation, int width, int height,
                        const std::uint16_t* stack, std::size_t plane_stride, const Vec3f* rays,
                        const std::uint8_t* ray_valid, const DecodeOutputsDevice& outputs, cudaStream_t stream) {
  if (width <= 0 || height <= 0) return;
  if (plane_stride > std::numeric_limits<std::uint32_t>::max()) {
    throw_error(ErrorCode::kInvalidArgument, "decode: planes of {} elements; the GPU decoder takes fewer than 2^32",
                plane_stride);
  }
  const auto stride = static_cast<std::uint32_t>(plane_stride);
  // Per pixel each image of the stack read (16 bits), its ray (and validity) read, each output
  // asked for written.
  const int images = std::max({decode.layout.pattern_count, decode.layout.white_index + 1, decode.layout.black_index + 1});
  const double output_bytes = 4.0 * ((outputs.u != nullptr) + (outputs.v != nullptr) +
                                     (outputs.confidence != nullptr) + (outputs.depth != nullptr)) +
                              (outputs.mask != nullptr ? 1.0 : 0.0);
  const KernelTimer timer("decode", (2.0 * images + 13.0 + output_bytes) * static_cast<double>(width) * height, stream);
  const dim3 block(32, kDecodeBlockThreads / 32);
  const dim3 grid((static_cast<unsigned>(width) + block.x - 1) / block.x,
                  (static_cast<unsigned>(height) + block.y - 1) / block.y);
  switch (decode.layout.unwrap) {
    case kUnwrapHeterodyne:
      decode_kernel<kUnwrapHeterodyne><<<grid, block, 0, stream>>>(decode, triangulation, width, height, stack,
                                                                   stride, rays, ray_valid, outputs);
      break;
    case kUnwrapMicroPhase:
      decode_micro_phase_kernel<<<grid, block, 0, stream>>>(
          decode, triangulation, width, height, stack, stride, rays, ray_valid, outputs);
      break;
    default:
      decode_kernel<kUnwrapGrayPhase><<<grid, block, 0, stream>>>(decode, triangulation, width, height, stack,
                                                                  stride, rays, ray_valid, outputs);
      break;
  }
  SLS_CUDA_CHECK_LAUNCH();
}

struct DecoderGpu::State {
  DecodeParams decode;
  TriangulationParams triangulation;
  int width = 0;
  int height = 0;
  std::size_t pixels = 0;
  GpuStream decode_stream, upload_stream;  // the session's, or the decoder's own
  cudaStream_t stream = nullptr;           // decode
  cudaStream_t copy_stream = nullptr;      // uploads, so they overlap the decode of the previous stack
  std::shared_ptr<const SharedRayMap> rays;
  // Upload slots for host stacks (allocated on first use), each with "upload landed" and
  // "decode done reading" events.
  DeviceBuffer<std::uint16_t> slots[2];
  cudaEvent_t uploaded[2] = {nullptr, nullptr};
  cudaEvent_t consumed[2] = {nullptr, nullptr};
  int next_slot = 0;
  // Who holds each slot, under slot_mutex: a prefetch (Decoder::prefetch) runs on another
  // thread than the decode that takes it. kFree slots may be claimed; a slot's stack stays
  // until decode_slot (kUploaded, kPrefetched) or until a newer prefetch replaces it.
  enum class Slot { kFree, kUploaded, kPrefetching, kPrefetched };
  std::mutex slot_mutex;
  std::condition_variable slot_changed;
  Slot slot_state[2] = {Slot::kFree, Slot::kFree};
  std::vector<const std::uint16_t*> slot_planes[2];  // a prefetched stack's planes, to match its decode
  // Uploads, one at a time: they share the staging planes and the copy stream.
  std::mutex upload_mutex;
  // Pinned staging planes for pageable stacks (allocated on first use): a pageable
  // cudaMemcpyAsync is synchronous and crosses the bus at 7-8 GB/s (measured on H100 and
  // H200 hosts, 2026-11); staged, the host's threads fill one plane while the copy engine
  // moves the one before at the bus's pinned rate. Each has a "copy engine done reading it" event.
  static constexpr int kStagingPlanes = 3;
  std::uint16_t* staging[kStagingPlanes] = {nullptr, nullptr, nullptr};
  cudaEvent_t staging_free[kStagingPlanes] = {nullptr, nullptr, nullptr};
  int next_staging = 0;
  // Pinned landing planes for downloads (allocated on first use), for the same reason: a
  // pageable download of a 12-megapixel float map runs at ~8 GB/s, a pinned one at the bus's
  // rate, and the host's threads then copy it out.
  float* landing[2] = {nullptr, nullptr};
  bool landing_queued[2] = {false, false};  // depth, confidence
  DeviceBuffer<float> u, v;
  Image32f confidence{MemoryType::kDevice}, depth{MemoryType::kDevice};  // what the session reads in place
  DeviceBuffer<std::uint8_t> mask;
  // The stack check's results (allocated on first use): the largest contrast, the lit pixels
  // and the histograms on the device, downloaded into one pinned block, and an event once
  // they have landed.
  DeviceBuffer<int> check_largest;
  DeviceBuffer<unsigned long long> check_lit;
  DeviceBuffer<std::uint32_t> check_counts;  // the histograms (stack_check_shared.h)
  void* check_host = nullptr;
  std::size_t check_host_bytes = 0;
  bool check_judged = false;  // the last check filled histograms
  cudaEvent_t check_ready = nullptr;

  ~State() {
    if (check_ready != nullptr) (void)cudaEventDestroy(check_ready);
    if (check_host != nullptr) (void)cudaFreeHost(check_host);
    for (float* plane : landing) {
      if (plane != nullptr) (void)cudaFreeHost(plane);
    }
    for (int i = 0; i < kStagingPlanes; ++i) {
      if (staging_free[i] != nullptr) (void)cudaEventDestroy(staging_free[i]);
      if (staging[i] != nullptr) (void)cudaFreeHost(staging[i]);
    }
    for (int i = 0; i < 2; ++i) {
      if (uploaded[i] != nullptr) (void)cudaEventDestroy(uploaded[i]);
      if (consumed[i] != nullptr) (void)cudaEventDestroy(consumed[i]);
    }
  }
};

DecoderGpu::DecoderGpu(const DecodeParams& decode, const TriangulationParams& triangulation,
                                     std::shared_ptr<const SharedRayMap> rays, const GpuStream& stream,
                                     const GpuStream& upload_stream)
    : state_(new State) {
  try {
    State& s = *state_;
    s.decode = decode;
    s.triangulation = triangulation;
    s.width = rays->host.width;
    s.height = rays->host.height;
    s.pixels = static_cast<std::size_t>(s.width) * static_cast<std::size_t>(s.height);
    s.rays = std::move(rays);
    s.decode_stream = stream;
    s.upload_stream = upload_stream;
    s.stream = cuda_stream(stream);
    s.copy_stream = cuda_stream(upload_stream);
    for (int i = 0; i < 2; ++i) {
      SLS_CUDA_CHECK(cudaEventCreateWithFlags(&s.uploaded[i], cudaEventDisableTiming));
      SLS_CUDA_CHECK(cudaEventCreateWithFlags(&s.consumed[i], cudaEventDisableTiming));
    }
    for (int i = 0; i < State::kStagingPlanes; ++i) {
      SLS_CUDA_CHECK(cudaEventCreateWithFlags(&s.staging_free[i], cudaEventDisableTiming));
    }
    s.u.allocate(s.pixels);
    s.v.allocate(s.pixels);
    s.confidence.resize(s.width, s.height);
    s.depth.resize(s.width, s.height);
    s.mask.allocate(s.pixels);
  } catch (...) {
    delete state_;
    throw;
  }
}

DecoderGpu::~DecoderGpu() {
  if (state_ != nullptr) {
    if (state_->copy_stream != nullptr) (void)cudaStreamSynchronize(state_->copy_stream);
    if (state_->stream != nullptr) (void)cudaStreamSynchronize(state_->stream);
  }
  delete state_;
}

void DecoderGpu::decode_resident(const std::uint16_t* stack_device, std::size_t plane_stride) {
  State& s = *state_;
  launch_decode_cuda(s.decode, s.triangulation, s.width, s.height, stack_device, plane_stride, s.rays->rays_device,
                     s.rays->valid_device, outputs(), s.stream);
}

int DecoderGpu::claim_slot(bool prefetch, const std::uint16_t* const* planes) {
  State& s = *state_;
  std::lock_guard<std::mutex> lock(s.slot_mutex);
  for (int i = 0; prefetch && i < 2; ++i) {
    if (s.slot_state[i] == State::Slot::kPrefetched) s.slot_state[i] = State::Slot::kFree;  // replaced
  }
  for (const int slot : {s.next_slot, s.next_slot ^ 1}) {
    if (s.slot_state[slot] != State::Slot::kFree) continue;
    s.next_slot = slot ^ 1;
    s.slot_state[slot] = prefetch ? State::Slot::kPrefetching : State::Slot::kUploaded;
    const std::size_t count = static_cast<std::size_t>(s.decode.layout.pattern_count);
    s.slot_planes[slot].assign(planes, planes + (prefetch ? count : 0));
    return slot;
  }
  if (prefetch) return -1;  // the frame being decoded and another's upload hold both
  throw_error(ErrorCode::kInvalidArgument, "upload_async: both upload slots hold stacks not yet decoded");
}

void DecoderGpu::release_slot(int slot) {
  State& s = *state_;
  {
    std::lock_guard<std::mutex> lock(s.slot_mutex);
    s.slot_state[slot] = State::Slot::kFree;
    s.slot_planes[slot].clear();
  }
  s.slot_changed.notify_all();
}

int DecoderGpu::upload_async(const std::uint16_t* const* planes) {
  const int slot = claim_slot(false, planes);
  try {
    upload_into(slot, planes);
  } catch (...) {
    release_slot(slot);
    throw;
  }
  return slot;
}

bool DecoderGpu::prefetch(const std::uint16_t* const* planes) {
  State& s = *state_;
  const int slot = claim_slot(true, planes);
  if (slot < 0) return false;
  try {
    upload_into(slot, planes);
  } catch (...) {
    release_slot(slot);
    throw;
  }
  {
    std::lock_guard<std::mutex> lock(s.slot_mutex);
    if (s.slot_state[slot] == State::Slot::kPrefetching) s.slot_state[slot] = State::Slot::kPrefetched;
  }
  s.slot_changed.notify_all();
  return true;
}

int DecoderGpu::take_prefetched(const std::uint16_t* const* planes) {
  State& s = *state_;
  const std::size_t count = static_cast<std::size_t>(s.decode.layout.pattern_count);
  const auto matches = [&](int slot) {
    return std::equal(planes, planes + count, s.slot_planes[slot].begin(), s.slot_planes[slot].end());
  };
  std::unique_lock<std::mutex> lock(s.slot_mutex);
  for (int slot = 0; slot < 2; ++slot) {
    if (s.slot_state[slot] != State::Slot::kPrefetching && s.slot_state[slot] != State::Slot::kPrefetched) continue;
    if (!matches(slot)) continue;
    // This stack's upload is under way on another thread: wait for it rather than upload it twice.
    s.slot_changed.wait(lock, [&] { return s.slot_state[slot] != State::Slot::kPrefetching; });
    if (s.slot_state[slot] != State::Slot::kPrefetched || !matches(slot)) return -1;  // it failed
    s.slot_state[slot] = State::Slot::kUploaded;
    return slot;
  }
  return -1;
}

void DecoderGpu::upload_into(int slot, const std::uint16_t* const* planes) {
  State& s = *state_;
  std::lock_guard<std::mutex> lock(s.upload_mutex);
  const std::size_t count = static_cast<std::size_t>(s.decode.layout.pattern_count);
  DeviceBuffer<std::uint16_t>& buffer = s.slots[slot];
  if (buffer.size() < count * s.pixels) {
    // A first use: nothing can be reading the slot yet.
    buffer.allocate(count * s.pixels);
  }
  // Do not overwrite the slot while the decode that last read it still does (an event never
  // recorded lets the wait through; a free slot's last decode_slot has recorded it).
  SLS_CUDA_CHECK(cudaStreamWaitEvent(s.copy_stream, s.consumed[slot], 0));
  const std::size_t plane_bytes = s.pixels * sizeof(std::uint16_t);
  bool read_in_place = false;  // a page-locked plane the copy engine reads after we return
  for (std::size_t k = 0; k < count; ++k) {
    std::uint16_t* destination = buffer.data() + k * s.pixels;
    // Small planes (under 4 MiB: the demo's 800x600) the driver stages well itself; ours pays off at 12 MP.
    // A page-locked plane (a camera's image captured for a GPU scan) needs no staging at all.
    const bool page_locked = is_page_locked(planes[k]);
    if (plane_bytes < (std::size_t{4} << 20) || page_locked) {
      SLS_CUDA_CHECK(cudaMemcpyAsync(destination, planes[k], plane_bytes, cudaMemcpyHostToDevice, s.copy_stream));
      read_in_place = read_in_place || page_locked;
      continue;
    }
    const int b = s.next_staging;
    s.next_staging = (b + 1) % State::kStagingPlanes;
    if (s.staging[b] == nullptr) {
      void* pinned = nullptr;
      const cudaError_t status = cudaMallocHost(&pinned, plane_bytes);
      if (status != cudaSuccess) {
        (void)cudaGetLastError();
        throw_error(status == cudaErrorMemoryAllocation ? ErrorCode::kOutOfMemory : ErrorCode::kDevice,
                    "cannot allocate {:.1f} MiB of pinned host memory to stage pattern images for the GPU: {}",
                    static_cast<double>(plane_bytes) / 1048576.0, cudaGetErrorString(status));
      }
      s.staging[b] = static_cast<std::uint16_t*>(pinned);
    }
    SLS_CUDA_CHECK(cudaEventSynchronize(s.staging_free[b]));  // its last plane has left for the GPU
    copy_bytes_parallel(s.staging[b], planes[k], plane_bytes);
    SLS_CUDA_CHECK(cudaMemcpyAsync(destination, s.staging[b], plane_bytes, cudaMemcpyHostToDevice, s.copy_stream));
    SLS_CUDA_CHECK(cudaEventRecord(s.staging_free[b], s.copy_stream));
  }
  SLS_CUDA_CHECK(cudaEventRecord(s.uploaded[slot], s.copy_stream));
  // The caller may free or refill its images once this returns (the pageable paths have copied
  // them by then); a page-locked plane is read by the copy engine meanwhile, so wait for it.
  if (read_in_place) SLS_CUDA_CHECK(cudaEventSynchronize(s.uploaded[slot]));
}

void DecoderGpu::require_uploaded(int slot, const char* caller) {
  State& s = *state_;
  bool uploaded = false;
  if (slot >= 0 && slot <= 1) {
    std::lock_guard<std::mutex> lock(s.slot_mutex);
    uploaded = s.slot_state[slot] == State::Slot::kUploaded && s.slots[slot].size() > 0;
  }
  if (!uploaded) throw_error(ErrorCode::kInvalidArgument, "{}({}): no stack was uploaded to that slot", caller, slot);
}

void DecoderGpu::decode_slot(int slot) {
  State& s = *state_;
  require_uploaded(slot, "decode_slot");
  SLS_CUDA_CHECK(cudaStreamWaitEvent(s.stream, s.uploaded[slot], 0));
  decode_resident(s.slots[slot].data(), s.pixels);
  SLS_CUDA_CHECK(cudaEventRecord(s.consumed[slot], s.stream));
  release_slot(slot);  // after `consumed` is recorded: the next upload into it waits for this decode
}

void DecoderGpu::decode_host(const std::uint16_t* const* planes, const DecodeOutputsHost& host) {
  decode_slot(upload_async(planes));
  download(host);
}

namespace {

// A fill of one int on the GPU (the reduction's start: cudaMemset writes bytes).
__global__ void set_int_kernel(int* target, int value) { *target = value; }

}  // namespace

void DecoderGpu::gather_check_async(int slot, const StackCheckGrid& grid, const StackCheckPlan& plan) {
  State& s = *state_;
  require_uploaded(slot, "gather_check_async");
  const int images = s.decode.layout.pattern_count;
  const bool judged = plan.usable && grid.count() > 0;
  const std::size_t bins = judged ? static_cast<std::size_t>(plan.slot_count) * kStackCheckBins : 0;
  // Pinned on the host: the largest contrast, the lit count, then the histograms.
  const std::size_t header = 2 * sizeof(unsigned long long);
  const std::size_t bytes = header + bins * sizeof(std::uint32_t);
  if (s.check_largest.size() == 0) {
    s.check_largest.allocate(1);
    s.check_lit.allocate(1);
    SLS_CUDA_CHECK(cudaEventCreateWithFlags(&s.check_ready, cudaEventDisableTiming));
  }
  if (s.check_counts.size() < bins) s.check_counts.allocate(bins);
  if (s.check_host_bytes < bytes) {
    if (s.check_host != nullptr) SLS_CUDA_CHECK(cudaFreeHost(s.check_host));
    s.check_host = nullptr;
    s.check_host_bytes = 0;
    const cudaError_t status = cudaMallocHost(&s.check_host, bytes);
    if (status != cudaSuccess) {
      (void)cudaGetLastError();
      throw_error(status == cudaErrorMemoryAllocation ? ErrorCode::kOutOfMemory : ErrorCode::kDevice,
                  "cannot allocate {:.1f} MiB of pinned host memory for the pattern stack's check: {}",
                  static_cast<double>(bytes) / 1048576.0, cudaGetErrorString(status));
    }
    s.check_host_bytes = bytes;
  }
  s.check_judged = judged;
  SLS_CUDA_CHECK(cudaStreamWaitEvent(s.stream, s.uploaded[slot], 0));
  set_int_kernel<<<1, 1, 0, s.stream>>>(s.check_largest.data(), std::numeric_limits<int>::min());
  SLS_CUDA_CHECK_LAUNCH();
  if (judged) {
    SLS_CUDA_CHECK(cudaMemsetAsync(s.check_lit.data(), 0, sizeof(unsigned long long), s.stream));
    SLS_CUDA_CHECK(cudaMemsetAsync(s.check_counts.data(), 0, bins * sizeof(std::uint32_t), s.stream));
  }
  launch_stack_check(s.slots[slot].data(), s.pixels, images, judged ? grid : StackCheckGrid{}, plan,
                     s.check_largest.data(), s.check_counts.data(), s.check_lit.data(), s.stream);
  auto* host = static_cast<unsigned char*>(s.check_host);
  SLS_CUDA_CHECK(cudaMemcpyAsync(host, s.check_largest.data(), sizeof(int), cudaMemcpyDeviceToHost, s.stream));
  if (judged) {
    SLS_CUDA_CHECK(cudaMemcpyAsync(host + sizeof(unsigned long long), s.check_lit.data(), sizeof(unsigned long long),
                                   cudaMemcpyDeviceToHost, s.stream));
    SLS_CUDA_CHECK(cudaMemcpyAsync(host + header, s.check_counts.data(), bins * sizeof(std::uint32_t),
                                   cudaMemcpyDeviceToHost, s.stream));
  }
  SLS_CUDA_CHECK(cudaEventRecord(s.check_ready, s.stream));
}

StackCheckInputs DecoderGpu::wait_check() {
  State& s = *state_;
  if (s.check_ready == nullptr) {
    throw_error(ErrorCode::kInvalidArgument, "wait_check(): no stack check was gathered");
  }
  SLS_CUDA_CHECK(cudaEventSynchronize(s.check_ready));
  const auto* host = static_cast<const unsigned char*>(s.check_host);
  StackCheckInputs inputs;
  std::memcpy(&inputs.largest, host, sizeof(int));
  if (s.check_judged) {
    unsigned long long lit = 0;
    std::memcpy(&lit, host + sizeof(unsigned long long), sizeof(lit));
    inputs.lit = static_cast<std::size_t>(lit);
    inputs.counts = reinterpret_cast<const std::uint32_t*>(host + 2 * sizeof(unsigned long long));
  }
  return inputs;
}

void DecoderGpu::queue_landing(bool depth, bool confidence) {
  State& s = *state_;
  const bool wanted[2] = {depth, confidence};
  const float* const sources[2] = {s.depth.data(), s.confidence.data()};
  for (int i = 0; i < 2; ++i) {
    if (!wanted[i] || s.landing_queued[i]) continue;
    if (s.landing[i] == nullptr) {
      void* pinned = nullptr;
      if (cudaMallocHost(&pinned, s.pixels * sizeof(float)) != cudaSuccess) {
        (void)cudaGetLastError();  // no pinned memory to spare: download() downloads straight, more slowly
        continue;
      }
      s.landing[i] = static_cast<float*>(pinned);
    }
    SLS_CUDA_CHECK(
        cudaMemcpyAsync(s.landing[i], sources[i], s.pixels * sizeof(float), cudaMemcpyDeviceToHost, s.stream));
    s.landing_queued[i] = true;
  }
}

void DecoderGpu::download(const DecodeOutputsHost& host) {
  State& s = *state_;
  if (host.u != nullptr) s.u.download(host.u, s.pixels, s.stream);
  if (host.v != nullptr) s.v.download(host.v, s.pixels, s.stream);
  if (host.mask != nullptr) s.mask.download(host.mask, s.pixels, s.stream);
  // Depth and confidence land in pinned planes first, unless the caller's own image is
  // page-locked (a GPU scan's keyframe depth): that one the copy engine fills directly.
  float* const wanted[2] = {host.depth, host.confidence};
  const bool direct[2] = {wanted[0] != nullptr && !s.landing_queued[0] && is_page_locked(wanted[0]),
                          wanted[1] != nullptr && !s.landing_queued[1] && is_page_locked(wanted[1])};
  queue_landing(host.depth != nullptr && !direct[0], host.confidence != nullptr && !direct[1]);
  const float* const sources[2] = {s.depth.data(), s.confidence.data()};
  for (int i = 0; i < 2; ++i) {
    if (wanted[i] != nullptr && !s.landing_queued[i]) {
      SLS_CUDA_CHECK(
          cudaMemcpyAsync(wanted[i], sources[i], s.pixels * sizeof(float), cudaMemcpyDeviceToHost, s.stream));
    }
  }
  const bool landed[2] = {s.landing_queued[0], s.landing_queued[1]};
  synchronize();
  for (int i = 0; i < 2; ++i) {
    if (wanted[i] != nullptr && landed[i]) {
      copy_bytes_parallel(wanted[i], s.landing[i], s.pixels * sizeof(float));
    }
  }
}

void DecoderGpu::synchronize() {
  State& s = *state_;
  const cudaError_t status = cudaStreamSynchronize(s.stream);
  // Whatever landed is stale once waited for: the next frame queues its own.
  s.landing_queued[0] = s.landing_queued[1] = false;
  SLS_CUDA_CHECK(status);
}

const Image32f& DecoderGpu::depth_image() const { return state_->depth; }
const Image32f& DecoderGpu::confidence_image() const { return state_->confidence; }

DecodeOutputsDevice DecoderGpu::outputs() const {
  State& s = *state_;
  DecodeOutputsDevice out;
  out.u = s.u.data();
  out.v = s.v.data();
  out.confidence = s.confidence.data();
  out.mask = s.mask.data();
  out.depth = s.depth.data();
  return out;
}

const GpuStream& DecoderGpu::stream() const { return state_->decode_stream; }
int DecoderGpu::width() const { return state_->width; }
int DecoderGpu::height() const { return state_->height; }

}  // namespace sls::detail
