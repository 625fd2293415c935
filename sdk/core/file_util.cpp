#include "sdk/core/file_util.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>

#include "sdk/core/error.h"

namespace sls {

std::string describe_errno(const std::string& path, int error_number) {
  return path + ": " + std::strerror(error_number);
}

std::vector<std::uint8_t> read_file_bytes(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    const int error_number = errno;
    throw Error(error_number == ENOENT ? ErrorCode::kNotFound : ErrorCode::kIo,
                "cannot open " + describe_errno(path, error_number));
  }
  struct stat status {};
  if (::fstat(fd, &status) != 0 || !S_ISREG(status.st_mode)) {
    ::close(fd);
    throw_error(ErrorCode::kIo, "cannot read {}: not a regular file", path);
  }
  // One sized read (files are tens of MB: images, clouds), then whatever a growing file adds.
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(status.st_size));
  std::size_t filled = 0;
  for (;;) {
    if (filled == bytes.size()) bytes.resize(bytes.size() + 65536);
    const ssize_t n = ::read(fd, bytes.data() + filled, bytes.size() - filled);
    if (n < 0) {
      if (errno == EINTR) continue;
      const int error_number = errno;
      ::close(fd);
      throw Error(ErrorCode::kIo, "cannot read " + describe_errno(path, error_number));
    }
    if (n == 0) break;
    filled += static_cast<std::size_t>(n);
  }
  ::close(fd);
  bytes.resize(filled);
  return bytes;
}

std::string read_file_text(const std::string& path) {
  const std::vector<std::uint8_t> bytes = read_file_bytes(path);
  return std::string(bytes.begin(), bytes.end());
}

namespace {

void write_all(int fd, std::string_view bytes, const std::string& path) {
  std::size_t written = 0;
  while (written < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + written, bytes.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw Error(ErrorCode::kIo, "cannot write " + describe_errno(path, errno));
    }
    written += static_cast<std::size_t>(n);
  }
}

}  // namespace

void write_file_atomic(const std::string& path, std::string_view bytes) {
  const std::filesystem::path target(path);
  const std::string temporary = path + ".tmp-" + std::to_string(::getpid());
  const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw Error(ErrorCode::kIo, "cannot create " + describe_errno(temporary, errno));
  try {
    write_all(fd, bytes, temporary);
    if (::fsync(fd) != 0) throw Error(ErrorCode::kIo, "cannot flush " + describe_errno(temporary, errno));
  } catch (...) {
    ::close(fd);
    ::unlink(temporary.c_str());
    throw;
  }
  if (::close(fd) != 0) {
    const int error_number = errno;
    ::unlink(temporary.c_str());
    throw Error(ErrorCode::kIo, "cannot close " + describe_errno(temporary, error_number));
  }
  if (::rename(temporary.c_str(), path.c_str()) != 0) {
    const int error_number = errno;
    ::unlink(temporary.c_str());
    throw Error(ErrorCode::kIo, "cannot rename " + temporary + " to " + describe_errno(path, error_number));
  }
  const std::filesystem::path parent = target.has_parent_path() ? target.parent_path() : ".";
  sync_directory(parent.string());
}

void create_directories(const std::string& path) {
  std::error_code error;
  std::filesystem::create_directories(path, error);
  if (error) throw_error(ErrorCode::kIo, "cannot create directory {}: {}", path, error.message());
}

void ensure_writable_directory(const std::string& path) {
  std::error_code error;
  if (std::filesystem::exists(path, error) && !std::filesystem::is_directory(path, error)) {
    throw_error(ErrorCode::kIo, "output folder {} is not a directory (a file of that name is in the way)", path);
  }
  create_directories(path);
  // mkstemp's template: it replaces the trailing six X with a unique suffix.
  std::string probe = (std::filesystem::path(path) / ".sls-write-test-XXXXXX").string();
  const int fd = ::mkstemp(probe.data());
  if (fd < 0) throw_error(ErrorCode::kIo, "output folder {} is not writable: {}", path, std::strerror(errno));
  ::close(fd);
  ::unlink(probe.c_str());
}

bool path_is_within(const std::string& path, const std::string& folder) {
  std::error_code inner_error, outer_error;
  const std::filesystem::path inner = std::filesystem::weakly_canonical(std::filesystem::absolute(path), inner_error);
  const std::filesystem::path outer =
      std::filesystem::weakly_canonical(std::filesystem::absolute(folder), outer_error);
  if (inner_error || outer_error) return false;
  auto a = inner.begin();
  for (auto b = outer.begin(); b != outer.end(); ++b, ++a) {
    if (b->empty()) continue;  // a trailing separator
    if (a == inner.end() || *a != *b) return false;
  }
  return true;
}

void sync_directory(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;  // best effort: some filesystems do not allow opening directories
  (void)::fsync(fd);
  ::close(fd);
}

}  // namespace sls
