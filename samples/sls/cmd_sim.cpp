// sls sim: scans the simulated scanner into a recording with ground truth
// (drivers/sim/sim_recording.h describes what is written), or with --calibration makes a
// calibration capture (drivers/sim/sim_calibration_capture.h).
#include <filesystem>
#include <iostream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "drivers/sim/rig.h"
#include "drivers/sim/sim_calibration_capture.h"
#include "drivers/sim/sim_recording.h"
#include "samples/sls/capture.h"
#include "samples/sls/commands.h"
#include "sdk/core/device.h"
#include "sdk/core/error.h"
#include "sdk/core/recording.h"
#include "sdk/decode/hdr_fusion.h"
#include "sdk/decode/pattern_families.h"
#include "sdk/session/sim_charuco_board.h"

namespace sls::cli {
namespace {

struct SimOptions {
  sim::RigOptions rig;
  std::string object = "knurled-screw";
  std::string mode = "patterns";
  std::string patterns;  // a pattern description file (sdk/decode/README.md); empty: the preset's set
  std::string out;
  std::string device;
  bool no_noise = false;
  double mount_offset_um = sim::RigOptions{}.mount_offset_m * 1e6;
  bool mount_offset_given = false;
  double reference_spacing_um = 0.0;
  bool calibration = false;
  bool resume = false;
  int hand_poses = sim::SimCalibrationOptions{}.hand_poses;
  int turntable_poses = sim::SimCalibrationOptions{}.turntable_poses;
  int cameras = 1;  // of the head, with --calibration
  std::string exposures;  // HDR: relative exposure times, "1,0.25"; empty: one exposure
  // The board (--calibration's target, or --object charuco's): "chessboard", "charuco" or
  // "charuco:COLSxROWS"; sizes in metres (0: the default board's).
  std::string board;
  double square_m = 0.0, marker_m = 0.0;
  std::string dictionary;
};

// The ChArUco board of --object charuco or --calibration --board charuco[:COLSxROWS] on the
// simulator's `geometry`, changed by the flags (session::sim_charuco_board: markers from calib).
sim::ChessboardParameters charuco_board(const SimOptions& options, const sim::ChessboardParameters& geometry) {
  return session::sim_charuco_board(options.board.empty() ? "charuco" : options.board, geometry, options.square_m,
                                    options.marker_m, options.dictionary);
}

int run_sim(const Context& context, const SimOptions& options) {
  const bool charuco = options.object == "charuco" && !options.calibration;
  const bool board_flags = !options.board.empty() || options.square_m > 0.0 || options.marker_m > 0.0 ||
                           !options.dictionary.empty();
  if (board_flags && !options.calibration && !charuco) {
    throw_error(ErrorCode::kInvalidArgument,
                "--board, --square, --marker and --dictionary describe --calibration's target or --object charuco");
  }
  if (charuco && !options.board.empty() && options.board.rfind("charuco", 0) != 0) {
    throw_error(ErrorCode::kInvalidArgument, "--object charuco: --board {} (expected charuco:COLSxROWS)", options.board);
  }
  if (options.calibration && options.board.rfind("charuco", 0) != 0 &&
      (options.marker_m > 0.0 || !options.dictionary.empty())) {
    throw_error(ErrorCode::kInvalidArgument, "--marker and --dictionary need --board charuco[:COLSxROWS]");
  }
  const Device device = options.device.empty() ? default_device() : parse_device(options.device);
  sim::RigOptions rig = options.rig;
  rig.noise = !options.no_noise;
  if (!options.patterns.empty()) rig.patterns = load_pattern_description(options.patterns);
  sim::SimRecordingSummary summary;
  std::string object = options.object;
  // A signal stops the capture after the current frame; the recording so far is kept.
  const StopOnSignal stop;
  const ProgressCallback progress = stop.wrap(context.progress_callback("sim"));
  std::size_t planned = 0;
  const ProgressCallback counting = [&planned, &progress](const ProgressUpdate& update) {
    planned = update.total;
    return progress(update);
  };
  try {
    if (options.calibration) {
      sim::SimCalibrationOptions calibration_options;
      calibration_options.rig = rig;
      calibration_options.hand_poses = options.hand_poses;
      calibration_options.turntable_poses = options.turntable_poses;
      calibration_options.head_object = options.object;
      calibration_options.cameras = options.cameras;
      if (options.board.rfind("charuco", 0) == 0) {
        calibration_options.board = charuco_board(options, sim::charuco_calibration_board_geometry());
      } else if (options.square_m > 0.0) {
        calibration_options.board.square = options.square_m;
      }
      summary = sim::write_sim_calibration_recording(options.out, calibration_options, device, counting);
      object = calibration_options.board.is_charuco() ? "charuco" : "chessboard";  // what is imaged; the head is
                                                                                   // set up for options.object
    } else {
      sim::SimRecordingOptions sim_options;
      sim_options.object = options.object;
      if (options.object == "charuco") {  // the chessboard scene's geometry with markers
        sim_options.scene = sim::make_chessboard_scene(charuco_board(options, sim::ChessboardParameters{}));
      }
      sim_options.rig = rig;
      // Only when given: the default through µm and back is not the same double, and the rig
      // would differ from `sls scan --sim`'s (a recording of one would not resume with the other).
      if (options.mount_offset_given) sim_options.rig.mount_offset_m = options.mount_offset_um * 1e-6;
      sim_options.depth_mode = options.mode == "depth";
      sim_options.reference_spacing_m = options.reference_spacing_um * 1e-6;
      sim_options.resume = options.resume;
      if (!options.exposures.empty()) sim_options.exposures = parse_hdr_exposures(options.exposures).scales;
      summary = sim::write_sim_recording(options.out, sim_options, device, counting);
    }
  } catch (const Error& error) {
    if (error.code() != ErrorCode::kCancelled || !stop.requested()) throw;
    // A head of several cameras: the recording being written when the signal came.
    std::string cut = options.out;
    for (int k = options.cameras - 1; k >= 0 && options.cameras > 1; --k) {
      cut = head_camera_folder(options.out, static_cast<std::size_t>(k));
      if (std::filesystem::exists(cut + "/manifest.json")) break;
    }
    const std::size_t frames = RecordingReader::open(cut).frame_count();
    const std::string resume = options.calibration ? std::string("run it again into an empty folder")
                                                   : "resume with the same command and --resume";
    if (context.options.json) {
      std::cout << nlohmann::json({{"ok", false},
                                   {"interrupted", true},
                                   {"signal", stop.signal_name()},
                                   {"recording", cut},
                                   {"frames", frames},
                                   {"frames_planned", planned}})
                       .dump(2)
                << "\n";
    }
    std::cerr << "\ninterrupted by " << stop.signal_name() << ": wrote " << frames
              << (planned > 0 ? " of " + std::to_string(planned) : std::string()) << " frames to " << cut
              << " (a valid recording); " << resume << "\n";
    return kExitInterrupted;
  }
  nlohmann::json result = {{"ok", true},
                           {"recording", options.out},
                           {"object", object},
                           {"preset", options.rig.preset},
                           {"mode", options.mode},
                           {"calibration", options.calibration},
                           {"uri", summary.uri},
                           {"frames", summary.frames},
                           {"resumed_from", summary.resumed_from},
                           {"images_per_frame", summary.images_per_frame},
                           {"material", options.rig.material},
                           {"camera", {summary.width, summary.height}},
                           {"device", device.to_string()}};
  if (options.calibration) {
    result["hand_poses"] = options.hand_poses;
    result["turntable_poses"] = options.turntable_poses;
    result["head_object"] = options.object;
    result["cameras"] = options.cameras;
    if (options.cameras > 1) {
      nlohmann::json recordings = nlohmann::json::array();
      for (int k = 0; k < options.cameras; ++k) recordings.push_back(head_camera_folder(options.out, static_cast<std::size_t>(k)));
      result["camera_recordings"] = recordings;
      result["groundtruth"] = summary.groundtruth_folder;
    }
  }
  context.emit(result, [&] {
    if (options.calibration) {
      std::cout << "wrote a calibration capture of " << summary.frames << " frames (" << options.hand_poses
                << " board poses by hand, " << options.turntable_poses << " on the turntable; "
                << summary.images_per_frame << " images each, " << summary.width << "x" << summary.height << ")"
                << (options.cameras > 1 ? fmt::format(" per camera of {}, one recording each in camera0 .. camera{} of",
                                                      options.cameras, options.cameras - 1)
                                        : std::string(" to"))
                << " " << options.out << " (exact calibration in " << summary.groundtruth_folder << ")\n";
      return;
    }
    std::cout << "wrote " << summary.frames << " frames"
              << (summary.resumed_from > 0 ? " (resumed at frame " + std::to_string(summary.resumed_from) + ")" : "")
              << " (" << summary.images_per_frame << " images each, "
              << summary.width << "x" << summary.height << ") of the simulated " << object << " to "
              << options.out << " (ground truth in " << summary.groundtruth_folder << ")\n";
  });
  return kExitOk;
}

}  // namespace

void add_sim_command(CLI::App& app, Context& context, int* exit_code) {
  CLI::App* command = app.add_subcommand(
      "sim", "Scan the built-in simulated scanner into a recording with ground truth (depth, projector "
             "coordinates, poses, exact surface)");
  auto options = std::make_shared<SimOptions>();
  command->add_option("--preset", options->rig.preset, "ci, demo or paper:\n" + sim::preset_help())
      ->check(CLI::IsMember({"ci", "demo", "paper"}))
      ->capture_default_str();
  command->add_option("--object", options->object,
                      "The object on the turntable (with --calibration: the one the head is set up for). charuco: "
                      "the chessboard's 10 x 8 squares of 1.2 mm with ArUco markers of 0.9 mm in its light squares "
                      "(OpenCV's ChArUco board, markers from its dictionary; --square, --marker, --dictionary, "
                      "--board charuco:COLSxROWS change it)")
      ->check(CLI::IsMember({"knurled-screw", "knurled-knob", "chessboard", "charuco", "plane", "sphere"}))
      ->capture_default_str();
  CLI::Option* frames =
      command->add_option("--frames", options->rig.frames, "Frames per revolution (0: the preset's)")
          ->check(CLI::Range(0, 100000));
  CLI::Option* mode =
      command
          ->add_option("--mode", options->mode,
                       "patterns: the camera images of every pattern; depth: noisy depth maps straight from the "
                       "geometry (for fusion tests that skip decode)")
          ->check(CLI::IsMember({"patterns", "depth"}))
          ->capture_default_str();
  CLI::Option* patterns = command->add_option(
      "--patterns", options->patterns,
      "A pattern description (JSON, sdk/decode/README.md; examples in samples/patterns/) to project instead of the "
      "preset's Gray code + phase shift; a description for another DMD size gets a DMD of that size");
  command->add_option("--material", options->rig.material,
                      "The object's finish: painted (Lambertian, the scene's albedo) or metal (machined steel: a "
                      "quarter of the albedo diffuse plus a Blinn-Phong specular lobe that saturates the camera at the "
                      "rig's exposure; docs/simulator.md)")
      ->check(CLI::IsMember({"painted", "metal"}))
      ->capture_default_str();
  CLI::Option* exposures = command->add_option(
      "--exposures", options->exposures,
      "HDR capture: the whole stack at each of these exposure times relative to the rig's, comma separated (2 to 4, "
      "e.g. 4,1,0.25), stored exposure-major in one frame; sls decode and sls scan fuse them per pixel "
      "(sdk/decode/hdr_fusion.h). Default: one exposure");
  command->add_option("--projector", options->rig.projector,
                      "dlpc350: DLP4500 912x1140 (as the DLPC350 drives it); 1080p: a 1920x1080 DMD")
      ->check(CLI::IsMember({"dlpc350", "1080p"}))
      ->capture_default_str();
  command->add_option("--bit-depth", options->rig.bit_depth, "Camera ADC bits")
      ->check(CLI::IsMember({8, 10, 12, 16}))
      ->capture_default_str();
  command->add_option("--gamma", options->rig.gamma, "Camera response exponent (1: linear)")
      ->check(finite_range(0.1, 10.0))
      ->capture_default_str();
  command->add_option("--projector-gamma", options->rig.projector_gamma,
                      "Projector response exponent: light = level^gamma per DMD pixel (1: linear, a DLP in pattern "
                      "mode; ~2.2: a projector fed video without linearisation)")
      ->check(finite_range(0.1, 10.0))
      ->capture_default_str();
  command->add_option("--turntable-jitter-deg", options->rig.angle_jitter_deg,
                      "Std. dev. of the true turntable angle about the commanded one (0: exact)")
      ->check(finite_range(0.0, 1.0))
      ->capture_default_str();
  CLI::Option* mount_tilt = command
                                 ->add_option("--mount-tilt-deg", options->rig.mount_tilt_deg,
                                              "Tilt of the object's axis on the table: the wobble (0: none)")
                                 ->check(finite_range(-4.999, 4.999))
                                 ->capture_default_str();
  CLI::Option* mount_offset =
      command->add_option("--mount-offset-um", options->mount_offset_um, "Object axis off the table axis (0: none)")
          ->check(finite_range(-4999.0, 4999.0))
          ->capture_default_str();
  command->add_option("--out", options->out, "Recording folder to create (must not exist or be empty)")->required();
  CLI::Option* resume = command->add_flag(
      "--resume", options->resume,
      "Continue the recording in --out that was cut off (SIGINT/SIGTERM: exit status 4; kill -9; a full disk) "
      "from its first missing frame; the options must be those it was made with (refused, naming the difference, "
      "if not). The result equals an uninterrupted run's");
  command->add_option("--device", options->device, "cpu, cuda or cuda:N (default: cuda when a GPU is present)");
  command->add_option("--seed", options->rig.seed, "Noise and turntable-jitter seed")->capture_default_str();
  command->add_flag("--no-noise", options->no_noise, "Noise-free images and depth (tests, pictures)");
  CLI::Option* reference_spacing =
      command->add_option("--reference-spacing-um", options->reference_spacing_um,
                          "Spacing of groundtruth/reference.ply samples (0: ci 100, demo 30, paper 10)")
          ->check(finite_range(0.0, 1e4));
  CLI::Option* calibration = command->add_flag(
      "--calibration", options->calibration,
      "A calibration capture instead of a scan: a 9 x 7 chessboard of 0.6 mm squares moved by hand (--hand-poses, "
      "table at 0°, manifest angle null), then on a mount on the turntable at angles over -40..+40° "
      "(--turntable-poses); patterns code projector columns and rows. Recorded uncalibrated; groundtruth/ holds the "
      "exact calibration, board, board poses and corners (docs/simulator.md). --object then names the object the "
      "head is set up for (it focuses on its surface; the axis calibrated is its scans'). Not with --frames, --mode, "
      "--mount-tilt-deg, --mount-offset-um, --reference-spacing-um, --patterns or --exposures");
  command->add_option("--hand-poses", options->hand_poses, "With --calibration: board poses by hand")
      ->check(CLI::Range(0, 1000))
      ->needs(calibration)
      ->capture_default_str();
  command->add_option("--turntable-poses", options->turntable_poses,
                      "With --calibration: board views on the turntable (for its axis)")
      ->check(CLI::Range(0, 1000))
      ->needs(calibration)
      ->capture_default_str();
  command
      ->add_option("--cameras", options->cameras,
                    "With --calibration: cameras of the head, 1 to 4, round the projector at the triangulation angle "
                    "from it: the second mirrors the first across it, the third stands above it and the fourth below; "
                    "each camera's capture is a recording of its own, OUT/camera0, OUT/camera1, ..., the head's exact "
                    "calibration in OUT/groundtruth (`sls calibrate --input OUT` calibrates them all)")
      ->check(CLI::Range(1, sim::kMaxSimCalibrationCameras))
      ->needs(calibration)
      ->capture_default_str();
  CLI::Option* board_option =
      command->add_option("--board", options->board,
                          "With --calibration: the target, chessboard (9 x 7 inner corners of 0.6 mm, the whole "
                          "board in every view) or charuco[:COLSxROWS] (OpenCV's ChArUco board, default 12 x 9 squares "
                          "of 1.2 mm with 0.9 mm markers: larger than the field, so views near its edges show part of "
                          "it and its corners reach the image's edges); with --object charuco: charuco:COLSxROWS")
          ->check([](const std::string& text) {
            return text == "chessboard" || text == "charuco" || text.rfind("charuco:", 0) == 0
                       ? std::string()
                       : std::string("expected chessboard, charuco or charuco:COLSxROWS");
          });
  command->add_option("--square", options->square_m,
                      "The board's square side in metres (with --board, or --object charuco; default: the board's)")
      ->check(CLI::PositiveNumber);
  command->add_option("--marker", options->marker_m,
                      "A ChArUco board's marker side in metres, smaller than the square (default: 3/4 of it)")
      ->check(CLI::PositiveNumber);
  command->add_option("--dictionary", options->dictionary,
                      "A ChArUco board's ArUco dictionary, OpenCV's name (default DICT_5X5_100)");
  (void)board_option;
  for (CLI::Option* scan_only :
       {frames, mode, mount_tilt, mount_offset, reference_spacing, resume, patterns, exposures}) {
    scan_only->excludes(calibration);
  }
  command->callback([&context, exit_code, options, mount_offset] {
    options->mount_offset_given = mount_offset->count() > 0;
    run_command(context, "sim", [&context, options] { return run_sim(context, *options); }, exit_code);
  });
}

}  // namespace sls::cli
