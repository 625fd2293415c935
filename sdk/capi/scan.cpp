// sls_scan: the scan session (sdk/session/scan_session.h) behind the C API. A recording, or
// devices by URI captured into one (sdk/session/scan_setup.h, as `sls scan` does), replayed
// through a ScanSession; each FrameReport goes to the caller's callback as an sls_frame_report,
// and a cancel reaches the replay (and the capture) through their progress callbacks. After a
// run, sls_scan_close_loop() is the session's close_loop(); the writes take the session's
// (deformed) model and trajectory.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "drivers/interfaces/device_uri.h"
#include "fusion/extract.h"
#include "sdk/capi/capi_guard.h"
#include "sdk/capi/context_internal.h"
#include "sdk/capi/scan_internal.h"
#include "sdk/capi/versioned_struct.h"
#include "sdk/core/calibration.h"
#include "sdk/core/error.h"
#include "sdk/core/log.h"
#include "sdk/core/ply.h"
#include "sdk/core/progress.h"
#include "sdk/core/recording.h"
#include "sdk/core/trajectory.h"
#include "sdk/session/frame_pipeline.h"
#include "sdk/session/scan_session.h"
#include "sdk/session/scan_setup.h"
#include "sls/sls_scan.h"

using sls::capi::discard_results;
using sls::capi::refuse_if_cancelled;
using sls::capi::report_busy;
using sls::capi::ScanHold;

namespace {

constexpr std::size_t kScanConfigFirstVersionSize = offsetof(sls_scan_config, max_voxels) + sizeof(double);
constexpr std::size_t kCaptureConfigFirstVersionSize = offsetof(sls_capture_config, frames) + sizeof(int);
constexpr std::size_t kSummaryFirstVersionSize = offsetof(sls_scan_summary, volume_moves) + sizeof(std::size_t);
constexpr std::size_t kLoopClosureFirstVersionSize = offsetof(sls_loop_closure, ms) + sizeof(double);

sls_scan_config scan_config_defaults() {
  sls_scan_config config = sls::capi::zeroed<sls_scan_config>();
  config.fusion = SLS_FUSION_GTSDF;
  config.online_deformation = 1;
  // `sls scan`'s defaults (the others are 0: the library's, or off).
  config.loop_frames = sls::session::DeformationOptions().loop_frames;
  config.icp_crease_deg = sls::fusion::TrackingOptions().crease_angle_deg;
  return config;
}

// A field appended after loop_closure starts past that struct, padding included.
static_assert(offsetof(sls_scan_config, max_gpu_bytes) >=
                  sls::capi::size_ending_at<sls_scan_config>(offsetof(sls_scan_config, loop_closure) +
                                                             sizeof(sls_loop_closure_mode)),
              "max_gpu_bytes lies in the padding of the struct that ended with loop_closure");
static_assert(offsetof(sls_scan_config, revisits) >=
                  sls::capi::size_ending_at<sls_scan_config>(offsetof(sls_scan_config, max_gpu_bytes) + sizeof(double)),
              "revisits lies in the padding of the struct that ended with max_gpu_bytes");
// (padding_0_6 fills the 0.6 struct's padding: never read.)
static_assert(offsetof(sls_scan_config, no_record) >=
                  sls::capi::size_ending_at<sls_scan_config>(offsetof(sls_scan_config, revisits) +
                                                             sizeof(sls_revisit_policy)),
              "no_record lies in the padding of the struct that ended with revisits");
// An API 0.5 field starts past the 0.4 struct, padding included (versioned_struct.h).
static_assert(offsetof(sls_scan_config, calibration_path) >= SLS_CAPI_SIZE_0_4(sls_scan_config, online_deformation),
              "a field appended in 0.5 lies in the 0.4 struct's padding");

// Throws kInvalidArgument naming config.FIELD unless lo <= value <= hi, or value is 0 and 0 is
// allowed (`zero`: what 0 means).
void check_range(double value, double lo, double hi, const char* field, const char* zero = nullptr) {
  if (zero != nullptr && value == 0.0) return;
  if (!(value >= lo && value <= hi)) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.{} {} ({}{} .. {})", field, value,
                     zero != nullptr ? fmt::format("0: {}, or ", zero) : std::string(), lo, hi);
  }
}

