// sls calibrate: camera, projector and turntable axis from board views (calib/), written as
// the calibration.yml that decode and fusion read. Input: a recording (e.g. `sls sim
// --calibration`) or a folder of captures, one subfolder per board pose; or the views captured
// first through devices by URI (--camera ... --record DIR: session::capture_calibration, a
// confirmation per hand pose read from stdin), then calibrated from DIR as --input DIR would.
#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <optional>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "samples/sls/capture.h"
#include "samples/sls/commands.h"
#include "sdk/core/device.h"
#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/recording.h"
#include "sdk/session/calibration_capture.h"

#if defined(SLS_HAVE_CALIB)
#include "calib/calibrate_capture.h"
#include "calib/multi_camera_calibration.h"
#include "samples/sls/calibrate_multi_camera.h"
#include "samples/sls/calibration_report.h"
#endif

namespace sls::cli {
namespace {

struct CalibrateOptions {
  std::string input;
  std::string out;
  std::string patterns;
  std::string board;  // COLSxROWS (chessboard) or charuco:COLSxROWS
  double square_m = 0.0;
  double marker_m = 0.0;   // ChArUco
  std::string dictionary;  // ChArUco; empty: calib's default
  std::string report;
  std::string device;
  double max_rms_px = 1.0;
  bool force = false;
  bool estimate_k3 = false;
  // Capture mode (--camera): the devices, the recording, the poses. Several cameras: a head,
  // captured together into record/camera0, camera1, ... and calibrated as a head.
  std::vector<std::string> camera_uris;
  std::string projector_uri;
  std::string turntable_uri;
  std::string record;
  int hand_poses = 12;
  std::vector<double> turntable_angles;
  double exposure_us = 0.0;
  bool yes = false;
  bool resume = false;
};

#if defined(SLS_HAVE_CALIB)
namespace fs = std::filesystem;

// One line from stdin without its newline, or nullopt at its end. Waits in steps of 100 ms, so
// that a SIGINT (after which a plain read would simply go on) ends the wait with kCancelled.
std::optional<std::string> read_answer(const StopOnSignal& stop) {
  std::string line;
  for (;;) {
    if (stop.requested()) throw_error(ErrorCode::kCancelled, "interrupted while waiting for the operator");
    pollfd input{STDIN_FILENO, POLLIN, 0};
    const int ready = ::poll(&input, 1, 100);
    if (ready < 0 && errno != EINTR) throw_error(ErrorCode::kIo, "stdin: {}", std::strerror(errno));
    if (ready <= 0) continue;
    char c = 0;
    const ssize_t n = ::read(STDIN_FILENO, &c, 1);
    if (n < 0 && errno != EINTR) throw_error(ErrorCode::kIo, "stdin: {}", std::strerror(errno));
    if (n < 0) continue;
    // An end of input that came with a signal (a parent that signals, then closes the pipe) is
    // the signal's: the handler has run by the time read() returns.
    if (n == 0 && stop.requested()) throw_error(ErrorCode::kCancelled, "interrupted while waiting for the operator");
    if (n == 0) return line.empty() ? std::nullopt : std::optional<std::string>(line);
    if (c == '\n') return line;
    line += c;
  }
}

// The operator's answer to `question` on stderr: Enter (capture), s (skip) or q (stop).
session::PoseDecision ask(const std::string& question, const std::string& pose, const StopOnSignal& stop) {
  if (::isatty(STDERR_FILENO) != 0) std::cerr << "\n";  // below the progress line
  for (;;) {
    std::cerr << question << std::flush;
    const std::optional<std::string> answer = read_answer(stop);
    if (::isatty(STDIN_FILENO) == 0) std::cerr << "\n";  // answers from a pipe are not echoed
    if (!answer) {
      throw_error(ErrorCode::kInvalidArgument,
                  "no answer for {}: stdin ended (--yes captures every pose without asking)", pose);
    }
    std::string word;
    for (const char c : *answer) {
      if (std::isspace(static_cast<unsigned char>(c)) == 0) word += static_cast<char>(std::tolower(c));
    }
    if (word.empty()) return session::PoseDecision::kCapture;
    if (word == "s" || word == "skip") return session::PoseDecision::kSkip;
    if (word == "q" || word == "quit" || word == "stop") return session::PoseDecision::kStop;
    std::cerr << "answer Enter (capture), s (skip) or q (stop capturing)\n";
  }
}

// The confirmations of `sls calibrate --camera`: each hand pose asked for on the terminal, and
// once before the turntable poses (the board goes onto the table); with --yes none.
session::PoseConfirmation terminal_confirmation(const CalibrateOptions& options, const StopOnSignal& stop) {
  auto table = std::make_shared<std::optional<session::PoseDecision>>();  // the answer for the table poses
  return [&options, &stop, table](const session::CalibrationPose& pose) {
    if (options.yes) return session::PoseDecision::kCapture;
    if (pose.kind == session::CalibrationPoseKind::kHand) {
      return ask(fmt::format("Place the board for pose {} of {} and press Enter (s: skip this pose, q: stop "
                             "capturing) ",
                             pose.index + 1, pose.count),
                 pose.describe(), stop);
    }
    if (!*table) {
      *table = ask(fmt::format("Fix the board on the turntable for the {} turntable pose(s) and press Enter (s: skip "
                               "them, q: stop capturing) ",
                               pose.count),
                   pose.describe(), stop);
    }
    return **table;
  };
}

// The command that continues an interrupted capture.
// The board's flags as given: "--board B --square S [--marker M] [--dictionary D]".
std::string board_words(const CalibrateOptions& options) {
  std::string words = fmt::format("--board {} --square {:g}", options.board, options.square_m);
  if (options.marker_m > 0.0) words += fmt::format(" --marker {:g}", options.marker_m);
  if (!options.dictionary.empty()) words += " --dictionary " + options.dictionary;
  return words;
}

std::string resume_command(const CalibrateOptions& options) {
  std::string command = "sls calibrate";
  for (const std::string& camera : options.camera_uris) command += " --camera " + camera;
  command += " --projector " + options.projector_uri;
  if (!options.turntable_uri.empty()) command += " --turntable " + options.turntable_uri;
  command += fmt::format(" --record {} --hand-poses {}", options.record, options.hand_poses);
  if (!options.turntable_angles.empty()) {
    std::string angles;
    for (const double angle : options.turntable_angles) angles += (angles.empty() ? "" : ",") + fmt::format("{:g}", angle);
    command += " --turntable-angles " + angles;
  }
  command += fmt::format(" {} --out {} --resume", board_words(options), options.out);
  return command;
}

nlohmann::json calibration_capture_json(const session::CalibrationCapture& captured) {
  nlohmann::json poses = nlohmann::json::array();
  for (const session::CalibrationPoseResult& pose : captured.poses) {
    poses.push_back({{"pose", pose.pose.describe()},
                     {"kind", session::calibration_pose_kind_name(pose.pose.kind)},
                     {"index", pose.pose.index},
                     {"captured", pose.captured},
                     {"frame", pose.captured ? nlohmann::json(pose.frame) : nlohmann::json()},
                     {"turntable_angle_deg",
                      pose.turntable_angle_deg ? nlohmann::json(*pose.turntable_angle_deg) : nlohmann::json()},
                     {"complete", pose.complete},
                     {"seconds", pose.seconds}});
  }
  const int captured_poses = captured.captured_poses();
  nlohmann::json recordings = nlohmann::json::array();
  for (int k = 0; k < captured.cameras; ++k) {
    recordings.push_back(captured.cameras > 1 ? head_camera_folder(captured.folder, static_cast<std::size_t>(k))
                                              : captured.folder);
  }
  return {{"recording", captured.folder},
          {"cameras", captured.cameras},
          {"recordings", recordings},
          {"frames", captured.frames},
          {"hand_frames", captured.hand_frames},
          {"turntable_frames", captured.turntable_frames},
          {"resumed_from", captured.resumed_from},
          {"images_per_frame", captured.images_per_frame},
          {"poses_captured", captured_poses},
          {"poses_skipped", captured.skipped_poses()},
          {"stopped", captured.stopped},
          {"incomplete_frames", captured.statistics.incomplete_frames},
          {"retries", captured.statistics.retries},
          {"seconds", captured.seconds},
          {"capture_seconds", captured.capture_seconds},
          {"seconds_per_pose", captured_poses > 0 ? nlohmann::json(captured.capture_seconds / captured_poses)
                                                  : nlohmann::json()},
          {"poses", poses}};
}

// Captures the board views through the devices into options.record. Returns nullopt when a
// signal stopped it (reported here: exit status 4).
std::optional<session::CalibrationCapture> capture_views(const Context& context, const CalibrateOptions& options,
                                                         const StopOnSignal& stop) {
  std::error_code error;
  // A head's capture is one recording per camera (camera0 says what was done).
  const bool head = options.camera_uris.size() > 1;
  const std::string first_recording = head ? head_camera_folder(options.record, 0) : options.record;
  const bool holds_recording = fs::exists(fs::path(first_recording) / "manifest.json", error);
  if (options.resume && !holds_recording) {
    throw_error(ErrorCode::kInvalidArgument, "--resume: {} holds no recording to continue (no {}manifest.json)",
                options.record, head ? "camera0/" : "");
  }
  if (!options.resume && fs::exists(options.record, error) && !fs::is_empty(options.record, error)) {
    throw_error(ErrorCode::kInvalidArgument, "--record {} is not empty{}; add --resume to continue it, or choose another",
                options.record, holds_recording ? " (it holds a recording, maybe one cut off)" : "");
  }
  session::CalibrationDeviceRequest request;
  request.camera_uri = options.camera_uris.front();
  request.more_camera_uris.assign(options.camera_uris.begin() + 1, options.camera_uris.end());
  request.projector_uri = options.projector_uri;
  request.turntable_uri = options.turntable_uri;
  if (!options.patterns.empty()) request.patterns = pattern_set_from_name(options.patterns);
  request.sim_device = options.device.empty() ? Device::cpu() : parse_device(options.device);
  session::CalibrationCaptureOptions capture;
  capture.hand_poses = options.hand_poses;
  capture.turntable_angles_deg = options.turntable_angles;
  capture.exposure_us = options.exposure_us;
  capture.resume = options.resume;
  const auto frames_in_record = [&first_recording] {
    try {
      return RecordingReader::open(first_recording).frame_count();
    } catch (const Error&) {
      return std::size_t{0};
    }
  };
  try {
    return session::capture_calibration_from_devices(options.record, request, capture,
                                                     terminal_confirmation(options, stop),
                                                     stop.wrap(context.progress_callback("capture")));
  } catch (const Error& failure) {
    if (failure.code() != ErrorCode::kCancelled || !stop.requested()) {
      if (frames_in_record() == 0) throw;
      throw Error(failure.code(), fmt::format("{}: continue it with the same command and --resume, or calibrate it "
                                              "with sls calibrate --input {}",
                                              failure.what(), options.record));
    }
  }
  const std::size_t frames = frames_in_record();
  if (context.options.json) {
    std::cout << nlohmann::json({{"ok", false},
                                 {"interrupted", true},
                                 {"stage", "capture"},
                                 {"signal", stop.signal_name()},
                                 {"recording", options.record},
                                 {"cameras", options.camera_uris.size()},
                                 {"frames_captured", frames},
                                 {"resume", resume_command(options)}})
                     .dump(2)
              << "\n";
  }
  std::cerr << fmt::format("\ninterrupted by {} during the calibration capture: {} pose(s) captured into {} ({}, not "
                           "calibrated).\nContinue the capture: {}\nor calibrate what it holds: sls "
                           "calibrate --input {} {} --out {}\n",
                           stop.signal_name(), frames, options.record,
                           head ? fmt::format("a valid recording per camera of the {}", options.camera_uris.size())
                                : "a valid recording",
                           resume_command(options), options.record, board_words(options), options.out);
  return std::nullopt;
}

// A signal stopped the calibration of a capture just made: said on stderr (and stdout with
// --json); exit status 4.
int report_calibration_interrupted(const Context& context, const CalibrateOptions& options, const StopOnSignal& stop,
                                   const session::CalibrationCapture& captured) {
  if (context.options.json) {
    std::cout << nlohmann::json({{"ok", false},
                                 {"interrupted", true},
                                 {"stage", "calibrate"},
                                 {"signal", stop.signal_name()},
                                 {"recording", options.record},
                                 {"capture", calibration_capture_json(captured)}})
                     .dump(2)
              << "\n";
  }
  std::cerr << fmt::format("\ninterrupted by {} during the calibration: the capture in {} is complete; calibrate it "
                           "with sls calibrate --input {} {} --out {}\n",
                           stop.signal_name(), options.record, options.record, board_words(options),
                           options.out);
  return kExitInterrupted;
}

int run_calibrate(const Context& context, const CalibrateOptions& options) {
  calib::CalibrateCaptureOptions calibrate;
  calibrate.input = options.input;
  calibrate.patterns = options.patterns;
  calibrate.estimate_k3 = options.estimate_k3;
  calibrate.device = options.device.empty() ? Device::cpu() : parse_device(options.device);
  if (!options.board.empty()) {
    calibrate.board = calib::parse_board_spec(options.board, options.square_m, options.marker_m, options.dictionary);
  } else if (options.square_m > 0.0 || options.marker_m > 0.0 || !options.dictionary.empty()) {
    throw_error(ErrorCode::kInvalidArgument, "--square, --marker and --dictionary need --board (COLSxROWS or "
                                             "charuco:COLSxROWS)");
  }
  // Capture mode (the board checked first): a signal stops the capture after the current pose,
  // or the calibration after it.
  std::optional<StopOnSignal> stop;
  std::optional<session::CalibrationCapture> captured;
  if (!options.camera_uris.empty()) {
    calibrate.board.validate();
    stop.emplace();
    captured = capture_views(context, options, *stop);
    if (!captured) return kExitInterrupted;
    if (captured->frames == 0) {
      throw_error(ErrorCode::kInvalidArgument, "no pose captured into {}: nothing to calibrate", options.record);
    }
    if (!context.options.json) {
      std::cerr << fmt::format("captured {} frame(s) ({} by hand, {} on the turntable; {} pose(s) skipped{}{}) x {} "
                               "images{} into {} in {:.1f} s ({:.2f} s per pose)\n",
                               captured->frames, captured->hand_frames, captured->turntable_frames,
                               captured->skipped_poses(),
                               captured->resumed_from > 0 ? fmt::format(", resumed at frame {}", captured->resumed_from)
                                                          : "",
                               captured->stopped ? ", stopped by the operator" : "", captured->images_per_frame,
                               captured->cameras > 1 ? fmt::format(" x {} cameras", captured->cameras) : "",
                               options.record, captured->seconds,
                               captured->captured_poses() > 0 ? captured->capture_seconds / captured->captured_poses()
                                                              : 0.0);
    }
    calibrate.input = options.record;
    calibrate.patterns.clear();  // the recording's own
  }
  const ProgressCallback progress = context.progress_callback("calibrate");
  // A head of several cameras (camera0/, camera1/, ...): each against the projector, then
  // camera to camera. A head just captured is one (captured->cameras > 1); a one-camera
  // capture is never taken for a head, whatever its recording's folder holds.
  const bool head = captured ? captured->cameras > 1 : calib::is_multi_camera_capture(calibrate.input);
  try {
    if (head) {
      MultiCameraOutput output;
      output.out = options.out;
      output.report = options.report;
      output.max_rms_px = options.max_rms_px;
      output.force = options.force;
      output.progress = stop ? stop->wrap(progress) : progress;
      if (captured) output.capture = calibration_capture_json(*captured);
      return run_multi_camera_calibrate(context, calibrate, output);
    }
  } catch (const Error& error) {
    if (!stop || !stop->requested() || error.code() != ErrorCode::kCancelled) throw;
    return report_calibration_interrupted(context, options, *stop, *captured);
  }
  calib::CalibrateCaptureResult result;
  try {
    result = calib::calibrate_capture(calibrate, stop ? stop->wrap(progress) : progress);
  } catch (const Error& error) {
    if (!stop || !stop->requested() || error.code() != ErrorCode::kCancelled) throw;
    return report_calibration_interrupted(context, options, *stop, *captured);
  }
  nlohmann::json json = calibration_json(result);
  if (captured) json["capture"] = calibration_capture_json(*captured);
  const double rms = result.procam.stereo_rms_px;
  const bool too_high = !(rms <= options.max_rms_px);
  const bool write = !too_high || options.force;
  json["out"] = options.out;
  json["written"] = write;
  json["max_rms_px"] = options.max_rms_px;
  if (too_high) {
    json["warning"] = fmt::format("stereo RMS {:.3f} px is above the limit {:.3f} px{}", rms, options.max_rms_px,
                                  options.force ? ": written anyway (--force)" : ": not written (--force writes it)");
  }
  // The report first: if the calibration cannot be written, the work is still on disk.
  if (!options.report.empty()) {
    json["report"] = options.report + "/calibration_report.html";
    write_calibration_report(options.report, result, json);
  }
  if (write) {
    const std::filesystem::path parent = std::filesystem::path(options.out).parent_path();
    if (!parent.empty()) create_directories(parent.string());
    write_calibration(options.out, result.procam.calibration);
  }
  if (!write) throw_error(ErrorCode::kInvalidArgument, "{}", json["warning"].get<std::string>());
  json["ok"] = true;
  context.emit(json, [&] {
    std::cout << fmt::format("calibrated from {} of {} views in {:.1f} s: camera {:.3f} px, projector {:.3f} px, "
                             "stereo {:.3f} px RMS (corners dropped as mislocated: {} camera, {} projector)\n",
                             result.procam.views_used, result.views.size(), result.seconds,
                             result.procam.camera_rms_px, result.procam.projector_rms_px, rms,
                             result.procam.camera_outliers, result.procam.projector_outliers);
    for (std::size_t v = 0; v < result.views.size(); ++v) {
      if (!result.procam.views[v].used) {
        std::cout << "  rejected " << result.views[v].name << ": " << result.procam.views[v].rejected_reason << "\n";
      }
    }
    std::cout << (result.axis.fitted
                      ? fmt::format("turntable axis from {} views ({:.0f}° span)\n", result.axis.views,
                                    result.axis.angle_span_deg)
                      : "no turntable axis: " + result.axis.reason + "\n");
    if (json.contains("truth")) {
      const nlohmann::json& t = json["truth"];
      std::cout << fmt::format("against the exact calibration: focal {:.4f} %, principal point {:.3f} px, baseline "
                               "{:.4f} %, rotation {:.4f}°",
                               100.0 * t["focal_rel_err"].get<double>(), t["principal_point_err_px"].get<double>(),
                               100.0 * t["baseline_rel_err"].get<double>(), t["rotation_err_deg"].get<double>());
      if (!t["axis_direction_err_deg"].is_null()) {
        std::cout << fmt::format(", axis {:.4f}° and {:.1f} um", t["axis_direction_err_deg"].get<double>(),
                                 t["axis_point_err_um"].get<double>());
      }
      std::cout << "\n";
    }
    if (too_high) std::cout << "warning: " << json["warning"].get<std::string>() << "\n";
    std::cout << "wrote " << options.out;
    if (!options.report.empty()) std::cout << " and " << options.report << "/calibration_report.html";
    std::cout << "\n";
  });
  return kExitOk;
}
#endif

}  // namespace

void add_calibrate_command(CLI::App& app, Context& context, int* exit_code) {
  CLI::App* command = app.add_subcommand(
      "calibrate", "Calibrate camera, projector and turntable axis from board views (a recording, e.g. `sls sim "
                   "--calibration`, or a folder with one subfolder of pattern images per board pose), or capture the "
                   "views first through devices by URI (--camera ... --record DIR)");
  command->footer(
      "Capture mode: --camera URI --projector URI [--turntable URI] --record DIR --hand-poses N [--turntable-angles "
      "A,B,...] --board COLSxROWS --square M --out FILE. Before each hand pose it asks on stderr \"Place the board for "
      "pose K of N and press Enter (s: skip this pose, q: stop capturing)\" and reads the answer from stdin (q ends "
      "the capture and calibrates from the poses captured); before the turntable poses it asks once for the board to "
      "be fixed on the table; --yes asks nothing. Each pose is the full pattern stack (columns and rows, white and "
      "black) through the capture sequencer, appended to DIR (an ordinary recording, uncalibrated); then DIR is "
      "calibrated as --input DIR. SIGINT/SIGTERM stops the capture after the current pose (or the calibration): DIR is "
      "kept (valid), exit status 4, and --resume continues it. sim://chessboard?calibration=1&preset=ci&hand_poses=N "
      "is a simulated board whose operator places it at each pose (&board=charuco[:COLSxROWS]: a ChArUco board, "
      "`sls sim --calibration --board charuco`'s). A head of several cameras: --camera once per "
      "camera, camera 0 first (e.g. sim://chessboard?calibration=1&preset=ci&hand_poses=N&cameras=2&camera=K for "
      "camera K of `sls sim --calibration --cameras 2`'s head); each pose is captured by every camera together into "
      "DIR/camera0, DIR/camera1, ..., then DIR is calibrated as a head (each camera against the projector, then "
      "camera to camera); --resume continues every camera's recording and refuses a head whose recordings disagree.");
  auto options = std::make_shared<CalibrateOptions>();
  auto* input = command->add_option("--input", options->input,
                                    "Recording, or folder of captures (one subfolder per board pose), or a head of "
                                    "several cameras: a folder with one such capture per camera in camera0, camera1, "
                                    "... (the same board poses in the same order)");
  auto* camera = command->add_option("--camera", options->camera_uris,
                                     "Capture the views first with devices by URI (see `sls devices`): the camera, e.g. "
                                     "gige://192.168.1.20; repeat it for a head of several cameras (camera 0 first): "
                                     "every pose is captured by all of them together, one projection per pattern, "
                                     "into --record's camera0, camera1, ..., then calibrated as a head");
  auto* projector = command->add_option("--projector", options->projector_uri,
                                        "With --camera: the projector, e.g. dlpc350://");
  auto* turntable = command->add_option("--turntable", options->turntable_uri,
                                        "With --camera: the turntable, e.g. headctl:// (for --turntable-angles)");
  auto* record = command->add_option("--record", options->record,
                                     "With --camera: folder for the capture's recording (new or empty; with --resume "
                                     "the one to continue); with several --camera, the head's folder, one recording "
                                     "per camera in camera0, camera1, ...");
  auto* hand_poses = command->add_option("--hand-poses", options->hand_poses,
                                         "With --camera: board poses by hand, each confirmed on the terminal")
                         ->check(CLI::Range(0, 1000))
                         ->capture_default_str();
  auto* angles = command->add_option("--turntable-angles", options->turntable_angles,
                                     "With --turntable: then the board fixed on the table at these angles in degrees, "
                                     "0 <= A < 360, e.g. 350,0,10 (none by default)")
                     ->delimiter(',')
                     ->check(CLI::Validator(
                         [](std::string& text) {
                           char* end = nullptr;
                           const double angle = std::strtod(text.c_str(), &end);
                           const bool ok = end != text.c_str() && *end == '\0' && std::isfinite(angle) &&
                                           angle >= 0.0 && angle < 360.0;
                           return ok ? std::string() : text.substr(0, 40) + " is not an angle in [0, 360)";
                         },
                         "ANGLE in [0, 360)"));
  auto* exposure = command->add_option("--exposure-us", options->exposure_us,
                                       "With --camera: camera exposure in microseconds (0: leave it as it is)")
                       ->check(finite_range(1.0, 1e7, true));
  auto* yes = command->add_flag("--yes", options->yes,
                                "With --camera: capture every pose without asking (a fixture that moves the board)");
  auto* resume = command->add_flag("--resume", options->resume,
                                   "With --camera: continue the capture in --record that was cut off (a signal, a kill, "
                                   "a device error) with the same devices and options: the hand poses it lacks, then "
                                   "the turntable angles it lacks; then calibrate");
  input->excludes(camera);
  camera->excludes(input);
  for (CLI::Option* option : {projector, record}) camera->needs(option);
  for (CLI::Option* option : {projector, turntable, record, hand_poses, exposure, yes, resume}) option->needs(camera);
  angles->needs(turntable);
  command->add_option("--out", options->out, "calibration.yml to write")->required();
  command->add_option("--patterns", options->patterns,
                      "Pattern set by name: opencv-graycode:WxH (OpenCV structured_light's Gray code for a WxH "
                      "projector, white and black last) or gray-phase:WxH (default: the recording's own; with "
                      "--camera: the set to project, default gray-phase with columns and rows at the projector's "
                      "size)");
  auto* board = command->add_option("--board", options->board,
                                    "The board: COLSxROWS = a chessboard's inner corners, e.g. 9x7; charuco:COLSxROWS = "
                                    "a ChArUco board's squares, e.g. charuco:12x9 (OpenCV's CharucoBoard: markers in "
                                    "the light squares; views of part of the board count). Default: a simulated "
                                    "capture's own board; required with --camera");
  auto* square = command->add_option("--square", options->square_m, "Board square side in metres (with --board)")
                     ->check(CLI::PositiveNumber);
  command->add_option("--marker", options->marker_m,
                      "ChArUco marker side in metres, smaller than --square (with --board charuco:COLSxROWS)")
      ->check(CLI::PositiveNumber)
      ->needs(board);
  command->add_option("--dictionary", options->dictionary,
                      fmt::format("ChArUco markers' ArUco dictionary, OpenCV's name (default {}; e.g. DICT_4X4_50, "
                                  "DICT_6X6_250, DICT_APRILTAG_36h11)",
                                  "DICT_5X5_100"))
      ->needs(board);
  camera->needs(board);
  camera->needs(square);
  command->add_option("--report", options->report, "Folder for calibration_report.html and calibration.json");
  command->add_option("--max-rms-px", options->max_rms_px,
                      "Stereo RMS above which the calibration is not written (unless --force)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  command->add_flag("--force", options->force, "Write the calibration even when its RMS is above --max-rms-px");
  command->add_flag("--estimate-k3", options->estimate_k3,
                    "Also estimate the r^6 distortion term (default: fixed at 0, poorly determined by a narrow field)");
  command->add_option("--device", options->device,
                      "Decode (and with --camera render sim:// devices) on cpu, cuda or cuda:N (default: cpu)");
  command->callback([&context, exit_code, options] {
    if (options->input.empty() && options->camera_uris.empty()) {
      throw CLI::RequiredError("--input (a recording or folder) or --camera (with --projector, --record)");
    }
    run_command(context, "calibrate",
                [&context, options] {
#if defined(SLS_HAVE_CALIB)
                  return run_calibrate(context, *options);
#else
                  throw_error(ErrorCode::kUnsupported, "sls was built without OpenCV: calibration is not available");
                  return kExitUnavailable;
#endif
                },
                exit_code);
  });
}

}  // namespace sls::cli
