// Progress of long work (recording checks, decoding a recording, fusing a scan): the SDK
// reports through one callback type; the `sls` tool draws it, the C API forwards it.
#pragma once

#include <cstddef>
#include <functional>
#include <string>

namespace sls {

struct ProgressUpdate {
  std::string stage;      // what is running, e.g. "decode"
  std::size_t done = 0;   // units finished (frames, images, ...)
  std::size_t total = 0;  // units in all; 0 when unknown
  std::string detail;     // optional, e.g. the current file
};

// Called on the thread doing the work. Returns false to ask the work to stop; the work then
// ends with sls::Error(kCancelled), keeping what it already produced.
using ProgressCallback = std::function<bool(const ProgressUpdate&)>;

// Reports progress through an optional callback; throws kCancelled when asked to stop.
inline void report_progress(const ProgressCallback& callback, const ProgressUpdate& update);

}  // namespace sls

#include "sdk/core/error.h"

namespace sls {

inline void report_progress(const ProgressCallback& callback, const ProgressUpdate& update) {
  if (callback && !callback(update)) {
    throw_error(ErrorCode::kCancelled, "{} cancelled after {} of {}", update.stage, update.done, update.total);
  }
}

}  // namespace sls
