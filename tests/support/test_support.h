// Helpers shared by the tests: temporary folders, paths to test data, GPU skipping.
#pragma once

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "sdk/core/error.h"

namespace sls::test {

// A fresh empty directory under the build tree, removed when the object is destroyed
// (kept when the environment variable SLS_KEEP_TEST_FILES is set, for debugging).
class TemporaryDirectory {
 public:
  TemporaryDirectory();
  ~TemporaryDirectory();
  TemporaryDirectory(const TemporaryDirectory&) = delete;
  TemporaryDirectory& operator=(const TemporaryDirectory&) = delete;
  const std::string& path() const { return path_; }
  std::string file(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

// ../shared/data/<relative>
std::string shared_data_path(const std::string& relative);

bool has_cuda_device();

// The code of the sls::Error that `f` throws; ErrorCode::kInternal when it throws none.
ErrorCode code_of(const std::function<void()>& f);
// The message of the sls::Error that `f` throws; empty when it throws none.
std::string message_of(const std::function<void()>& f);

// A file's bytes as a string (throws sls::Error when it cannot be read).
std::string bytes_of(const std::string& path);
// Every file under a recording's `folder` (relative path -> bytes, sorted), its manifest without
// the creation time: two recordings of the same frames compare equal.
std::vector<std::pair<std::string, std::string>> recording_snapshot(const std::string& folder);

}  // namespace sls::test

// Skips the current test (reported by ctest as skipped, not passed) when no GPU is present.
#define SLS_REQUIRE_CUDA_DEVICE()                                              \
  do {                                                                         \
    if (!::sls::test::has_cuda_device()) GTEST_SKIP() << "no CUDA device";     \
  } while (0)