// The GTSDF parameters a config sets (0 / SLS_GTSDF_PENALTY_DEFAULT: the library's), over
// IntegrationOptions::gtsdf(); refused with SLS_FUSION_TSDF, as `sls scan` refuses them.
void apply_gtsdf(const sls_scan_config& config, sls::fusion::IntegrationOptions* integration) {
  const long long penalty = sls::capi::c_enum_value(config.gtsdf_penalty);
  const bool any = config.gtsdf_lambda != 0.0 || config.gtsdf_kappa != 0.0 || penalty != SLS_GTSDF_PENALTY_DEFAULT ||
                   config.gtsdf_iterations != 0;
  if (any && !integration->is_gtsdf()) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument,
                     "config.gtsdf_lambda/_kappa/_penalty/_iterations are set but config.fusion is SLS_FUSION_TSDF "
                     "(they need SLS_FUSION_GTSDF)");
  }
  check_range(config.gtsdf_lambda, 1e-3, 1e3, "gtsdf_lambda", "the library's");
  check_range(config.gtsdf_kappa, 1e-4, 10.0, "gtsdf_kappa", "the library's");
  check_range(config.gtsdf_iterations, 1, 100, "gtsdf_iterations", "the library's");
  if (config.gtsdf_lambda != 0.0) integration->lambda = config.gtsdf_lambda;
  if (config.gtsdf_kappa != 0.0) integration->kappa = config.gtsdf_kappa;
  if (config.gtsdf_iterations != 0) integration->iterations = config.gtsdf_iterations;
  switch (penalty) {
    case SLS_GTSDF_PENALTY_DEFAULT: break;
    case SLS_GTSDF_PENALTY_PERONA_MALIK: integration->penalty = sls::fusion::Penalty::kPeronaMalik; break;
    case SLS_GTSDF_PENALTY_CHARBONNIER: integration->penalty = sls::fusion::Penalty::kCharbonnier; break;
    case SLS_GTSDF_PENALTY_GEMAN_MCCLURE: integration->penalty = sls::fusion::Penalty::kGemanMcClure; break;
    default:
      sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.gtsdf_penalty {} is not an sls_gtsdf_penalty",
                       penalty);
  }
}

// What the C API keeps of a config beside the session's options.
struct ScanChoices {
  bool groundtruth = false;
  bool no_record = false;
  sls_loop_closure_mode loop_closure = SLS_LOOP_CLOSURE_CALLER;
};

