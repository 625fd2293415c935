#include <gtest/gtest.h>

#include "sdk/core/device.h"
#include "sdk/core/error.h"
#include "tests/support/test_support.h"

namespace sls {
namespace {

TEST(Device, ParsesAndPrints) {
  EXPECT_EQ(parse_device("cpu"), Device::cpu());
  EXPECT_EQ(parse_device("cuda"), Device::cuda(0));
  EXPECT_EQ(parse_device("cuda:3"), Device::cuda(3));
  EXPECT_EQ(parse_device("cuda:3").to_string(), "cuda:3");
  for (const char* bad : {"", "gpu", "cuda:", "cuda:x", "cuda:-1", "cuda:1x"}) {
    EXPECT_THROW(parse_device(bad), Error) << bad;
  }
}

TEST(Device, CudaRequestWithoutGpuIsAClearError) {
  EXPECT_NO_THROW(require_device(Device::cpu()));
  const int count = cuda_device_count();
  try {
    require_device(Device::cuda(count));  // one past the last device always fails
    FAIL() << "expected an error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), cuda_compiled() ? ErrorCode::kDevice : ErrorCode::kUnsupported);
    EXPECT_NE(std::string(error.what()).find("cuda:"), std::string::npos);
  }
}

// sls bench's GPU figures: the CPU is not a GPU; a missing GPU is require_device's error; on a
// GPU the memory in use is within its total and a copy moves at a positive rate (its size:
// 64 MiB, enough for a rate, small enough for any GPU).
TEST(Device, GpuMemoryAndCopyBandwidth) {
  EXPECT_EQ(test::code_of([] { gpu_memory(Device::cpu()); }), ErrorCode::kInvalidArgument);
  EXPECT_EQ(test::code_of([] { copy_bandwidth_gbps(Device::cpu()); }), ErrorCode::kInvalidArgument);
  const int count = cuda_device_count();
  const ErrorCode missing = cuda_compiled() ? ErrorCode::kDevice : ErrorCode::kUnsupported;
  EXPECT_EQ(test::code_of([count] { gpu_memory(Device::cuda(count)); }), missing);
  EXPECT_EQ(test::code_of([count] { copy_bandwidth_gbps(Device::cuda(count)); }), missing);
  if (count == 0) GTEST_SKIP() << "no GPU: its figures are not measured here";
  const GpuMemory memory = gpu_memory(Device::cuda(0));
  EXPECT_GT(memory.total_bytes, 0u);
  EXPECT_LE(memory.used_bytes, memory.total_bytes);
  EXPECT_GT(copy_bandwidth_gbps(Device::cuda(0), std::size_t{64} << 20), 0.0);
  EXPECT_EQ(test::code_of([] { copy_bandwidth_gbps(Device::cuda(0), 0); }), ErrorCode::kInvalidArgument);
}

}  // namespace
}  // namespace sls
