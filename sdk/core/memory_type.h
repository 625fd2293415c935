// Where a host buffer's bytes live (issue 18; as nvblox's MemoryType): HostBuffer and Image are
// pageable or page-locked. GPU memory is a separate type, DeviceBuffer (sdk/core/cuda).
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
  // buffer says so (HostBuffer::memory_type).
  kPinned,
};

inline const char* memory_type_name(MemoryType type) { return type == MemoryType::kPinned ? "pinned" : "host"; }

}  // namespace sls
