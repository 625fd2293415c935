// Where a buffer's bytes live (issue 18; as nvblox's MemoryType): Buffer<T> (buffer.h), and
// Image<T> over it, are pageable host memory, page-locked host memory, or a GPU's memory.
#pragma once

namespace sls {

enum class MemoryType {
  // Ordinary, pageable host memory. A GPU upload from it is staged by the driver (or by us)
  // through page-locked memory first: 7-8 GB/s for a 12-megapixel pattern stack.
  kHost,
  // Page-locked ("pinned") host memory: the GPU's copy engine reads and writes it directly at
  // the bus's rate. A camera that delivers its images here (the capture of a scan fused on a
  // GPU) saves the staging copy of every pattern stack. Needs a CUDA build and a GPU; where
  // there is neither, or the driver refuses more, a request falls back to kHost, and the
  // buffer says so (Buffer::memory_type).
  kPinned,
  // The current CUDA device's memory: what the GPU stages read and write. The host reads it
  // only through copies. Needs a CUDA build and a GPU (an error otherwise, never a fallback).
  kDevice,
};

inline const char* memory_type_name(MemoryType type) {
  switch (type) {
    case MemoryType::kPinned:
      return "pinned";
    case MemoryType::kDevice:
      return "device";
    case MemoryType::kHost:
    default:
      return "host";
  }
}

}  // namespace sls
