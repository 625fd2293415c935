// File helpers every file format uses, so each error names the path and the OS reason,
// and nothing half-written is ever left under a final name.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace sls {

// Reads a whole file; throws sls::Error (not found / I/O) naming the path.
std::vector<std::uint8_t> read_file_bytes(const std::string& path);
std::string read_file_text(const std::string& path);

// Writes `bytes` to `path` atomically: a temporary file beside it, fsync, rename, fsync of
// the directory. A crash leaves either the old file or the new one, never a mix.
void write_file_atomic(const std::string& path, std::string_view bytes);

// Creates a directory and its parents if missing; throws sls::Error (I/O) naming the path.
void create_directories(const std::string& path);

// An output folder before any work goes into it: created if missing, then proven writable by
// creating and removing a file in it. Throws sls::Error(kIo) naming the path and the OS reason
// (a regular file in the way, no permission, a read-only filesystem).
void ensure_writable_directory(const std::string& path);

// Whether `path` is `folder` or lies inside it, comparing their absolute, normalised forms
// with symbolic links of the existing parts resolved (neither needs to exist).
bool path_is_within(const std::string& path, const std::string& folder);

// Flushes a directory entry to disk (after creating or renaming files inside it).
void sync_directory(const std::string& path);

// "path: message" with the OS error text for errno, for error messages.
std::string describe_errno(const std::string& path, int error_number);

}  // namespace sls
