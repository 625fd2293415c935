// sls_feed.h: frames the caller feeds (depth maps or pattern stacks) into a scan session made
// from a calibration file, as make_recording_session() makes one from a recording.
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <utility>

#include "sdk/capi/capi_guard.h"
#include "sdk/capi/scan_internal.h"
#include "sdk/capi/versioned_struct.h"
#include "sdk/core/calibration.h"
#include "sdk/core/error.h"
#include "sdk/core/image.h"
#include "sdk/decode/pattern_set.h"
#include "sdk/session/scan_session.h"
#include "sls/sls_feed.h"

namespace {

using Clock = std::chrono::steady_clock;

sls_feed_config feed_config_defaults() {
  sls_feed_config config = sls::capi::zeroed<sls_feed_config>();
  config.bit_depth = 12;
  return config;
}

constexpr std::size_t kFeedConfigFirstVersionSize = offsetof(sls_feed_config, bit_depth) + sizeof(int);
constexpr std::size_t kDepthFrameFirstVersionSize =
    offsetof(sls_depth_frame, turntable_angle_deg) + sizeof(double);
constexpr std::size_t kStackFrameFirstVersionSize =
    offsetof(sls_stack_frame, turntable_angle_deg) + sizeof(double);
constexpr std::size_t kReportFirstVersionSize = offsetof(sls_frame_report, total_ms) + sizeof(double);

double ms_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// The scan's pattern set for a projector of the calibration's size (scan_pattern_set()'s).
sls::PatternSet feed_pattern_set(const sls::ScannerCalibration& calibration) {
  sls::GrayPhaseOptions options;
  options.projector_width = calibration.projector.width;
  options.projector_height = calibration.projector.height;
  return sls::make_gray_phase_pattern_set(options);
}

void start_feed(sls_scan& scan, const sls_feed_config& config, int* patterns_per_stack) {
  if (config.calibration_path == nullptr || config.calibration_path[0] == '\0') {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.calibration_path is missing");
  }
  if (config.bit_depth < 8 || config.bit_depth > 16) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.bit_depth {} (8 .. 16)", config.bit_depth);
  }
  const sls::ScannerCalibration calibration = sls::read_calibration(config.calibration_path);
  const sls::PatternSet patterns = feed_pattern_set(calibration);
  sls::session::ScanSessionOptions options = scan.options;
  options.decode.bit_depth = config.bit_depth;
  sls::capi::discard_results(scan);
  scan.session.emplace(calibration, &patterns, options);
  // Reported from inside add_frame, where the frame's depth map (a stack's decoded one) exists.
  sls_scan* const reported = &scan;
  scan.session->set_frame_observer([reported](const sls::session::FrameReport& frame, sls::session::FrameMaps& maps) {
    sls::capi::report_frame(*reported, frame, 0, maps);
  });
  scan.feeding = true;
  scan.camera_width = calibration.camera.width;
  scan.camera_height = calibration.camera.height;
  scan.pattern_count = patterns.size();
  if (patterns_per_stack != nullptr) *patterns_per_stack = static_cast<int>(patterns.size());
}

void require_feeding(const sls_scan& scan) {
  if (!scan.feeding || !scan.session) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument,
                     "no feed: call sls_scan_start_feed first (a run since replaces the feed)");
  }
}

void require_camera_size(const sls_scan& scan, int width, int height) {
  if (width != scan.camera_width || height != scan.camera_height) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "frame of {}x{}, the calibration's camera is {}x{}", width,
                     height, scan.camera_width, scan.camera_height);
  }
}

std::size_t row_stride(std::size_t given, int width, std::size_t pixel_bytes) {
  const std::size_t row = static_cast<std::size_t>(width) * pixel_bytes;
  if (given == 0) return row;
  if (given < row) sls::throw_error(sls::ErrorCode::kInvalidArgument, "stride_bytes {} < a row's {} bytes", given, row);
  return given;
}

