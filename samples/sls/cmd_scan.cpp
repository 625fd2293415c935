// sls scan: the scan pipeline, from a recording or the built-in simulator, to a model.
// It runs the stages that exist in this build and names the first one that does not;
// it never writes made-up output.
#include <iostream>

#include <fmt/format.h>

#include "drivers/sim/sim_recording.h"
#include "samples/sls/commands.h"
#include "sdk/core/device.h"
#include "sdk/core/error.h"
#include "sdk/core/recording.h"
#include "sdk/decode/decoder.h"

namespace sls::cli {
namespace {

struct ScanOptions {
  std::string input;
  std::string sim_preset;
  std::string object = "knurled-screw";
  int frames = 0;
  std::string out;
  std::string device = "cuda";
  std::string fusion = "gtsdf";
  std::string poses = "track";
  bool device_given = false;
};

int run_scan(const Context& context, const ScanOptions& options) {
  // An explicit --device cuda without a GPU is an error, not a silent fallback.
  const Device device = options.device_given ? parse_device(options.device) : default_device();
  require_device(device);

  std::string input = options.input;
  if (!options.sim_preset.empty()) {
    // Capture: scan the simulated scanner into OUT/recording, as a hardware scan would record.
    sim::SimRecordingOptions sim_options;
    sim_options.rig.preset = options.sim_preset;
    sim_options.object = options.object;
    sim_options.rig.frames = options.frames;
    input = options.out + "/recording";
    const sim::SimRecordingSummary summary =
        sim::write_sim_recording(input, sim_options, device, context.progress_callback("capture"));
    if (!context.options.json) {
      std::cerr << "captured " << summary.frames << " frames x " << summary.images_per_frame << " images ("
                << summary.width << "x" << summary.height << ") from " << summary.uri << " into " << input << "\n";
    }
  }

  // The recording is read and checked (manifest, calibration), then every frame decoded.
  const RecordingReader recording = RecordingReader::open(input);
  recording.verify(false);
  if (!recording.has_calibration()) {
    throw_error(ErrorCode::kInvalidArgument, "{} has no calibration.yml: a scan needs a calibrated recording", input);
  }
  const RecordingInfo& info = recording.info();
  std::size_t decoded_pixels = 0, frames_decoded = 0, frames_with_depth = 0;
  if (info.images_per_frame > 0) {
    DecodeOptions decode_options;
    decode_options.bit_depth = info.camera.bit_depth;
    Decoder decoder(pattern_set_from_json(info.pattern_set_json), recording.calibration(), device, decode_options);
    const ProgressCallback progress = context.progress_callback("decode");
    for (std::size_t i = 0; i < recording.frame_count(); ++i) {
      if (!recording.frame(i).complete) continue;  // an incomplete stack cannot be decoded
      decoded_pixels += decoder.decode(recording.load_images(i)).ok_count();
      ++frames_decoded;
      report_progress(progress, {"decode", i + 1, recording.frame_count(), ""});
    }
  } else {
    for (std::size_t i = 0; i < recording.frame_count(); ++i) frames_with_depth += recording.frame(i).has_depth();
  }
  const double pixels = static_cast<double>(info.camera.width) * static_cast<double>(info.camera.height);
  const std::string done =
      info.images_per_frame > 0
          ? fmt::format("decoded {} of {} frame(s) of {} ({:.1f} % of pixels valid on average)", frames_decoded,
                        recording.frame_count(), input,
                        frames_decoded > 0 ? 100.0 * static_cast<double>(decoded_pixels) /
                                                 (pixels * static_cast<double>(frames_decoded))
                                           : 0.0)
          : fmt::format("read {} depth map(s) from {}", frames_with_depth, input);
  throw_error(ErrorCode::kUnsupported,
              "{}; tracking and fusion (fusion/) are not in this build yet, so no cloud, mesh or trajectory can be "
              "made. Missing stages: tracking, fusion.",
              done);
}

}  // namespace

void add_scan_command(CLI::App& app, Context& context, int* exit_code) {
  CLI::App* command = app.add_subcommand("scan", "Scan an object: recording or simulator -> decode -> track -> fuse -> model");
  auto options = std::make_shared<ScanOptions>();
  auto* input = command->add_option("--input", options->input, "Recording folder to scan");
  auto* sim = command->add_option("--sim", options->sim_preset, "Scan the simulated scanner with this preset")
                  ->check(CLI::IsMember({"ci", "demo", "paper"}));
  input->excludes(sim);
  sim->excludes(input);
  command->add_option("--object", options->object, "Simulated object (with --sim)")
      ->check(CLI::IsMember({"knurled-screw", "knurled-knob", "chessboard", "plane", "sphere"}))
      ->capture_default_str();
  command->add_option("--frames", options->frames, "Simulated frames per revolution (with --sim; 0: the preset's)")
      ->check(CLI::NonNegativeNumber);
  command->add_option("--out", options->out, "Output folder for cloud.ply, mesh.ply, trajectory.txt, report.json")
      ->required();
  command->add_option("--device", options->device, "cpu, cuda or cuda:N (default: cuda when a GPU is present, else cpu)");
  command->add_option("--fusion", options->fusion, "Fusion: tsdf or gtsdf")
      ->check(CLI::IsMember({"tsdf", "gtsdf"}))
      ->capture_default_str();
  command->add_option("--poses", options->poses, "Camera poses: track (ICP) or groundtruth (simulated recordings)")
      ->check(CLI::IsMember({"track", "groundtruth"}))
      ->capture_default_str();
  command->callback([&context, exit_code, options, command] {
    run_command(context, "scan", [&context, options, command] {
      if (options->input.empty() && options->sim_preset.empty()) {
        throw_error(ErrorCode::kInvalidArgument, "give --input REC or --sim PRESET");
      }
      options->device_given = command->count("--device") > 0;
      return run_scan(context, *options);
    }, exit_code);
  });
}

}  // namespace sls::cli
