// Host memory admission (host_memory.h): what the process may still allocate, and a refusal
// that names the size asked, the size available and the limit, before anything is allocated.
#include <string>

#include <gtest/gtest.h>

#include "sdk/core/error.h"
#include "sdk/core/host_memory.h"

namespace sls {
namespace {

TEST(HostMemory, AvailableIsKnownOnLinux) {
  const HostMemoryAvailable available = host_memory_available();
  EXPECT_GT(available.bytes, 16u << 20) << available.limited_by;  // a machine that runs the tests
  EXPECT_NE(available.limited_by, "unknown");
}

TEST(HostMemory, AdmitsWhatFitsAndRefusesWhatDoesNotNamingTheSizes) {
  EXPECT_NO_THROW(admit_host_allocation(1u << 20, "a small buffer", "no hint"));
  const HostMemoryAvailable available = host_memory_available();
  try {
    admit_host_allocation(available.bytes + (1ull << 30), "a volume of test voxels", "use larger voxels");
    FAIL() << "admitted 1 GiB more than available";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kOutOfMemory);
    const std::string message = error.what();
    EXPECT_NE(message.find("a volume of test voxels needs"), std::string::npos) << message;
    EXPECT_NE(message.find("MiB are available (limited by"), std::string::npos) << message;
    EXPECT_NE(message.find("use larger voxels"), std::string::npos) << message;
  }
}

}  // namespace
}  // namespace sls
