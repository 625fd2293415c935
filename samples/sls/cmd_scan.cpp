// sls scan: the scan pipeline, from a recording or the built-in simulator, to a model.
// It runs the stages that exist in this build and names the first one that does not;
// it never writes made-up output.
#include <iostream>

#include "drivers/sim/sim_recording.h"
#include "samples/sls/commands.h"
#include "sdk/core/device.h"
#include "sdk/core/error.h"
#include "sdk/core/recording.h"

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

  // The recording is read and checked (manifest, calibration, every image).
  const RecordingReader recording = RecordingReader::open(input);
  recording.verify(false);
  const ProgressCallback progress = context.progress_callback("read");
  for (std::size_t i = 0; i < recording.frame_count(); ++i) {
    (void)recording.load_images(i);
    report_progress(progress, {"read", i + 1, recording.frame_count(), ""});
  }
  if (!recording.has_calibration()) {
    throw_error(ErrorCode::kInvalidArgument, "{} has no calibration.yml: a scan needs a calibrated recording",
                options.input);
  }
  throw_error(ErrorCode::kUnsupported,
              "read {} frame(s) of {} images from {}, all valid; the decode stage (pattern decoding and "
              "triangulation, sdk/decode) is not in this build yet, so no depth maps, cloud, mesh or trajectory can "
              "be made. Missing stages: decode, tracking, fusion.",
              recording.frame_count(), recording.info().images_per_frame, input);
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