sls::session::ScanFrame frame_header(sls_scan& scan, int64_t timestamp_ns, int has_angle, double angle_deg) {
  if (has_angle != 0 && !std::isfinite(angle_deg)) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "turntable_angle_deg is {}", angle_deg);
  }
  sls::session::ScanFrame frame;
  frame.index = scan.next_index;
  frame.timestamp_ns = timestamp_ns;
  if (has_angle != 0) frame.turntable_angle_deg = angle_deg;
  return frame;
}

// Adds the frame to the session (whose observer calls the callback), and reports it to the
// caller's `report`.
void add(sls_scan& scan, const sls::session::ScanFrame& frame, sls_frame_report* report) {
  ++scan.next_index;
  scan.session->add_frame(frame);
  if (report != nullptr) {
    sls_frame_report filled = sls::capi::frame_report_to_c(scan.session->frames().back(), 0, {});
    sls::capi::write_versioned(filled, report, kReportFirstVersionSize, "sls_frame_report");
  }
}

void add_depth(sls_scan& scan, const sls_depth_frame& in, sls_frame_report* report) {
  require_feeding(scan);
  if (in.depth_m == nullptr) sls::throw_error(sls::ErrorCode::kInvalidArgument, "frame.depth_m is NULL");
  require_camera_size(scan, in.width, in.height);
  const std::size_t stride = row_stride(in.stride_bytes, in.width, sizeof(float));
  const Clock::time_point start = Clock::now();
  sls::session::ScanFrame frame = frame_header(scan, in.timestamp_ns, in.has_turntable_angle, in.turntable_angle_deg);
  sls::Image32f depth(in.width, in.height);
  const auto* bytes = reinterpret_cast<const unsigned char*>(in.depth_m);
  for (int y = 0; y < in.height; ++y) {
    std::memcpy(depth.view().row(y), bytes + static_cast<std::size_t>(y) * stride,
                sizeof(float) * static_cast<std::size_t>(in.width));
    for (int x = 0; x < in.width; ++x) {
      if (!std::isfinite(depth(x, y))) depth(x, y) = 0.0f;  // "none", as the session reads 0
    }
  }
  frame.read_ms = ms_since(start);
  frame.depth_m = std::move(depth);
  add(scan, frame, report);
}

void add_stack(sls_scan& scan, const sls_stack_frame& in, sls_frame_report* report) {
  require_feeding(scan);
  if (in.images == nullptr) sls::throw_error(sls::ErrorCode::kInvalidArgument, "frame.images is NULL");
  if (in.image_count != scan.pattern_count) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "a stack of {} images; the scan's pattern set has {}",
                     in.image_count, scan.pattern_count);
  }
  if (in.bytes_per_pixel != 1 && in.bytes_per_pixel != 2) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "bytes_per_pixel {} (1 or 2)", in.bytes_per_pixel);
  }
  require_camera_size(scan, in.width, in.height);
  const std::size_t pixel_bytes = static_cast<std::size_t>(in.bytes_per_pixel);
  const std::size_t stride = row_stride(in.stride_bytes, in.width, pixel_bytes);
  for (std::size_t i = 0; i < in.image_count; ++i) {
    if (in.images[i] == nullptr) sls::throw_error(sls::ErrorCode::kInvalidArgument, "frame.images[{}] is NULL", i);
  }
  const Clock::time_point start = Clock::now();
  sls::session::ScanFrame frame = frame_header(scan, in.timestamp_ns, in.has_turntable_angle, in.turntable_angle_deg);
  frame.images.reserve(in.image_count);
  for (std::size_t i = 0; i < in.image_count; ++i) {
    sls::Image16u image(in.width, in.height);
    const auto* bytes = static_cast<const unsigned char*>(in.images[i]);
    for (int y = 0; y < in.height; ++y) {
      const unsigned char* row = bytes + static_cast<std::size_t>(y) * stride;
      std::uint16_t* out = image.view().row(y);
      if (pixel_bytes == 1) {
        for (int x = 0; x < in.width; ++x) out[x] = row[x];
      } else {
        std::memcpy(out, row, sizeof(std::uint16_t) * static_cast<std::size_t>(in.width));
      }
    }
    frame.images.push_back(std::move(image));
  }
  frame.read_ms = ms_since(start);
  add(scan, frame, report);
}