sls::session::ScanSessionOptions session_options(const sls_scan_config& config, const sls::Device& device,
                                                 ScanChoices* choices) {
  sls::session::ScanSessionOptions options;
  options.device = device;
  const long long fusion = sls::capi::c_enum_value(config.fusion);
  if (fusion == SLS_FUSION_GTSDF) {
    options.integration = sls::fusion::IntegrationOptions::gtsdf();
  } else if (fusion == SLS_FUSION_TSDF) {
    options.integration = sls::fusion::IntegrationOptions::tsdf();
  } else {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.fusion {} is not an sls_fusion_method", fusion);
  }
  apply_gtsdf(config, &options.integration);
  options.turntable_prior = config.use_turntable_prior != 0;
  if (!(config.voxel_size_m >= 0.0) || !std::isfinite(config.voxel_size_m)) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.voxel_size_m {} (0: automatic, or positive)",
                     config.voxel_size_m);
  }
  options.voxel_size_m = config.voxel_size_m;
  const double* size = config.volume_size_m;
  const bool automatic = size[0] == 0.0 && size[1] == 0.0 && size[2] == 0.0;
  const bool given = std::all_of(size, size + 3, [](double s) { return s > 0.0 && std::isfinite(s); });
  if (!automatic && !given) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument,
                     "config.volume_size_m {} x {} x {} (all three 0: automatic, or all three positive)", size[0],
                     size[1], size[2]);
  }
  options.volume_size_m = Eigen::Vector3d(size[0], size[1], size[2]);
  if (!(config.max_voxels >= 0.0) || !std::isfinite(config.max_voxels)) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.max_voxels {} (0: automatic, or positive)",
                     config.max_voxels);
  }
  options.max_voxels = config.max_voxels > 0.0 ? config.max_voxels : sls::session::automatic_max_voxels(device);
  check_range(config.max_gpu_bytes, 1.0, 1e15, "max_gpu_bytes", "none");
  options.max_gpu_bytes = config.max_gpu_bytes;
  options.deformation.enabled = config.online_deformation != 0;
  check_range(config.loop_frames, 1, 64, "loop_frames");
  options.deformation.loop_frames = config.loop_frames;
  check_range(config.photometric_weight, 0.0, 1e6, "photometric_weight");
  options.tracking.photometric_weight = config.photometric_weight;
  check_range(config.icp_crease_deg, 0.0, 179.0, "icp_crease_deg");
  options.tracking.crease_angle_deg = config.icp_crease_deg;
  const long long weights = sls::capi::c_enum_value(config.icp_weights);
  if (weights != SLS_ICP_WEIGHTS_CONFIDENCE && weights != SLS_ICP_WEIGHTS_EQUAL) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.icp_weights {} is not an sls_icp_weights", weights);
  }
  options.tracking.weight_by_confidence = weights == SLS_ICP_WEIGHTS_CONFIDENCE;
  const long long poses = sls::capi::c_enum_value(config.poses);
  if (poses != SLS_POSES_TRACK && poses != SLS_POSES_GROUNDTRUTH) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.poses {} is not an sls_pose_source", poses);
  }
  choices->groundtruth = poses == SLS_POSES_GROUNDTRUTH;
  if (choices->groundtruth) {
    // Known poses, as `sls scan --poses groundtruth`: nothing tracked, so no prior and no drift.
    options.turntable_prior = false;
    options.deformation.enabled = false;
  }
  const long long loop = sls::capi::c_enum_value(config.loop_closure);
  if (loop != SLS_LOOP_CLOSURE_CALLER && loop != SLS_LOOP_CLOSURE_AUTO && loop != SLS_LOOP_CLOSURE_ON) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.loop_closure {} is not an sls_loop_closure_mode", loop);
  }
  choices->loop_closure = static_cast<sls_loop_closure_mode>(loop);
  choices->no_record = config.no_record != 0;
  if (choices->no_record && choices->groundtruth) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument,
                     "config.no_record with config.poses SLS_POSES_GROUNDTRUTH: known poses are read from the "
                     "recording a capture writes (record it, or track the poses)");
  }
  switch (sls::capi::c_enum_value(config.revisits)) {
    case SLS_REVISITS_AUTO: options.revisits = sls::session::RevisitPolicy::kAfterFirstRevolution; break;
    case SLS_REVISITS_KEEP: options.revisits = sls::session::RevisitPolicy::kKeep; break;
    case SLS_REVISITS_MERGE: options.revisits = sls::session::RevisitPolicy::kMerge; break;
    default:
      sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.revisits {} is not an sls_revisit_policy",
                       sls::capi::c_enum_value(config.revisits));
  }
  options.validate();
  return options;
}

sls_frame_status to_c(sls::session::FrameStatus status) {
  switch (status) {
    case sls::session::FrameStatus::kFused: return SLS_FRAME_FUSED;
    case sls::session::FrameStatus::kLost: return SLS_FRAME_LOST;
    case sls::session::FrameStatus::kSkipped: return SLS_FRAME_SKIPPED;
  }
  sls::throw_error(sls::ErrorCode::kInternal, "frame status {} has no C value", static_cast<int>(status));
}

bool cancel_requested(const sls_scan& scan) { return scan.cancel_requested.load(); }

sls_loop_closure close_loop(sls_scan& scan);
void close_loop_after_run(sls_scan& scan, const std::vector<std::optional<double>>& turntable_angles);

// What a live capture tells the scan (sls_scan_run_devices): with no_record, what its
// recording would hold (written on the capture's thread before its first frame, read once the
// pipeline has that frame) and each frame's turntable angle (read once the pipeline returned).
struct LiveCapture {
  const sls::session::FrameSource* frames = nullptr;
  std::size_t expected_frames = 0;
  bool record = true;
  std::optional<sls::RecordingInfo> info;
  std::optional<sls::ScannerCalibration> calibration;
  std::vector<std::optional<double>> turntable_angles;
};

