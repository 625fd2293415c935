// Host memory admission (host_memory.h): what the process may still allocate, and a refusal
// that names the size asked, the size available and the limit, before anything is allocated;
// and the pages of a large array mapped on all threads before its first writes.
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <numeric>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "sdk/core/error.h"
#include "sdk/core/host_memory.h"
#include "sdk/core/recording.h"
#include "tests/support/process_memory.h"
#include "tests/support/test_support.h"

namespace sls {
namespace {

TEST(HostMemory, AvailableIsKnownOnLinux) {
  const HostMemoryAvailable available = host_memory_available();
  EXPECT_GT(available.bytes, 16u << 20) << available.limited_by;  // a machine that runs the tests
  EXPECT_NE(available.limited_by, "unknown");
}

// The pages mapped ahead of the writes: what a vector holds is exactly what resize gives it —
// old values kept, new ones zero — whatever the start's alignment and however many threads'
// pieces the range spans; and mapping pages already written changes none of their bytes.
TEST(HostMemory, ResizePopulatedKeepsTheValuesAndZeroesTheNewOnes) {
  std::vector<float> values;
  resize_populated(&values, 3);  // less than a page
  EXPECT_EQ(values, std::vector<float>(3, 0.0f));
  values = {1.0f, 2.0f, 3.0f};
  const std::size_t count = (std::size_t{40} << 20) / sizeof(float) + 7;  // 40 MiB: many 2 MiB pieces
  resize_populated(&values, count);
  ASSERT_EQ(values.size(), count);
  EXPECT_EQ(values[0], 1.0f);
  EXPECT_EQ(values[1], 2.0f);
  EXPECT_EQ(values[2], 3.0f);
  EXPECT_EQ(std::count(values.begin() + 3, values.end(), 0.0f), static_cast<std::ptrdiff_t>(count - 3));
  resize_populated(&values, 2);
  EXPECT_EQ(values, (std::vector<float>{1.0f, 2.0f}));

  std::vector<std::uint32_t> written(std::size_t{6} << 20);
  std::iota(written.begin(), written.end(), 7u);
  populate_pages_parallel(reinterpret_cast<unsigned char*>(written.data()) + 5, written.size() * 4 - 5);
  populate_pages_parallel(written.data(), 0);
  populate_pages_parallel(nullptr, 4096);
  for (std::size_t i = 0; i < written.size(); ++i) {
    if (written[i] != static_cast<std::uint32_t>(i + 7)) FAIL() << "value " << i << " changed to " << written[i];
  }
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

#if !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)  // they need the address space
// A recording's pattern stack (8 images of 2048x1536: 48 MiB) read in a child limited to its
// size plus 16 MiB (ulimit -v): refused before allocating, naming the frame and the limit, and
// not as a problem of the frame (a scan stops with it rather than skipping every frame).
TEST(HostMemory, APatternStackBeyondTheLimitIsRefusedBeforeItIsRead) {
  if (!test::address_space_limits_hold()) GTEST_SKIP() << "ulimit -v does not bind here (a user-mode emulator)";
  test::TemporaryDirectory dir;
  RecordingInfo info;
  info.device = {"sim://stack", "slscan-sim", "SN-1"};
  info.camera = {2048, 1536, 12};
  info.pattern_set_json = R"({"name": "test", "image_count": 8})";
  info.images_per_frame = 8;
  {
    RecordingWriterOptions options;
    options.sync = false;
    RecordingWriter writer = RecordingWriter::create(dir.file("rec"), info, std::nullopt, options);
    writer.append_frame(std::vector<Image16u>(8, Image16u(2048, 1536)), FrameMetadata{});
  }
  const RecordingReader recording = RecordingReader::open(dir.file("rec"));
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    if (!test::limit_address_space(16ull << 20)) _exit(3);
    try {
      (void)recording.load_images(0);
    } catch (const Error& error) {
      const bool named = std::strstr(error.what(), "frame 0's pattern stack (8 images of 2048x1536) needs 48.0 MiB") &&
                         std::strstr(error.what(), "ulimit -v");
      _exit(error.code() == ErrorCode::kOutOfMemory && named && !is_frame_problem(error) ? 0 : 2);
    }
    _exit(1);
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << "1: the stack was read beyond the limit; 2: another error; 3: no limit set";
  // Without the limit it reads.
  EXPECT_EQ(recording.load_images(0).size(), 8u);
}
#endif

}  // namespace
}  // namespace sls
