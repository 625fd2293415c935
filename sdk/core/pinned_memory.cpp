#include "sdk/core/pinned_memory.h"

#include <cstdlib>
#include <map>
#include <mutex>
#include <vector>

#if defined(SLS_HAVE_CUDA)
#include <cuda_runtime.h>
#endif

namespace sls {
namespace {

struct PinnedCache {
  std::mutex mutex;
  std::multimap<std::size_t, void*> free_blocks;  // by size: a scan asks for a few sizes, over and over
  PinnedMemoryStatistics statistics{0, 0, std::uint64_t{4} << 30, 0, 0, 0};

  // Frees cached blocks, largest first, until the cache holds at most `limit`. Under the mutex.
  void shrink_to(std::uint64_t limit) {
    while (statistics.cached_bytes > limit && !free_blocks.empty()) {
      const auto largest = std::prev(free_blocks.end());
      free_to_driver(largest->second);
      statistics.cached_bytes -= largest->first;
      free_blocks.erase(largest);
    }
  }

  static void free_to_driver(void* block) {
#if defined(SLS_HAVE_CUDA)
    (void)cudaFreeHost(block);
#else
    (void)block;
#endif
  }
};

PinnedCache& cache() {
  // Never destroyed: buffers in static objects may give blocks back during exit, and the CUDA
  // runtime may be gone by then (its own teardown frees what is left).
  static PinnedCache* const instance = new PinnedCache();
  return *instance;
}

}  // namespace

void* allocate_pinned(std::size_t bytes) noexcept {
  if (bytes == 0) return nullptr;
  PinnedCache& c = cache();
  {
    const std::lock_guard<std::mutex> lock(c.mutex);
    const auto found = c.free_blocks.find(bytes);
    if (found != c.free_blocks.end()) {
      void* block = found->second;
      c.free_blocks.erase(found);
      c.statistics.cached_bytes -= bytes;
      c.statistics.in_use_bytes += bytes;
      ++c.statistics.reuses;
      return block;
    }
  }
  void* block = nullptr;
#if defined(SLS_HAVE_CUDA)
  // Portable: the block is page-locked for every GPU's context, not only the current one.
  if (cudaHostAlloc(&block, bytes, cudaHostAllocPortable) != cudaSuccess) {
    (void)cudaGetLastError();  // no GPU, or no page-locked memory to spare: not an error of the caller's
    block = nullptr;
  } else {
    // The cache is given back at exit, before the CUDA runtime's own teardown (registered at
    // its initialisation, so run after this): no block is left for a leak checker to report.
    static const bool trimmed_at_exit = std::atexit([] { trim_pinned_cache(); }) == 0;
    (void)trimmed_at_exit;
  }
#endif
  const std::lock_guard<std::mutex> lock(c.mutex);
  if (block == nullptr) {
    ++c.statistics.refusals;
    return nullptr;
  }
  ++c.statistics.allocations;
  c.statistics.in_use_bytes += bytes;
  return block;
}

void release_pinned(void* block, std::size_t bytes) noexcept {
  if (block == nullptr) return;
  PinnedCache& c = cache();
  const std::lock_guard<std::mutex> lock(c.mutex);
  c.statistics.in_use_bytes -= bytes;
  if (c.statistics.cached_bytes + bytes > c.statistics.cache_limit_bytes) {
    PinnedCache::free_to_driver(block);
    return;
  }
  c.free_blocks.emplace(bytes, block);
  c.statistics.cached_bytes += bytes;
}

void trim_pinned_cache() noexcept {
  PinnedCache& c = cache();
  const std::lock_guard<std::mutex> lock(c.mutex);
  c.shrink_to(0);
}

bool is_page_locked(const void* host) noexcept {
#if defined(SLS_HAVE_CUDA)
  cudaPointerAttributes attributes{};
  if (host == nullptr || cudaPointerGetAttributes(&attributes, host) != cudaSuccess) {
    (void)cudaGetLastError();  // older drivers: an error for plain pageable memory
    return false;
  }
  return attributes.type == cudaMemoryTypeHost;
#else
  (void)host;
  return false;
#endif
}

PinnedMemoryStatistics pinned_memory_statistics() noexcept {
  PinnedCache& c = cache();
  const std::lock_guard<std::mutex> lock(c.mutex);
  return c.statistics;
}

void set_pinned_cache_limit(std::uint64_t bytes) noexcept {
  PinnedCache& c = cache();
  const std::lock_guard<std::mutex> lock(c.mutex);
  c.statistics.cache_limit_bytes = bytes;
  c.shrink_to(bytes);
}

}  // namespace sls
