// A CUDA GPU's memory for Buffer<T> (MemoryType::kDevice), without CUDA's headers: allocation
// with a clear error when it does not fit, release, and copies between any two kinds of memory.
// Every allocation is counted in gpu_allocations() (device.h). Explicit memory only: no managed
// memory (DESIGN.md section 6).
#pragma once

#include <cstddef>

#include "sdk/core/gpu_stream.h"

namespace sls {

// `bytes` of the current device's memory (require_device selects it). Throws
// sls::Error(kOutOfMemory) naming the size and what is free when it does not fit,
// kUnsupported in a build without CUDA, kDevice for other driver errors. 0 bytes: nullptr.
void* allocate_device(std::size_t bytes);
// Frees a block from allocate_device; nullptr is ignored. Waits for the device's work on it
// (cudaFree does).
void release_device(void* block, std::size_t bytes) noexcept;
// Sets `bytes` at `block` (device memory) to zero, on `stream` (asynchronous) or, with none,
// before returning.
void zero_device(void* block, std::size_t bytes, const GpuStream& stream = {});
// Copies `bytes` between any two of host, page-locked and device memory (the driver tells them
// apart), on `stream` (asynchronous) or, with none, before returning. Host to host is memcpy.
void copy_memory(void* to, const void* from, std::size_t bytes, bool device_involved, const GpuStream& stream = {});
// `rows` runs of `width_bytes`, the k-th from `from` + k `from_pitch` to `to` + k `to_pitch`
// (every n-th row of an image: the pitch is n rows), as copy_memory.
void copy_memory_2d(void* to, std::size_t to_pitch, const void* from, std::size_t from_pitch, std::size_t width_bytes,
                    std::size_t rows, bool device_involved, const GpuStream& stream = {});

}  // namespace sls
