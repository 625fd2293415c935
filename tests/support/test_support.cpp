#include "tests/support/test_support.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <cstdint>

#include "sdk/core/device.h"
#include "sdk/core/file_util.h"

namespace sls::test {

TemporaryDirectory::TemporaryDirectory() {
  static std::atomic<int> counter{0};
  const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = info != nullptr ? std::string(info->test_suite_name()) + "." + info->name() : "test";
  for (char& c : name) {
    if (c == '/') c = '_';
  }
  path_ = std::string(SLS_TEST_BINARY_DIR) + "/tmp/" + name + "-" + std::to_string(::getpid()) + "-" +
          std::to_string(counter++);
  std::filesystem::remove_all(path_);
  std::filesystem::create_directories(path_);
}

TemporaryDirectory::~TemporaryDirectory() {
  if (std::getenv("SLS_KEEP_TEST_FILES") == nullptr) {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
}

std::string shared_data_path(const std::string& relative) { return std::string(SLS_SHARED_DATA_DIR) + "/" + relative; }

bool has_cuda_device() { return sls::cuda_device_count() > 0; }

ErrorCode code_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& error) {
    return error.code();
  }
  return ErrorCode::kInternal;
}

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& error) {
    return error.what();
  }
  return "";
}

std::string bytes_of(const std::string& path) {
  const std::vector<std::uint8_t> bytes = read_file_bytes(path);
  return {bytes.begin(), bytes.end()};
}

std::vector<std::pair<std::string, std::string>> recording_snapshot(const std::string& folder) {
  std::vector<std::pair<std::string, std::string>> files;
  for (const std::filesystem::directory_entry& entry : std::filesystem::recursive_directory_iterator(folder)) {
    if (!entry.is_regular_file()) continue;
    const std::string relative = std::filesystem::relative(entry.path(), folder).string();
    std::string bytes = bytes_of(entry.path().string());
    if (relative == "manifest.json") {
      const std::size_t at = bytes.find("\"created_utc\"");
      if (at != std::string::npos) bytes.erase(at, bytes.find('\n', at) - at);
    }
    files.emplace_back(relative, std::move(bytes));
  }
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace sls::test
