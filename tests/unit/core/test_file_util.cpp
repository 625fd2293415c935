#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <functional>
#include <future>

#include <gtest/gtest.h>

#include "sdk/core/calibration.h"
#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/image_io.h"
#include "sdk/core/ply.h"
#include "sdk/core/recording.h"
#include "sdk/core/trajectory.h"
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

// Every reader of a data file, by the path it reads.
const std::vector<std::pair<std::string, std::function<void(const std::string&)>>>& data_readers() {
  static const std::vector<std::pair<std::string, std::function<void(const std::string&)>>> readers = {
      {"read_file_bytes", [](const std::string& path) { (void)read_file_bytes(path); }},
      {"read_ply_mesh", [](const std::string& path) { (void)read_ply_mesh(path); }},
      {"read_png", [](const std::string& path) { (void)read_png(path); }},
      {"read_png_header", [](const std::string& path) { (void)read_png_header(path); }},
      {"read_pfm", [](const std::string& path) { (void)read_pfm(path); }},
      {"read_calibration", [](const std::string& path) { (void)read_calibration(path); }},
      {"read_tum_trajectory", [](const std::string& path) { (void)read_tum_trajectory(path); }},
  };
  return readers;
}

// Runs `read` on `path` and expects sls::Error(kIo) naming the path and `what` within
// seconds. A reader that blocks on a FIFO is released by opening the FIFO for writing, so
// the test fails instead of hanging.
void expect_refused_quickly(const std::string& reader, const std::function<void(const std::string&)>& read,
                            const std::string& path, const std::string& what) {
  std::future<std::string> outcome = std::async(std::launch::async, [&]() -> std::string {
    try {
      read(path);
      return "no error";
    } catch (const Error& error) {
      if (error.code() != ErrorCode::kIo) return std::string("wrong code: ") + error.what();
      return error.what();
    }
  });
  if (outcome.wait_for(std::chrono::seconds(10)) != std::future_status::ready) {
    const int fd = ::open(path.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd >= 0) ::close(fd);
    ADD_FAILURE() << reader << " blocked on " << path;
  }
  const std::string message = outcome.get();
  EXPECT_NE(message.find(path), std::string::npos) << reader << ": " << message;
  EXPECT_NE(message.find(what), std::string::npos) << reader << ": " << message;
}

TEST(FileUtil, AFifoInPlaceOfADataFileIsRefusedAtOnceByEveryReader) {
  test::TemporaryDirectory dir;
  const std::string fifo = dir.file("model.ply");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  for (const auto& [name, read] : data_readers()) {
    expect_refused_quickly(name, read, fifo, "is a FIFO (named pipe), not a regular file");
  }
  // The manifest of a recording too (its reader reads it through read_file_text).
  create_directories(dir.file("recording"));
  ASSERT_EQ(::mkfifo(dir.file("recording/manifest.json").c_str(), 0600), 0);
  expect_refused_quickly("RecordingReader::open", [](const std::string& folder) { (void)RecordingReader::open(folder); },
                         dir.file("recording"), "manifest.json: it is a FIFO");
}

TEST(FileUtil, ALinkToADeviceOrADirectoryIsRefusedWithoutReading) {
  test::TemporaryDirectory dir;
  // A link to /dev/zero would otherwise be read until memory runs out.
  std::filesystem::create_symlink("/dev/zero", dir.file("zero.ply"));
  create_directories(dir.file("folder.ply"));
  for (const auto& [name, read] : data_readers()) {
    expect_refused_quickly(name, read, dir.file("zero.ply"), "is a character device, not a regular file");
    expect_refused_quickly(name, read, dir.file("folder.ply"), "is a directory, not a regular file");
  }
}

TEST(FileUtil, AFileOverTheLimitIsRefusedBeforeItIsRead) {
  test::TemporaryDirectory dir;
  const std::string path = dir.file("manifest.json");
  write_file_atomic(path, std::string(100, 'x'));
  EXPECT_EQ(read_file_bytes(path, 100).size(), 100u);  // exactly the limit is fine
  try {
    (void)read_file_bytes(path, 99);
    FAIL();
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kFormat);
    EXPECT_NE(std::string(error.what()).find(path + ": the file holds 100 bytes, more than the 99 bytes"),
              std::string::npos)
        << error.what();
  }
  // A sparse file of 1 GiB: refused from its size alone, nothing is allocated or read.
  const std::string sparse = dir.file("calibration.yml");
  const int fd = ::open(sparse.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::ftruncate(fd, off_t{1} << 30), 0);
  ::close(fd);
  EXPECT_THROW((void)read_file_text(sparse), Error);
  EXPECT_THROW((void)read_calibration(sparse), Error);
  EXPECT_THROW((void)read_tum_trajectory(sparse), Error);
}

TEST(FileUtil, RegularFileReadsAtOffsets) {
  test::TemporaryDirectory dir;
  const std::string path = dir.file("data.bin");
  write_file_atomic(path, "0123456789");
  const RegularFile file(path);
  EXPECT_EQ(file.size(), 10u);
  char buffer[8] = {};
  EXPECT_EQ(file.read_at(4, buffer, 4), 4u);
  EXPECT_EQ(std::string(buffer, 4), "4567");
  EXPECT_EQ(file.read_at(8, buffer, 8), 2u);  // fewer at the end of the file
  EXPECT_EQ(std::string(buffer, 2), "89");
  EXPECT_EQ(file.read_all(10).size(), 10u);
}

}  // namespace
}  // namespace sls
