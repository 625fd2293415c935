// Page-locked host memory, recycled (issue 18: the pinned ring the captured stacks land in).
//
// Page-locking is slow — cudaHostAlloc of a 24 MB image plane takes milliseconds, 22 of them
// per 12-megapixel pattern stack would cost a frame's time — so blocks are not returned to
// the driver when a buffer lets go of them: they wait in a process-wide cache for the next
// request of the same size (a scan asks for the same plane size thousands of times). The cache
// keeps at most PinnedMemoryStatistics::cache_limit_bytes; blocks beyond it are freed at once.
//
// Thread-safe. Without CUDA (or without a GPU, or when the driver refuses more page-locked
// memory) allocate_pinned returns nullptr and the caller uses pageable memory.
#pragma once

#include <cstddef>
#include <cstdint>

namespace sls {

// `bytes` of page-locked host memory usable by every GPU (a cached block when one of that size
// waits), or nullptr when none can be had. Never throws.
void* allocate_pinned(std::size_t bytes) noexcept;
// Gives a block from allocate_pinned back (to the cache, or to the driver when the cache is
// full). nullptr is ignored.
void release_pinned(void* block, std::size_t bytes) noexcept;
// Frees every cached block (they stay pinned otherwise until the process ends; exit trims them).
void trim_pinned_cache() noexcept;

// Whether `host` points into page-locked memory (ours, or any cudaMallocHost/cudaHostRegister
// block): the copy engine reads it directly. false without CUDA or a GPU.
bool is_page_locked(const void* host) noexcept;

struct PinnedMemoryStatistics {
  std::uint64_t in_use_bytes = 0;       // held by buffers now
  std::uint64_t cached_bytes = 0;       // waiting in the cache
  std::uint64_t cache_limit_bytes = 0;  // the most the cache keeps
  std::uint64_t allocations = 0;        // blocks page-locked by the driver so far
  std::uint64_t reuses = 0;             // requests served from the cache so far
  std::uint64_t refusals = 0;           // requests that got nullptr (no CUDA, no GPU, none left)
};
PinnedMemoryStatistics pinned_memory_statistics() noexcept;

// The cache's limit in bytes (default 4 GiB: the queue's stacks at 12 MP, ~0.5 GB each, and
// their recording's and decoder's turn, several times over). Blocks cached above a new, lower
// limit are freed.
void set_pinned_cache_limit(std::uint64_t bytes) noexcept;

}  // namespace sls