// Fuses the recording at `folder` into a new session (scan.session), the frame callback after
// each frame: replayed (`live` null; the next frames read while one is fused), or as a capture
// records it (`live`: its frames, the session made at the first, once the recording exists;
// `expected_frames` what the frame reports say the run holds). Throws kCancelled after a cancel
// (the model keeps what was fused, a capture's recording what it recorded), the source's error
// after fusing what came before it, kInvalidArgument when nothing was fused.
void fuse_frames(sls_scan& scan, const std::string& folder, LiveCapture* live) {
  std::optional<sls::RecordingReader> recording;
  std::vector<sls::StampedPose> truth;
  const std::size_t expected_frames = live != nullptr ? live->expected_frames : 0;
  const auto make_session = [&]() -> sls::session::ScanSession& {
    if (live != nullptr && !live->record) {
      // No recording to open: what the capture described before its first frame.
      if (!live->info || !live->calibration) {
        sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.no_record: the capture has no calibration");
      }
      scan.session.emplace(sls::session::make_capture_session(*live->info, scan.calibration ? *scan.calibration
                                                                                            : *live->calibration,
                                                              scan.options));
    } else {
      recording.emplace(sls::session::open_recording_for_scan(folder, scan.calibration.has_value()));
      sls::session::ScanSessionOptions options = scan.options;
      if (scan.groundtruth) {
        // As `sls scan --poses groundtruth`: the true poses, one volume around the object.
        truth = sls::session::groundtruth_poses(*recording);
        options.fixed_volume =
            sls::session::groundtruth_volume(*recording, options.voxel_size_m, options.max_voxels, options.integration);
      }
      scan.session.emplace(
          sls::session::make_recording_session(*recording, options, scan.calibration ? &*scan.calibration : nullptr));
    }
    const std::size_t frames = live != nullptr ? expected_frames : recording->frame_count();
    // Reported from inside the session's add_frame, where the frame's depth map still exists.
    scan.session->set_frame_observer([&scan, frames](const sls::session::FrameReport& frame,
                                                     sls::session::FrameMaps& maps) {
      sls::capi::report_frame(scan, frame, frames, maps);
    });
    return *scan.session;
  };
  // Asked before every frame: a cancel stops the run after the frame in progress.
  const sls::ProgressCallback progress = [&scan](const sls::ProgressUpdate&) { return !cancel_requested(scan); };
  sls::session::PipelineOutcome outcome;
  if (live != nullptr) {
    try {
      outcome = sls::session::run_pipeline(make_session, *live->frames, sls::session::PipelineOptions{}, {}, progress);
    } catch (const sls::Error& error) {
      if (error.code() == sls::ErrorCode::kCancelled) scan.cancelled = true;
      throw;
    }
    if (scan.session && live->record) recording.emplace(sls::RecordingReader::open(folder));  // as the capture left it
  } else {
    make_session();
    outcome = sls::session::run_recording(*scan.session, *recording, scan.groundtruth ? &truth : nullptr, {}, progress);
  }
  if (!scan.session) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "{}: the capture recorded no frame to fuse", folder);
  }
  sls::session::ScanSession& session = *scan.session;
  if (outcome.interrupted) {
    scan.cancelled = true;
    sls::throw_error(sls::ErrorCode::kCancelled, "{}: {}; the model keeps the {} frame(s) fused", folder,
                     outcome.interruption, session.fused_count());
  }
  if (session.fused_count() == 0) {
    const std::vector<sls::session::FrameReport>& frames = session.frames();
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "{}: no frame could be fused ({} frame(s){})", folder,
                     frames.size(),
                     frames.empty() ? std::string()
                                    : "; frame " + std::to_string(frames.front().index) + " " +
                                          sls::session::frame_status_name(frames.front().status) + ": " +
                                          frames.front().reason);
  }
  std::vector<std::optional<double>> angles;
  if (recording) {
    for (std::size_t i = 0; i < recording->frame_count(); ++i) angles.push_back(recording->frame(i).turntable_angle_deg);
  } else {
    angles = live->turntable_angles;
  }
  close_loop_after_run(scan, angles);
}

void scan_recording(sls_scan& scan, const std::string& folder) { fuse_frames(scan, folder, nullptr); }

