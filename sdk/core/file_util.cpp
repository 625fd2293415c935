#include "sdk/core/file_util.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>

#include "sdk/core/error.h"

namespace sls {

std::string describe_errno(const std::string& path, int error_number) {
  return path + ": " + std::strerror(error_number);
}

namespace {

// What a non-regular file is, for "cannot read X: it is ..., not a regular file".
const char* describe_file_type(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO (named pipe)";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a plain file";
}

// "1048576 bytes (1.0 MiB)": exact, and readable when large.
std::string describe_size(std::uint64_t bytes) {
  if (bytes < (std::uint64_t{1} << 20)) return fmt::format("{} bytes", bytes);
  return fmt::format("{} bytes ({:.1f} MiB)", bytes,
                     static_cast<double>(bytes) / static_cast<double>(std::uint64_t{1} << 20));
}

// `size` is what was found: the file's size, or how far a growing file was read.
[[noreturn]] void throw_too_large(const std::string& path, std::uint64_t size, std::uint64_t max_bytes) {
  throw_error(ErrorCode::kFormat, "{}: the file holds {}, more than the {} a file of this kind may hold", path,
              describe_size(size), describe_size(max_bytes));
}

}  // namespace

RegularFile::RegularFile(const std::string& path) : path_(path) {
  // O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer, forever.
  fd_ = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) {
    const int error_number = errno;
    struct stat status {};
    // A socket cannot be opened at all (ENXIO); say what it is rather than the OS's words.
    if (error_number == ENXIO && ::stat(path.c_str(), &status) == 0 && !S_ISREG(status.st_mode)) {
      throw_error(ErrorCode::kIo, "cannot read {}: it is {}, not a regular file", path,
                  describe_file_type(status.st_mode));
    }
    throw Error(error_number == ENOENT ? ErrorCode::kNotFound : ErrorCode::kIo,
                "cannot open " + describe_errno(path, error_number));
  }
  struct stat status {};
  if (::fstat(fd_, &status) != 0) {
    const int error_number = errno;
    ::close(fd_);
    throw Error(ErrorCode::kIo, "cannot read " + describe_errno(path, error_number));
  }
  if (!S_ISREG(status.st_mode)) {
    ::close(fd_);
    throw_error(ErrorCode::kIo, "cannot read {}: it is {}, not a regular file", path,
                describe_file_type(status.st_mode));
  }
  // Back to ordinary reads (O_NONBLOCK means nothing for a regular file, but say what we mean).
  const int flags = ::fcntl(fd_, F_GETFL);
  if (flags >= 0) (void)::fcntl(fd_, F_SETFL, flags & ~O_NONBLOCK);
  size_ = static_cast<std::uint64_t>(status.st_size);
}

RegularFile::~RegularFile() { ::close(fd_); }

std::size_t RegularFile::read_at(std::uint64_t offset, void* out, std::size_t count) const {
  auto* bytes = static_cast<std::uint8_t*>(out);
  std::size_t filled = 0;
  while (filled < count) {
    const ssize_t n = ::pread(fd_, bytes + filled, count - filled, static_cast<off_t>(offset + filled));
    if (n < 0) {
      if (errno == EINTR) continue;
      throw Error(ErrorCode::kIo, "cannot read " + describe_errno(path_, errno));
    }
    if (n == 0) break;
    filled += static_cast<std::size_t>(n);
  }
  return filled;
}

void RegularFile::check_size(std::uint64_t max_bytes) const {
  if (size_ > max_bytes) throw_too_large(path_, size_, max_bytes);
}

std::vector<std::uint8_t> RegularFile::read_all(std::uint64_t max_bytes) const {
  std::vector<std::uint8_t> bytes;
  read_all(max_bytes, &bytes);
  return bytes;
}

void RegularFile::read_all(std::uint64_t max_bytes, std::vector<std::uint8_t>* out) const {
  check_size(max_bytes);
  // One sized read, then whatever a growing file adds, up to one byte past the limit to
  // tell "exactly the limit" from "more". Only what the vector lacks is allocated (and
  // value-initialised) first.
  std::vector<std::uint8_t>& bytes = *out;
  if (bytes.size() < size_) bytes.resize(static_cast<std::size_t>(size_));
  std::size_t filled = read_at(0, bytes.data(), static_cast<std::size_t>(size_));
  if (filled == size_) {
    for (;;) {
      const std::uint64_t room = max_bytes + 1 - filled;
      const std::size_t chunk = static_cast<std::size_t>(std::min<std::uint64_t>(room, 65536));
      if (chunk == 0) throw_too_large(path_, filled, max_bytes);
      bytes.resize(filled + chunk);
      const std::size_t n = read_at(filled, bytes.data() + filled, chunk);
      filled += n;
      if (n < chunk) break;
    }
    if (filled > max_bytes) throw_too_large(path_, filled, max_bytes);
  }
  bytes.resize(filled);
}

std::vector<std::uint8_t> read_file_bytes(const std::string& path, std::uint64_t max_bytes) {
  return RegularFile(path).read_all(max_bytes);
}

std::string read_file_text(const std::string& path, std::uint64_t max_bytes) {
  const std::vector<std::uint8_t> bytes = read_file_bytes(path, max_bytes);
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

void ensure_writable_directory(const std::string& path, std::uint64_t min_free_bytes) {
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
  std::error_code space_error;
  const std::filesystem::space_info space = std::filesystem::space(path, space_error);
  if (!space_error && space.available < min_free_bytes) {
    throw_error(ErrorCode::kIo, "output folder {} has {:.1f} MiB free, less than the {:.0f} MiB its first outputs need "
                "(no space left on the device): free some or choose another folder",
                path, static_cast<double>(space.available) / 1048576.0, static_cast<double>(min_free_bytes) / 1048576.0);
  }
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
