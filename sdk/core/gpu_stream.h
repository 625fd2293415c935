// A CUDA stream as the rest of slscan sees it, without CUDA's headers: who makes it owns
// it, and every stage handed a copy queues its work on it (issue 18). A scan session makes its
// streams once (compute, upload, ship) and hands them down, so decoding, tracking, integration
// and raycasting of a frame are ordered by the stream rather than by host waits between
// objects that each had their own. A stage made without one (a test, a tool) makes its own.
//
// Copies share the stream; the last copy destroys it, so a stage never outlives its stream.
#pragma once

#include <memory>

#include "sdk/core/device.h"

namespace sls {

class GpuStream {
 public:
  GpuStream() = default;  // none: CPU work, or "make your own" where a stage takes one
  // A non-blocking stream of its own on `device` (a CUDA device; none for the CPU). Throws as
  // require_device, and sls::Error(kDevice) when the driver refuses.
  static GpuStream create(const Device& device);
  // `stream` if it has one, else one of its own on `device` (none for the CPU): what a stage's
  // constructor calls with the stream it was handed.
  static GpuStream or_create(const GpuStream& stream, const Device& device) {
    return stream.valid() ? stream : create(device);
  }

  bool valid() const { return stream_ != nullptr; }
  // The cudaStream_t (CUDA code casts it: sdk/core/cuda/cuda_stream.h); nullptr when none.
  void* native() const { return stream_.get(); }
  // Waits for everything queued on it; nothing when none. Throws sls::Error(kDevice) on a
  // failed kernel or copy.
  void synchronize() const;

  bool operator==(const GpuStream& other) const { return stream_ == other.stream_; }
  bool operator!=(const GpuStream& other) const { return stream_ != other.stream_; }

 private:
  std::shared_ptr<void> stream_;
};

}  // namespace sls
