// File helpers every file format uses, so each error names the path and the OS reason,
// and nothing half-written is ever left under a final name.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace sls {

// The most a metadata file (manifest, calibration, trajectory, pattern set, report) read
// whole may hold: far above any real one, far below a machine's memory, so a corrupt or
// hostile file is refused before it is read. Bulk data (images, clouds) pass their own bound.
constexpr std::uint64_t kMaxMetadataFileBytes = std::uint64_t{64} << 20;

// A data file open for reading, known to be a regular file. Opening never blocks and never
// reads: a FIFO, a device (a link to /dev/zero), a socket or a directory in place of a data
// file is refused at once. Throws sls::Error naming the path: kNotFound (missing), kIo
// (cannot be opened, or "is a FIFO (named pipe), not a regular file" and the like).
class RegularFile {
 public:
  explicit RegularFile(const std::string& path);
  ~RegularFile();
  RegularFile(const RegularFile&) = delete;
  RegularFile& operator=(const RegularFile&) = delete;

  int fd() const { return fd_; }
  const std::string& path() const { return path_; }
  std::uint64_t size() const { return size_; }  // when opened

  // Up to `count` bytes from `offset`; fewer only at the end of the file. Throws kIo.
  std::size_t read_at(std::uint64_t offset, void* out, std::size_t count) const;
  // The whole file. Throws kFormat naming the path, its size and the limit when it holds
  // more than max_bytes (also when it grows past them while being read), kIo on a read error.
  std::vector<std::uint8_t> read_all(std::uint64_t max_bytes) const;
  // The same into `bytes`, whose capacity is reused: a reader of many large files keeps one.
  void read_all(std::uint64_t max_bytes, std::vector<std::uint8_t>* bytes) const;
  // Throws kFormat, as read_all would, when the file holds more than max_bytes.
  void check_size(std::uint64_t max_bytes) const;

 private:
  std::string path_;
  int fd_ = -1;
  std::uint64_t size_ = 0;
};

// Reads a whole regular file of at most max_bytes; throws sls::Error naming the path (see
// RegularFile).
std::vector<std::uint8_t> read_file_bytes(const std::string& path, std::uint64_t max_bytes = kMaxMetadataFileBytes);
std::string read_file_text(const std::string& path, std::uint64_t max_bytes = kMaxMetadataFileBytes);

// Writes `bytes` to `path` atomically: a temporary file beside it, fsync, rename, fsync of
// the directory. A crash leaves either the old file or the new one, never a mix.
void write_file_atomic(const std::string& path, std::string_view bytes);

// Creates a directory and its parents if missing; throws sls::Error (I/O) naming the path.
void create_directories(const std::string& path);

// An output folder before any work goes into it: created if missing, then proven writable by
// creating and removing a file in it, and holding at least `min_free_bytes` free for an
// unprivileged writer. Throws sls::Error(kIo) naming the path and the OS reason (a regular file
// in the way, no permission, a read-only filesystem) or the space free and needed.
void ensure_writable_directory(const std::string& path, std::uint64_t min_free_bytes = 0);

// Whether `path` is `folder` or lies inside it, comparing their absolute, normalised forms
// with symbolic links of the existing parts resolved (neither needs to exist).
bool path_is_within(const std::string& path, const std::string& folder);

// Flushes a directory entry to disk (after creating or renaming files inside it).
void sync_directory(const std::string& path);

// "path: message" with the OS error text for errno, for error messages.
std::string describe_errno(const std::string& path, int error_number);

}  // namespace sls