// Captures through the devices into capture.recording_path and fuses each frame as it is
// recorded (sls_scan_run_devices).
void scan_devices(sls_scan& scan, const sls_capture_config& capture) {
  const auto required = [](const char* value, const char* name) {
    if (value == nullptr || value[0] == '\0') {
      sls::throw_error(sls::ErrorCode::kInvalidArgument, "capture.{} is missing", name);
    }
    return std::string(value);
  };
  sls::session::DeviceCaptureRequest request;
  request.camera_uri = required(capture.camera_uri, "camera_uri");
  request.projector_uri = required(capture.projector_uri, "projector_uri");
  // A replay:// camera brings its recording's calibration; other devices need theirs.
  if (capture.calibration_path != nullptr) request.calibration_path = capture.calibration_path;
  if (request.calibration_path.empty() && sls::drivers::parse_device_uri(request.camera_uri).scheme != "replay") {
    sls::throw_error(sls::ErrorCode::kInvalidArgument,
                     "capture.calibration_path is missing (only a replay:// camera brings its recording's)");
  }
  const bool has_path = capture.recording_path != nullptr && capture.recording_path[0] != '\0';
  if (scan.no_record && has_path) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument,
                     "capture.recording_path {} with config.no_record: nothing is recorded (leave it NULL, or record)",
                     capture.recording_path);
  }
  const std::string folder = scan.no_record ? std::string() : required(capture.recording_path, "recording_path");
  if (capture.turntable_uri != nullptr) request.turntable_uri = capture.turntable_uri;
  if (capture.frames < 0) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "capture.frames {} (0: automatic, or positive)",
                     capture.frames);
  }
  request.frames = capture.frames;
  request.sim_device = scan.options.device;
  request.image_memory = sls::session::capture_memory_for(scan.options.device);
  // Asked after every stack: a cancel stops the capture after the stack in progress (what it
  // recorded is fused).
  const sls::ProgressCallback progress = [&scan](const sls::ProgressUpdate&) { return !cancel_requested(scan); };
  LiveCapture live;
  live.record = !scan.no_record;
  request.record = live.record;
  request.described = [&live](const sls::RecordingInfo& info, const std::optional<sls::ScannerCalibration>& calibration) {
    live.info = info;
    live.calibration = calibration;
  };
  const sls::session::FrameSource frames = sls::session::captured_frames(
      folder, [&request, &progress, &folder, &live](const sls::session::RecordedFrame& recorded) {
        sls::session::capture_from_devices(folder, request, progress, [&](sls::session::ScanFrame&& frame) {
          live.turntable_angles.push_back(frame.turntable_angle_deg);
          recorded(std::move(frame));
        });
      });
  live.frames = &frames;
  // What the frame reports say the run holds: capture_from_devices' frame count.
  std::size_t expected =
      request.frames > 0 ? static_cast<std::size_t>(request.frames) : (request.turntable_uri.empty() ? 1 : 36);
  const sls::drivers::DeviceUri camera = sls::drivers::parse_device_uri(request.camera_uri);
  if (request.frames == 0 && camera.scheme == "replay") {
    expected = sls::RecordingReader::open(camera.target).frame_count();
  }
  live.expected_frames = expected;
  fuse_frames(scan, folder, &live);
}

// The loop closure of the last run's model; the model extracted before it is dropped, so the
// writes extract the closed one.
sls_loop_closure close_loop(sls_scan& scan) {
  if (!scan.session) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "loop closure asked before any run: run the scan first");
  }
  // Dropped whatever happens: a solve that fails part way may have moved the graph.
  scan.surface.reset();
  const sls::session::LoopClosureReport closed = scan.session->close_loop();
  sls_loop_closure result;
  sls_loop_closure_init(&result);
  result.first_frame = closed.first_frame;
  result.last_frame = closed.last_frame;
  result.registration_inlier_fraction = closed.registration.inlier_fraction;
  result.registration_residual_rms_m = closed.registration.residual_rms_m;
  result.constraints = closed.constraints;
  result.iterations = closed.solve.iterations;
  result.last_pose_correction_m = closed.correction_m;
  result.last_pose_correction_deg = closed.correction_deg;
  result.ms = closed.ms;
  return result;
}

// config.loop_closure after a run that was not cancelled: SLS_LOOP_CLOSURE_ON always,
// SLS_LOOP_CLOSURE_AUTO for a full turntable revolution (as `sls scan`). A loop that does not
// close is a warning, as in the tool: the run's model stands.
void close_loop_after_run(sls_scan& scan, const std::vector<std::optional<double>>& turntable_angles) {
  if (scan.loop_closure == SLS_LOOP_CLOSURE_CALLER || !scan.session->deformation_enabled()) return;
  std::string why = "config.loop_closure SLS_LOOP_CLOSURE_ON";
  if (scan.loop_closure == SLS_LOOP_CLOSURE_AUTO && !sls::session::is_full_revolution(turntable_angles, &why)) return;
  try {
    close_loop(scan);
  } catch (const sls::Error& error) {
    if (error.code() != sls::ErrorCode::kInvalidArgument) throw;
    sls::logger().warn("scan: the loop ({}) was not closed: {}", why, error.what());
  }
}

}  // namespace