// Checks the caller's report struct before the frame goes in (a bad one must change nothing).
void require_report(const sls_frame_report* report) {
  if (report != nullptr) sls::capi::require_versioned(report, kReportFirstVersionSize, "sls_frame_report");
}

}  // namespace

extern "C" {

SLS_CAPI_DEFINE_INIT(sls_feed_config, bit_depth, feed_config_defaults())

SLS_CAPI_DEFINE_INIT(sls_depth_frame, turntable_angle_deg, sls::capi::zeroed<sls_depth_frame>())

SLS_CAPI_DEFINE_INIT(sls_stack_frame, turntable_angle_deg, sls::capi::zeroed<sls_stack_frame>())

SLS_API sls_status sls_scan_start_feed(sls_scan* scan, const sls_feed_config* config, int* patterns_per_stack,
                                       sls_error** error) {
  SLS_CAPI_REQUIRE(scan != nullptr, error, "scan is NULL");
  SLS_CAPI_REQUIRE(config != nullptr, error, "config is NULL");
  const sls::capi::ScanHold hold(*scan);
  if (!hold.held()) return sls::capi::report_busy(__func__, error);
  return sls::capi::guarded(__func__, error, [&] {
    sls_feed_config defaults;
    sls_feed_config_init(&defaults);
    const sls_feed_config resolved =
        sls::capi::read_versioned(config, defaults, kFeedConfigFirstVersionSize, "sls_feed_config");
    sls::capi::refuse_if_cancelled(*scan);
    if (scan->groundtruth) {
      sls::throw_error(sls::ErrorCode::kInvalidArgument,
                       "config.poses is SLS_POSES_GROUNDTRUTH: fed frames have no ground truth (runs of simulated "
                       "recordings only)");
    }
    start_feed(*scan, resolved, patterns_per_stack);
  });
}

SLS_API sls_status sls_scan_add_depth(sls_scan* scan, const sls_depth_frame* frame, sls_frame_report* report,
                                      sls_error** error) {
  SLS_CAPI_REQUIRE(scan != nullptr, error, "scan is NULL");
  SLS_CAPI_REQUIRE(frame != nullptr, error, "frame is NULL");
  const sls::capi::ScanHold hold(*scan);
  if (!hold.held()) return sls::capi::report_busy(__func__, error);
  return sls::capi::guarded(__func__, error, [&] {
    sls_depth_frame defaults;
    sls_depth_frame_init(&defaults);
    const sls_depth_frame resolved =
        sls::capi::read_versioned(frame, defaults, kDepthFrameFirstVersionSize, "sls_depth_frame");
    require_report(report);
    sls::capi::refuse_if_cancelled(*scan);
    add_depth(*scan, resolved, report);
  });
}

SLS_API sls_status sls_scan_add_stack(sls_scan* scan, const sls_stack_frame* frame, sls_frame_report* report,
                                      sls_error** error) {
  SLS_CAPI_REQUIRE(scan != nullptr, error, "scan is NULL");
  SLS_CAPI_REQUIRE(frame != nullptr, error, "frame is NULL");
  const sls::capi::ScanHold hold(*scan);
  if (!hold.held()) return sls::capi::report_busy(__func__, error);
  return sls::capi::guarded(__func__, error, [&] {
    sls_stack_frame defaults;
    sls_stack_frame_init(&defaults);
    const sls_stack_frame resolved =
        sls::capi::read_versioned(frame, defaults, kStackFrameFirstVersionSize, "sls_stack_frame");
    require_report(report);
    sls::capi::refuse_if_cancelled(*scan);
    add_stack(*scan, resolved, report);
  });
}

}  // extern "C"
