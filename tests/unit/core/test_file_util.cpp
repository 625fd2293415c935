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

TEST(FileUtil, AWritableOutputFolderIsCreatedAndAFileInTheWayIsAClearError) {
  test::TemporaryDirectory dir;
  ensure_writable_directory(dir.file("out/nested"));
  EXPECT_TRUE(std::filesystem::is_directory(dir.file("out/nested")));
  int entries = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(dir.file("out/nested"))) ++entries;
  EXPECT_EQ(entries, 0);  // the probe is gone
  write_file_atomic(dir.file("file"), "x");
  try {
    ensure_writable_directory(dir.file("file"));
    FAIL();
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kIo);
    EXPECT_NE(std::string(error.what()).find("not a directory"), std::string::npos) << error.what();
  }
  EXPECT_THROW(ensure_writable_directory(dir.file("file/below")), Error);
}

TEST(FileUtil, PathIsWithinComparesNormalisedPathsAndLinks) {
  test::TemporaryDirectory dir;
  create_directories(dir.file("rec/groundtruth"));
  EXPECT_TRUE(path_is_within(dir.file("rec"), dir.file("rec")));
  EXPECT_TRUE(path_is_within(dir.file("rec/groundtruth"), dir.file("rec")));
  EXPECT_TRUE(path_is_within(dir.file("rec/not-yet/deeper"), dir.file("rec/")));
  EXPECT_TRUE(path_is_within(dir.file("other/../rec/x"), dir.file("rec")));
  EXPECT_FALSE(path_is_within(dir.file("recording"), dir.file("rec")));  // a prefix of the name is not inside
  EXPECT_FALSE(path_is_within(dir.file("rec"), dir.file("rec/groundtruth")));
  std::filesystem::create_directory_symlink(dir.file("rec"), dir.file("link"));
  EXPECT_TRUE(path_is_within(dir.file("link/groundtruth"), dir.file("rec")));
}

}  // namespace
}  // namespace sls
