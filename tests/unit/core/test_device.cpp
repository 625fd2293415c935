#include <gtest/gtest.h>

#include "sdk/core/device.h"
#include "sdk/core/error.h"

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

}  // namespace
}  // namespace sls