namespace sls::capi {

sls_status report_busy(const char* function, sls_error** error) {
  return report(SLS_ERROR_BUSY, function,
                "the scan is running (during a run only sls_scan_cancel may be called on it)", error);
}

const session::ScanSession& fused_session(const sls_scan& scan) {
  if (!scan.session || scan.session->fused_count() == 0) {
    throw_error(ErrorCode::kInvalidArgument, "no frame has been fused: nothing to write (run the scan first)");
  }
  return *scan.session;
}

std::shared_ptr<const fusion::ExtractedSurface> model_surface(const sls_scan& scan) {
  const session::ScanSession& session = fused_session(scan);
  if (!scan.surface) scan.surface = std::make_shared<const fusion::ExtractedSurface>(session.final_surface());
  return scan.surface;
}

void refuse_if_cancelled(const sls_scan& scan) {
  if (scan.cancel_requested.load()) {
    throw_error(ErrorCode::kCancelled, "the scan was cancelled (sls_scan_cancel); create a new one");
  }
}

void discard_results(sls_scan& scan) {
  // The volume's memory first: the next run allocates its own.
  scan.surface.reset();
  scan.session.reset();
  scan.cancelled = false;
  scan.feeding = false;
  scan.next_index = 0;
}

// The report's strings point into `frame`: valid while it lives (the callback's duration).
sls_frame_report frame_report_to_c(const session::FrameReport& frame, std::size_t recording_frames,
                                   const FrameDepth& depth) {
  sls_frame_report report;
  std::memset(&report, 0, sizeof(report));
  report.struct_size = sizeof(report);
  report.index = frame.index;
  report.recording_frames = recording_frames;
  report.timestamp_ns = frame.timestamp_ns;
  report.status = to_c(frame.status);
  report.reason = frame.reason.c_str();
  const Eigen::Matrix4d T_world_camera = frame.T_world_camera.matrix();
  for (int row = 0; row < 4; ++row) {
    for (int column = 0; column < 4; ++column) report.T_world_camera[4 * row + column] = T_world_camera(row, column);
  }
  report.depth_pixels = frame.depth_pixels;
  if (frame.tracking) {
    report.tracked = 1;
    report.inlier_fraction = frame.tracking->inlier_fraction;
    report.residual_rms_m = frame.tracking->residual_rms_m;
  }
  report.read_ms = frame.times.read_ms;
  report.decode_ms = frame.times.decode_ms;
  report.track_ms = frame.times.track_ms;
  report.integrate_ms = frame.times.integrate_ms;
  report.move_ms = frame.times.move_ms;
  report.raycast_ms = frame.times.raycast_ms;
  report.deform_ms = frame.times.deform_ms;
  report.total_ms = frame.times.total_ms();
  report.keyframe = frame.deformation.keyframe ? 1 : 0;
  report.deformation_nodes = frame.deformation.nodes;
  report.deformation_constraints = frame.deformation.constraints;
  report.deformation_solve_ms = frame.deformation.solve_ms;
  report.unverified = frame.unverified ? 1 : 0;
  if (depth.depth_m != nullptr && !depth.depth_m->empty()) {
    report.depth_m = depth.depth_m->data();
    report.depth_width = depth.depth_m->width();
    report.depth_height = depth.depth_m->height();
    report.depth_stride_bytes = sizeof(float) * static_cast<std::size_t>(depth.depth_m->width());
    report.depth_device = depth.depth_device;
  }
  return report;
}

void report_frame(sls_scan& scan, const session::FrameReport& frame, std::size_t recording_frames,
                  session::FrameMaps& maps) {
  scan.surface.reset();  // the model changed (a fused frame), or may have (the graph's worker)
  if (frame.status != session::FrameStatus::kFused) {
    logger().warn("scan: frame {} {}: {}", frame.index, session::frame_status_name(frame.status), frame.reason);
  }
  if (scan.callback == nullptr) return;
  // The depth map comes to the host only for a callback (a GPU decode leaves it on the device).
  const float* depth_device = maps.depth_on_device != nullptr ? maps.depth_on_device->data() : nullptr;
  const sls_frame_report report = frame_report_to_c(frame, recording_frames, {maps.host_depth(), depth_device});
  scan.callback_thread.store(std::this_thread::get_id());
  scan.callback(&report, scan.user);
  scan.callback_thread.store(std::thread::id());
}

}  // namespace sls::capi

