#include <filesystem>

#include <gtest/gtest.h>

#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "tests/support/test_support.h"

namespace sls {
namespace {

TEST(FileUtil, AtomicWriteReplacesWholeFileAndLeavesNoTemporary) {
  test::TemporaryDirectory dir;
  const std::string path = dir.file("a.txt");
  write_file_atomic(path, "first version, long");
  write_file_atomic(path, "second");
  EXPECT_EQ(read_file_text(path), "second");
  int entries = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(dir.path())) ++entries;
  EXPECT_EQ(entries, 1);
}

TEST(FileUtil, ErrorsNameThePath) {
  test::TemporaryDirectory dir;
  try {
    read_file_bytes(dir.file("missing.bin"));
    FAIL();
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kNotFound);
    EXPECT_NE(std::string(error.what()).find("missing.bin"), std::string::npos);
  }
  EXPECT_THROW(write_file_atomic(dir.file("no/such/dir/x.txt"), "x"), Error);
}

}  // namespace
}  // namespace sls
