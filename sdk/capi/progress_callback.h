// A C progress callback (sls_calibration_progress_callback, sls_eval_progress_callback: a struct
// of struct_size, stage, done, total, detail, and an int answer) as the SDK's ProgressCallback.
#pragma once

#include <cstring>

#include "sdk/core/progress.h"

namespace sls::capi {

// The caller's callback as the SDK's: 0 from it stops the work (kCancelled). `CProgress` is the
// header's progress struct; the library fills its own version of it.
template <typename CProgress>
ProgressCallback progress_callback(int (*callback)(const CProgress*, void*), void* user) {
  if (callback == nullptr) return {};
  return [callback, user](const ProgressUpdate& update) {
    CProgress progress;
    std::memset(&progress, 0, sizeof(progress));
    progress.struct_size = sizeof(progress);
    progress.stage = update.stage.c_str();
    progress.done = update.done;
    progress.total = update.total;
    progress.detail = update.detail.c_str();
    return callback(&progress, user) != 0;
  };
}

}  // namespace sls::capi
