// The state of an sls_scan, shared by the C API's scan files: scan.cpp (config, runs, loop
// closure, writes), scan_feed.cpp (frames the caller feeds) and scan_results.cpp (the model,
// trajectory and preview in memory).
#pragma once

#include <atomic>
#include <cstddef>
#include <memory>
#include <optional>
#include <thread>

#include "fusion/extract.h"
#include "sdk/core/calibration.h"
#include "sdk/core/image.h"
#include "sdk/session/scan_session.h"
#include "sls/sls_scan.h"

struct sls_scan {
  sls::session::ScanSessionOptions options;  // from the config and the context's device
  // The rest of the config: known poses (config.poses), what a run does about the loop, and
  // the calibration runs decode with instead of the recording's (config.calibration_path).
  bool groundtruth = false;
  bool no_record = false;  // config.no_record: sls_scan_run_devices writes no recording
  sls_loop_closure_mode loop_closure = SLS_LOOP_CLOSURE_CALLER;
  std::optional<sls::ScannerCalibration> calibration;
  sls_frame_callback callback = nullptr;
  void* user = nullptr;
  std::atomic<bool> cancel_requested{false};  // final once set (sls_scan_cancel)
  // Taken by a run for its whole length and by the other calls for theirs: a second taker
  // answers SLS_ERROR_BUSY. An atomic flag rather than a mutex, because the frame callback
  // calls in on the thread that holds it.
  mutable std::atomic<bool> in_use{false};
  // The thread running the frame callback, while it runs: the results getters (sls_results.h)
  // serve it, the scan being between two frames then.
  std::atomic<std::thread::id> callback_thread{};

  // The last run's (or feed's) results.
  std::optional<sls::session::ScanSession> session;
  bool cancelled = false;
  // The model extracted once for the writes and getters, shared with the sls_cloud and sls_mesh
  // handles made from it (they outlive the scan); dropped when the model changes.
  mutable std::shared_ptr<const sls::fusion::ExtractedSurface> surface;

  // A feed (sls_scan_start_feed): the frames the caller adds, numbered from 0.
  bool feeding = false;
  int next_index = 0;
  int camera_width = 0, camera_height = 0;  // the calibration's camera: every frame's size
  std::size_t pattern_count = 0;            // images per pattern stack
};

namespace sls::capi {

// Holds a scan for one call, or finds it held (a run in progress, or another thread's call).
class ScanHold {
 public:
  explicit ScanHold(const sls_scan& scan) : flag_(scan.in_use), held_(!flag_.exchange(true)) {}
  ~ScanHold() {
    if (held_) flag_.store(false);
  }
  ScanHold(const ScanHold&) = delete;
  ScanHold& operator=(const ScanHold&) = delete;
  bool held() const { return held_; }

 private:
  std::atomic<bool>& flag_;
  bool held_;
};

sls_status report_busy(const char* function, sls_error** error);

// The depth map a frame was fused from, for the frame report (valid during the callback).
struct FrameDepth {
  const sls::Image32f* depth_m = nullptr;
  const float* depth_device = nullptr;
};

// Hands a frame's report to the caller's callback (if any), on this thread, after dropping the
// model extracted before the frame. recording_frames: 0 for a fed frame.
void report_frame(sls_scan& scan, const sls::session::FrameReport& frame, std::size_t recording_frames,
                  sls::session::FrameMaps& maps);

// The session's report as the C struct (the library's own size); its strings and depth point into
// `frame` and `depth`.
sls_frame_report frame_report_to_c(const sls::session::FrameReport& frame, std::size_t recording_frames,
                                   const FrameDepth& depth);

// The session of a run or feed that fused a frame; throws kInvalidArgument otherwise.
const sls::session::ScanSession& fused_session(const sls_scan& scan);

// The model (extracted once, until it changes); throws as fused_session().
std::shared_ptr<const sls::fusion::ExtractedSurface> model_surface(const sls_scan& scan);

// Throws kCancelled once the scan was cancelled (final).
void refuse_if_cancelled(const sls_scan& scan);

// Forgets the previous run's or feed's model.
void discard_results(sls_scan& scan);

}  // namespace sls::capi
