// What this process holds, for the long-run tests and benchmarks (test_scan_soak, bench_soak):
// resident memory, the heap's live bytes and the GPU memory in use, in MiB. Header-only, so a
// benchmark can use it without the gtest-based support library.
#pragma once

#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define SLS_PROCESS_MEMORY_ASAN 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__) && !defined(SLS_PROCESS_MEMORY_ASAN)
#define SLS_PROCESS_MEMORY_ASAN 1
#endif
#if defined(SLS_PROCESS_MEMORY_ASAN)
// The ASan runtime's (sanitizer/allocator_interface.h, which gcc does not install everywhere).
extern "C" std::size_t __sanitizer_get_current_allocated_bytes();
#else
#include <malloc.h>
#endif
#if defined(SLS_HAVE_CUDA)
#include <cuda_runtime_api.h>
#endif

namespace sls::test {

constexpr double kMiB = 1048576.0;

// VmRSS: pages resident, including those the allocator keeps after a free.
inline double rss_mib() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::atof(line.c_str() + 6) / 1024.0;  // kB
  }
  return 0.0;
}

// VmRSS after the allocator has returned its free pages to the system (glibc's malloc_trim, all
// arenas): live memory and fragmentation, without the free blocks kept by design, which moved
// RSS by up to 10 MiB between identical scans in one process (test_scan_soak, 2026-11-29). Under
// ASan (its own allocator, no trim) the plain VmRSS.
inline double settled_rss_mib() {
#if !defined(SLS_PROCESS_MEMORY_ASAN)
  malloc_trim(0);
#endif
  return rss_mib();
}

// Bytes the program holds on the heap (freed ones excluded): exact for leaks, unlike RSS, which
// keeps pages the allocator has not returned (and, under ASan, its quarantine of freed blocks).
inline double heap_mib() {
#if defined(SLS_PROCESS_MEMORY_ASAN)
  return static_cast<double>(__sanitizer_get_current_allocated_bytes()) / kMiB;
#else
  const struct mallinfo2 info = mallinfo2();
  return static_cast<double>(info.uordblks + info.hblkhd) / kMiB;
#endif
}

// The GPU's memory in use (all processes: cudaMemGetInfo), 0 without CUDA or a device.
inline double gpu_used_mib() {
#if defined(SLS_HAVE_CUDA)
  std::size_t free_bytes = 0, total_bytes = 0;
  if (cudaMemGetInfo(&free_bytes, &total_bytes) != cudaSuccess) return 0.0;
  return static_cast<double>(total_bytes - free_bytes) / kMiB;
#else
  return 0.0;
#endif
}

// Limits this process's address space (ulimit -v) to its present size plus `headroom_bytes`:
// for a forked child that checks memory admission. False when the size is unknown or the limit
// cannot be set. (Not under the sanitizers: their shadow memory needs the address space.)
inline bool limit_address_space(std::uint64_t headroom_bytes) {
  std::ifstream status("/proc/self/status");
  std::string line;
  std::uint64_t vm_kb = 0;
  while (std::getline(status, line)) {
    if (line.rfind("VmSize:", 0) == 0) vm_kb = std::strtoull(line.c_str() + 7, nullptr, 10);
  }
  if (vm_kb == 0) return false;
  rlimit limit{};
  if (getrlimit(RLIMIT_AS, &limit) != 0) return false;
  limit.rlim_cur = static_cast<rlim_t>(vm_kb * 1024u + headroom_bytes);
  return setrlimit(RLIMIT_AS, &limit) == 0;
}

// Whether limit_address_space binds here: a forked child limits itself to 16 MiB more and must
// be refused a 256 MiB mapping. Not under a user-mode emulator (qemu-user, the aarch64 tests),
// whose own reservations and mappings are what the kernel sees: there a memory admission test
// skips, as it is compiled out under the sanitizers.
inline bool address_space_limits_hold() {
  const pid_t child = fork();
  if (child < 0) return false;
  if (child == 0) {
    if (!limit_address_space(16ull << 20)) _exit(2);
    void* mapping = mmap(nullptr, 256ull << 20, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    _exit(mapping == MAP_FAILED ? 0 : 1);
  }
  int status = 0;
  if (waitpid(child, &status, 0) != child) return false;
  return WIFEXITED(status) && WEXITSTATUS(status) == 0;
}

// The upper median (0 for none).
inline double median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

}  // namespace sls::test