extern "C" {

SLS_CAPI_DEFINE_INIT(sls_scan_config, online_deformation, scan_config_defaults())

SLS_CAPI_DEFINE_INIT(sls_frame_report, depth_device, sls::capi::zeroed<sls_frame_report>())

SLS_CAPI_DEFINE_INIT(sls_capture_config, frames, sls::capi::zeroed<sls_capture_config>())

SLS_CAPI_DEFINE_INIT(sls_scan_summary, loop_closed, sls::capi::zeroed<sls_scan_summary>())

SLS_CAPI_DEFINE_INIT(sls_loop_closure, ms, sls::capi::zeroed<sls_loop_closure>())

SLS_API sls_status sls_scan_create(sls_context* context, const sls_scan_config* config, sls_scan** scan,
                                   sls_error** error) {
  SLS_CAPI_REQUIRE(scan != nullptr, error, "scan (the output pointer) is NULL");
  *scan = nullptr;
  SLS_CAPI_REQUIRE(context != nullptr, error, "context is NULL");
  return sls::capi::guarded(__func__, error, [&] {
    sls_scan_config defaults;
    sls_scan_config_init(&defaults);
    const sls_scan_config resolved =
        config == nullptr ? defaults
                          : sls::capi::read_versioned(config, defaults, kScanConfigFirstVersionSize, "sls_scan_config");
    auto created = std::make_unique<sls_scan>();
    ScanChoices choices;
    created->options = session_options(resolved, context->device, &choices);
    created->groundtruth = choices.groundtruth;
    created->no_record = choices.no_record;
    created->loop_closure = choices.loop_closure;
    if (resolved.calibration_path != nullptr && resolved.calibration_path[0] != '\0') {
      created->calibration = sls::read_calibration(resolved.calibration_path);
    }
    *scan = created.release();
  });
}

SLS_API void sls_scan_destroy(sls_scan* scan) { delete scan; }

SLS_API sls_status sls_scan_set_frame_callback(sls_scan* scan, sls_frame_callback callback, void* user,
                                               sls_error** error) {
  SLS_CAPI_REQUIRE(scan != nullptr, error, "scan is NULL");
  const ScanHold hold(*scan);
  if (!hold.held()) return report_busy(__func__, error);
  scan->callback = callback;
  scan->user = user;
  return SLS_OK;
}

SLS_API sls_status sls_scan_run_recording(sls_scan* scan, const char* recording_path, sls_error** error) {
  SLS_CAPI_REQUIRE(scan != nullptr, error, "scan is NULL");
  SLS_CAPI_REQUIRE(recording_path != nullptr, error, "recording_path is NULL");
  const ScanHold hold(*scan);
  if (!hold.held()) return report_busy(__func__, error);
  return sls::capi::guarded(__func__, error, [&] {
    refuse_if_cancelled(*scan);
    discard_results(*scan);
    scan_recording(*scan, recording_path);
  });
}

SLS_API sls_status sls_scan_run_devices(sls_scan* scan, const sls_capture_config* capture, sls_error** error) {
  SLS_CAPI_REQUIRE(scan != nullptr, error, "scan is NULL");
  SLS_CAPI_REQUIRE(capture != nullptr, error, "capture is NULL");
  const ScanHold hold(*scan);
  if (!hold.held()) return report_busy(__func__, error);
  return sls::capi::guarded(__func__, error, [&] {
    sls_capture_config defaults;
    sls_capture_config_init(&defaults);
    const sls_capture_config resolved =
        sls::capi::read_versioned(capture, defaults, kCaptureConfigFirstVersionSize, "sls_capture_config");
    refuse_if_cancelled(*scan);
    discard_results(*scan);
    scan_devices(*scan, resolved);
  });
}

SLS_API sls_status sls_scan_cancel(sls_scan* scan, sls_error** error) {
  SLS_CAPI_REQUIRE(scan != nullptr, error, "scan is NULL");
  scan->cancel_requested.store(true);
  return SLS_OK;
}

SLS_API sls_status sls_scan_get_summary(const sls_scan* scan, sls_scan_summary* summary, sls_error** error) {
  SLS_CAPI_REQUIRE(scan != nullptr, error, "scan is NULL");
  SLS_CAPI_REQUIRE(summary != nullptr, error, "summary (the output pointer) is NULL");
  const ScanHold hold(*scan);
  if (!hold.held()) return report_busy(__func__, error);
  return sls::capi::guarded(__func__, error, [&] {
    sls_scan_summary filled;
    sls_scan_summary_init(&filled);
    if (scan->session) {
      const sls::session::ScanSession& session = *scan->session;
      for (const sls::session::FrameReport& frame : session.frames()) {
        ++filled.frames;
        switch (frame.status) {
          case sls::session::FrameStatus::kFused: ++filled.fused; break;
          case sls::session::FrameStatus::kLost: ++filled.lost; break;
          case sls::session::FrameStatus::kSkipped: ++filled.skipped; break;
        }
      }
      if (filled.fused > 0) filled.voxel_size_m = session.volume_geometry().voxel_size_m;
      filled.volume_moves = session.moves();
      // The graph once the worker is done: waits for it only when the caller's struct asks.
      if (summary->struct_size > offsetof(sls_scan_summary, deformation_nodes)) {
        const sls::session::ScanSession::GraphSummary graph = session.graph_summary();
        filled.deformation_nodes = graph.nodes;
        filled.deformation_constraints = graph.constraints;
      }
      filled.loop_closed = session.loop_closure().has_value() ? 1 : 0;
    }
    filled.cancelled = scan->cancelled ? 1 : 0;
    sls::capi::write_versioned(filled, summary, kSummaryFirstVersionSize, "sls_scan_summary");
  });
}

SLS_API sls_status sls_scan_close_loop(sls_scan* scan, sls_loop_closure* result, sls_error** error) {
  SLS_CAPI_REQUIRE(scan != nullptr, error, "scan is NULL");
  const ScanHold hold(*scan);
  if (!hold.held()) return report_busy(__func__, error);
  return sls::capi::guarded(__func__, error, [&] {
    // The caller's struct checked before the model changes: a bad one changes nothing.
    if (result != nullptr) sls::capi::require_versioned(result, kLoopClosureFirstVersionSize, "sls_loop_closure");
    const sls_loop_closure closed = close_loop(*scan);
    if (result != nullptr) sls::capi::write_versioned(closed, result, kLoopClosureFirstVersionSize, "sls_loop_closure");
  });
}

SLS_API sls_status sls_scan_write_cloud(const sls_scan* scan, const char* path, sls_error** error) {
  SLS_CAPI_REQUIRE(scan != nullptr, error, "scan is NULL");
  SLS_CAPI_REQUIRE(path != nullptr, error, "path is NULL");
  const ScanHold hold(*scan);
  if (!hold.held()) return report_busy(__func__, error);
  return sls::capi::guarded(__func__, error, [&] { sls::write_ply(path, sls::capi::model_surface(*scan)->cloud); });
}

SLS_API sls_status sls_scan_write_mesh(const sls_scan* scan, const char* path, sls_error** error) {
  SLS_CAPI_REQUIRE(scan != nullptr, error, "scan is NULL");
  SLS_CAPI_REQUIRE(path != nullptr, error, "path is NULL");
  const ScanHold hold(*scan);
  if (!hold.held()) return report_busy(__func__, error);
  return sls::capi::guarded(__func__, error, [&] { sls::write_ply(path, sls::capi::model_surface(*scan)->mesh); });
}

SLS_API sls_status sls_scan_write_trajectory(const sls_scan* scan, const char* path, sls_error** error) {
  SLS_CAPI_REQUIRE(scan != nullptr, error, "scan is NULL");
  SLS_CAPI_REQUIRE(path != nullptr, error, "path is NULL");
  const ScanHold hold(*scan);
  if (!hold.held()) return report_busy(__func__, error);
  return sls::capi::guarded(__func__, error,
                            [&] { sls::write_tum_trajectory(path, sls::capi::fused_session(*scan).trajectory()); });
}

}  // extern "C"
