// Host memory admission: before a large allocation (a volume, a pattern stack), whether it
// fits in what this process may still use. Linux overcommits, so an allocation that does not
// fit usually "succeeds" and the process is killed later by the OOM killer, with no message:
// the check must come first.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

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

}  // namespace sls
