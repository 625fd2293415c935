// Host memory admission: before a large allocation (a volume, a pattern stack), whether it
// fits in what this process may still use. Linux overcommits, so an allocation that does not
// fit usually "succeeds" and the process is killed later by the OOM killer, with no message:
// the check must come first.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace sls {

struct HostMemoryAvailable {
  std::uint64_t bytes = 0;  // the least of the limits below that apply
  std::string limited_by;   // which one: "MemAvailable", "the cgroup's memory.max", "ulimit -v"
};

// What the process may still allocate: the kernel's MemAvailable (/proc/meminfo), the control
// group's limit less its usage (cgroup v2 memory.max, v1 memory.limit_in_bytes), and the
// address-space limit (RLIMIT_AS) less the process's size, whichever is least. Without
// /proc (not Linux), UINT64_MAX and "unknown".
HostMemoryAvailable host_memory_available();

// Throws sls::Error(kOutOfMemory) when `bytes` exceed what is available: "`what` needs N MiB
// of host memory; M MiB are available (limited by ...)` followed by `hint` (what fixes it).
void admit_host_allocation(std::uint64_t bytes, const std::string& what, const std::string& hint);

// memcpy spread over the machine's threads (OpenMP; one thread when built without it): one
// thread copies 5-10 GB/s, too slow to stage a 12-megapixel pattern stack (528 MB) into the
// pinned memory a GPU upload needs at the bus's rate. The ranges must not overlap.
void copy_bytes_parallel(void* destination, const void* source, std::size_t bytes);

// Maps the pages of [data, data + bytes), memory allocated but not yet written (a vector's
// reserved capacity), spread over the machine's threads: on Linux 5.14 or later through
// madvise(MADV_POPULATE_WRITE), elsewhere nothing (the first writes map them, as always). A
// fresh array's first write costs a page fault every 4 KiB, ~1.4 GB/s on one thread: a
// paper-size model's joined arrays (~0.6 GB, zeroed as std::vector sizes them) spent ~0.4 s in
// them. Only whole pages inside the range are touched; their contents are left as they are.
void populate_pages_parallel(void* data, std::size_t bytes);

// values->resize(count) (new elements value-initialised, as std::vector does), its new pages
// mapped first on all threads (populate_pages_parallel), so that the zeroing and the writes
// after it run at memory speed instead of page-fault speed.
template <typename T>
void resize_populated(std::vector<T>* values, std::size_t count) {
  if (count > values->size()) {
    values->reserve(count);
    populate_pages_parallel(reinterpret_cast<unsigned char*>(values->data()) + values->size() * sizeof(T),
                            (count - values->size()) * sizeof(T));
  }
  values->resize(count);
}

}  // namespace sls
