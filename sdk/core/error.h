// The SDK's error type. Internally the SDK throws sls::Error; the C API (sdk/capi) turns it
// into an sls_status code and an optional sls_error object, so no exception crosses the
// C boundary. Codes have the same values as sls_status in sdk/include/sls/sls.h.
#pragma once

#include <stdexcept>
#include <string>

#include <fmt/format.h>

namespace sls {

enum class ErrorCode : int {
  kInvalidArgument = -1,  // a caller passed something unusable
  kIo = -2,               // a file or stream could not be read or written
  kFormat = -3,           // a file was read but its content is corrupt or unsupported
  kNotFound = -4,         // a file, device or key does not exist
  kOutOfMemory = -5,      // host or device allocation failed (e.g. volume too large)
  kUnsupported = -6,      // not built in (e.g. CUDA) or not available yet
  kVersionMismatch = -7,  // API or file-format version the SDK does not speak
  kDevice = -8,           // a device misbehaved (protocol error, disconnect)
  kTimeout = -9,          // a device did not answer in time
  kCancelled = -10,       // the caller cancelled long work
  kBusy = -11,            // the resource is in use
  kInternal = -99,        // a bug in the SDK
};

const char* error_code_name(ErrorCode code);

class Error : public std::runtime_error {
 public:
  Error(ErrorCode code, const std::string& message) : std::runtime_error(message), code_(code) {}
  ErrorCode code() const { return code_; }

 private:
  ErrorCode code_;
};

// Whether an error is about one piece of input (a file missing, unreadable or corrupt, data
// that does not make sense) rather than the machine (memory, a device, a bug, a cancel): a
// scan or decode skips the frame for the first and stops for the second.
bool is_frame_problem(const Error& error);

// Throws sls::Error with a fmt-formatted message.
template <typename... Args>
[[noreturn]] void throw_error(ErrorCode code, fmt::format_string<Args...> format, Args&&... args) {
  throw Error(code, fmt::format(format, std::forward<Args>(args)...));
}

}  // namespace sls
