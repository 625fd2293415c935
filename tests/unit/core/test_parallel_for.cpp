// parallel_for on the CPU: every element once, nothing for none, and a CUDA loop asked of code
// compiled for the CPU is a clear error (the CUDA loop: test_parallel_for_cuda.cu).
#include <cstddef>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "sdk/core/error.h"
#include "sdk/core/kernel_profile.h"
#include "sdk/core/parallel_for.h"

namespace sls {
namespace {

TEST(ParallelFor, CpuRunsEveryElementOnce) {
  const std::size_t count = 100003;  // not a multiple of any thread count
  std::vector<unsigned> visits(count, 0u);
  unsigned* out = visits.data();
  parallel_for(Device::cpu(), count, SLS_LAMBDA(std::size_t i) { out[i] += 1u + static_cast<unsigned>(i % 7); });
  for (std::size_t i = 0; i < count; ++i) ASSERT_EQ(visits[i], 1u + i % 7) << "element " << i;
}

TEST(ParallelFor, NoElementsRunsNothing) {
  bool ran = false;
  parallel_for(Device::cpu(), 0, [&ran](std::size_t) { ran = true; });
  EXPECT_FALSE(ran);
}

TEST(KernelProfile, OffByDefaultAndATimerRecordsNothingThen) {
  EXPECT_FALSE(kernel_profiling());
  { const KernelTimer timer("nothing", 1.0, nullptr); }
  EXPECT_TRUE(kernel_profile().empty());
}

TEST(ParallelFor, CudaLoopInCpuCodeIsUnsupported) {
  std::vector<int> values(4, 0);
  int* out = values.data();
  try {
    parallel_for(Device::cuda(0), values.size(), SLS_LAMBDA(std::size_t i) { out[i] = 1; });
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kUnsupported);
    EXPECT_NE(std::string(e.what()).find("compiled for the CPU only"), std::string::npos) << e.what();
  }
  EXPECT_EQ(values, std::vector<int>(4, 0));
}

}  // namespace
}  // namespace sls
