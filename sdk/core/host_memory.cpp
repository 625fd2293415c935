#include "sdk/core/host_memory.h"

#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

#include "sdk/core/error.h"

namespace sls {
namespace {

constexpr std::uint64_t kUnlimited = std::numeric_limits<std::uint64_t>::max();

// "Key:   123 kB" of /proc/meminfo and /proc/self/status, in bytes; kUnlimited when absent.
std::uint64_t proc_kilobytes(const char* path, const std::string& key) {
  std::ifstream file(path);
  std::string line;
  while (std::getline(file, line)) {
    if (line.compare(0, key.size(), key) != 0 || line.size() <= key.size() || line[key.size()] != ':') continue;
    std::istringstream fields(line.substr(key.size() + 1));
    std::uint64_t kilobytes = 0;
    if (fields >> kilobytes) return kilobytes * 1024u;
  }
  return kUnlimited;
}

// A number in a one-line control-group file; kUnlimited for "max", a missing file or garbage.
std::uint64_t cgroup_value(const std::string& path) {
  std::ifstream file(path);
  std::string text;
  if (!(file >> text) || text == "max") return kUnlimited;
  try {
    return std::stoull(text);
  } catch (const std::exception&) {
    return kUnlimited;
  }
}

// The cgroup limit less usage (v2, then v1); kUnlimited without one. v1 reports "no limit"
// as a huge number, which min() below handles the same way.
std::uint64_t cgroup_headroom() {
  for (const auto& [limit_file, usage_file] :
       {std::pair{"/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"},
        std::pair{"/sys/fs/cgroup/memory/memory.limit_in_bytes", "/sys/fs/cgroup/memory/memory.usage_in_bytes"}}) {
    const std::uint64_t limit = cgroup_value(limit_file);
    if (limit == kUnlimited) continue;
    const std::uint64_t usage = cgroup_value(usage_file);
    return usage == kUnlimited || usage >= limit ? 0 : limit - usage;
  }
  return kUnlimited;
}

std::uint64_t address_space_headroom() {
  rlimit limit{};
  if (getrlimit(RLIMIT_AS, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY) return kUnlimited;
  const std::uint64_t size = proc_kilobytes("/proc/self/status", "VmSize");
  if (size == kUnlimited) return kUnlimited;
  return size >= limit.rlim_cur ? 0 : static_cast<std::uint64_t>(limit.rlim_cur) - size;
}

double mib(std::uint64_t bytes) { return static_cast<double>(bytes) / 1048576.0; }

}  // namespace

HostMemoryAvailable host_memory_available() {
  HostMemoryAvailable available{kUnlimited, "unknown"};
  const auto consider = [&](std::uint64_t bytes, const char* name) {
    if (bytes < available.bytes) available = {bytes, name};
  };
  consider(proc_kilobytes("/proc/meminfo", "MemAvailable"), "MemAvailable");
  consider(cgroup_headroom(), "the cgroup's memory limit");
  consider(address_space_headroom(), "ulimit -v");
  return available;
}

void admit_host_allocation(std::uint64_t bytes, const std::string& what, const std::string& hint) {
  const HostMemoryAvailable available = host_memory_available();
  if (bytes <= available.bytes) return;
  throw_error(ErrorCode::kOutOfMemory, "{} needs {:.1f} MiB of host memory; {:.1f} MiB are available (limited by {}){}",
              what, mib(bytes), mib(available.bytes), available.limited_by, hint.empty() ? "" : ": " + hint);
}

void copy_bytes_parallel(void* destination, const void* source, std::size_t bytes) {
  // Pieces of 1 MiB or more: a 12-megapixel plane (24 MB) in 24 keeps 16 threads busy;
  // smaller pieces and the threads' hand-off costs more than their copy saves.
  constexpr std::size_t kPiece = std::size_t{1} << 20;
  const std::size_t pieces = std::max<std::size_t>(1, bytes / kPiece);
  auto* out = static_cast<unsigned char*>(destination);
  const auto* in = static_cast<const unsigned char*>(source);
  const auto count = static_cast<std::ptrdiff_t>(pieces);
#if defined(_OPENMP)
#pragma omp parallel for schedule(static) if (pieces > 1)
#endif
  for (std::ptrdiff_t p = 0; p < count; ++p) {
    const std::size_t begin = static_cast<std::size_t>(p) * bytes / pieces;
    const std::size_t end = static_cast<std::size_t>(p + 1) * bytes / pieces;
    std::memcpy(out + begin, in + begin, end - begin);
  }
}

void populate_pages_parallel(void* data, std::size_t bytes) {
#if defined(MADV_POPULATE_WRITE)
  const long page_size = sysconf(_SC_PAGESIZE);
  if (page_size <= 0 || data == nullptr) return;
  const auto page = static_cast<std::uintptr_t>(page_size);
  const auto start = reinterpret_cast<std::uintptr_t>(data);
  const std::uintptr_t first = (start + page - 1) / page * page;  // whole pages only
  const std::uintptr_t last = (start + bytes) / page * page;
  if (last <= first) return;
  // Pieces of 2 MiB: a thread's madvise maps 512 pages per call; ~300 pieces for a model's
  // 0.6 GB keep 16 threads busy.
  constexpr std::uintptr_t kPiece = std::uintptr_t{1} << 21;
  const std::uintptr_t span = last - first;
  const auto count = static_cast<std::ptrdiff_t>((span + kPiece - 1) / kPiece);
#if defined(_OPENMP)
#pragma omp parallel for schedule(static) if (count > 1)
#endif
  for (std::ptrdiff_t p = 0; p < count; ++p) {
    const std::uintptr_t begin = first + static_cast<std::uintptr_t>(p) * kPiece;
    const std::uintptr_t end = std::min(last, begin + kPiece);
    // A kernel without MADV_POPULATE_WRITE (EINVAL) or memory it cannot map now (ENOMEM) only
    // leaves the pages to the first writes, which report the shortage as they always would.
    (void)madvise(reinterpret_cast<void*>(begin), end - begin, MADV_POPULATE_WRITE);
  }
#else
  (void)data;
  (void)bytes;
#endif
}

}  // namespace sls
