// sls decode: decodes every frame of a recording into projector coordinates and depth, and
// writes per frame DIR/frames/NNNNNN/depth.pfm (metres, 0 = invalid) and cloud.ply (points
// with normals and confidence, camera frame), plus DIR/decode.json. When the recording has
// ground truth (sls sim), decode.json holds projector_rms_px, projector_max_px,
// depth_rms_um and valid_fraction (of ground-truth-valid pixels), per frame and in total.
#include <chrono>
#include <filesystem>
#include <iostream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "samples/sls/commands.h"
#include "sdk/core/calibration.h"
#include "sdk/core/device.h"
#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/image_io.h"
#include "sdk/core/ply.h"
#include "sdk/core/recording.h"
#include "sdk/decode/decode_metrics.h"
#include "sdk/decode/decoder.h"
#include "sdk/decode/hdr_fusion.h"

namespace sls::cli {
namespace {

struct DecodeCommandOptions {
  std::string input;
  std::string out;
  std::string device;
  std::string calibration;  // decode with this calibration instead of the recording's
  bool no_clouds = false;
};

nlohmann::json stats_json(const DecodeErrorStats& stats) {
  return {{"projector_rms_px", stats.projector_rms_px()},
          {"projector_max_px", stats.projector_max_px},
          {"depth_rms_um", stats.depth_rms_um()},
          {"depth_max_um", stats.depth_max_m * 1e6},
          {"valid_fraction", stats.valid_fraction()},
          {"compared_pixels", stats.compared},
          {"false_valid_pixels", stats.false_valid}};
}

// The simulator's ground truth of frame `index`, if the recording has it (sls sim layout).
bool load_ground_truth(const RecordingReader& recording, int index, Image32f* u, Image32f* depth, Image8u* valid) {
  const std::string folder = recording.groundtruth_folder();
  if (folder.empty()) return false;
  const std::string frame = fmt::format("{}/frames/{:06d}", folder, index);
  if (!std::filesystem::exists(frame + "/projector_u.pfm")) return false;
  *u = read_pfm(frame + "/projector_u.pfm");
  *depth = read_pfm(frame + "/depth.pfm");
  *valid = read_png_u8(frame + "/valid.png");
  return true;
}

int run_decode(const Context& context, const DecodeCommandOptions& options) {
  const Device device = options.device.empty() ? default_device() : parse_device(options.device);
  // The output is checked before any work, as the scan's is.
  if (path_is_within(options.out, options.input)) {
    throw_error(ErrorCode::kInvalidArgument,
                "--out {} is inside the recording {}: decoding would overwrite it; choose a folder outside it",
                options.out, options.input);
  }
  const RecordingReader recording = RecordingReader::open(options.input);
  ensure_writable_directory(options.out, kFirstOutputsBytes);
  const RecordingInfo& info = recording.info();
  if (info.images_per_frame == 0) {
    throw_error(ErrorCode::kInvalidArgument, "{} is a depth-only recording: there are no pattern images to decode",
                options.input);
  }
  if (options.calibration.empty() && !recording.has_calibration()) {
    throw_error(ErrorCode::kInvalidArgument,
                "{} has no calibration.yml: decoding needs the calibration (give one with --calibration)",
                options.input);
  }
  const ScannerCalibration calibration =
      options.calibration.empty() ? recording.calibration() : read_calibration(options.calibration);
  if (calibration.camera.width != info.camera.width || calibration.camera.height != info.camera.height) {
    throw_error(ErrorCode::kInvalidArgument, "{}: a calibration of a {}x{} camera for {}'s {}x{} images",
                options.calibration, calibration.camera.width, calibration.camera.height, options.input,
                info.camera.width, info.camera.height);
  }
  DecodeOptions decode_options;
  decode_options.bit_depth = info.camera.bit_depth;
  Decoder decoder(pattern_set_from_json(info.pattern_set_json), calibration, device, decode_options);
  const HdrExposures exposures = info.exposures.empty() ? HdrExposures{} : HdrExposures{info.exposures};
  const std::size_t patterns = decoder.pattern_set().size();
  if (exposures.is_hdr() && static_cast<std::size_t>(info.images_per_frame) != patterns * exposures.count()) {
    throw_error(ErrorCode::kFormat, "{}: {} images per frame for {} patterns at {} exposure(s)", options.input,
                info.images_per_frame, patterns, exposures.count());
  }
  create_directories(options.out);

  nlohmann::json frames = nlohmann::json::array();
  DecodeErrorStats total;
  bool has_truth = false;
  double decode_seconds = 0.0;
  std::size_t skipped = 0;
  const ProgressCallback progress = context.progress_callback("decode");
  for (std::size_t i = 0; i < recording.frame_count(); ++i) {
    const FrameInfo& frame = recording.frame(i);
    nlohmann::json entry = {{"index", frame.index}};
    if (!frame.complete) {
      // An incomplete stack (a capture cut short) cannot be decoded: reported, not guessed.
      entry["status"] = "skipped";
      entry["reason"] = "incomplete pattern stack";
      ++skipped;
      frames.push_back(entry);
      continue;
    }
    // A frame that cannot be read (a missing, empty, corrupt or mis-sized image) or decoded (a
    // stack that does not behave as the pattern set says) is reported and skipped, as the
    // scan does; faults of the machine (memory, the GPU) still stop the command.
    DecodedFrame decoded;
    const auto start = std::chrono::steady_clock::now();
    try {
      std::vector<Image16u> images = recording.load_images(i);
      // HDR: the exposures' stacks fused per pixel (sdk/decode/hdr_fusion.h).
      if (exposures.is_hdr()) images = fuse_hdr_stack(images, patterns, exposures, decode_options).images;
      decoded = decoder.decode(images);
    } catch (const Error& error) {
      if (!is_frame_problem(error)) throw;
      entry["status"] = "skipped";
      entry["reason"] = error.what();
      if (!context.options.json) std::cerr << fmt::format("\nframe {} skipped: {}\n", frame.index, error.what());
      ++skipped;
      frames.push_back(entry);
      continue;
    }
    decode_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const std::string folder = fmt::format("{}/frames/{:06d}", options.out, frame.index);
    create_directories(folder);
    write_pfm(folder + "/depth.pfm", decoded.depth_m);
    if (!options.no_clouds) write_ply(folder + "/cloud.ply", depth_to_cloud(decoded, decoder.rays()));
    entry["status"] = "decoded";
    entry["valid_pixels"] = decoded.ok_count();
    Image32f true_u, true_depth;
    Image8u true_valid;
    if (load_ground_truth(recording, frame.index, &true_u, &true_depth, &true_valid)) {
      has_truth = true;
      const DecodeErrorStats stats = compare_with_ground_truth(decoded, true_u, true_depth, true_valid);
      total.accumulate(stats);
      entry["groundtruth"] = stats_json(stats);
    }
    frames.push_back(entry);
    report_progress(progress, {"decode", i + 1, recording.frame_count(), ""});
  }
  const std::size_t decoded_frames = recording.frame_count() - skipped;
  nlohmann::json report = {{"recording", options.input},
                           {"calibration", options.calibration.empty() ? recording.folder() + "/calibration.yml"
                                                                       : options.calibration},
                           {"device", device.to_string()},
                           {"frames_decoded", decoded_frames},
                           {"frames_skipped", skipped},
                           {"decode_ms_per_frame", decoded_frames > 0 ? 1e3 * decode_seconds / static_cast<double>(decoded_frames) : 0.0},
                           {"frames", frames}};
  if (has_truth) {
    const nlohmann::json totals = stats_json(total);
    for (const auto& [key, value] : totals.items()) report[key] = value;
  }
  write_file_atomic(options.out + "/decode.json", report.dump(2));

  nlohmann::json summary = report;
  summary.erase("frames");
  summary["ok"] = true;
  context.emit(summary, [&] {
    std::cout << "decoded " << decoded_frames << " frame(s) of " << options.input << " into " << options.out;
    if (skipped > 0) std::cout << " (" << skipped << " frame(s) skipped: see decode.json)";
    std::cout << "\n";
    if (has_truth) {
      std::cout << fmt::format("against ground truth: projector RMS {:.4f} px (max {:.3f}), depth RMS {:.2f} um, "
                               "valid fraction {:.4f}\n",
                               total.projector_rms_px(), total.projector_max_px, total.depth_rms_um(),
                               total.valid_fraction());
    }
  });
  return kExitOk;
}

}  // namespace

void add_decode_command(CLI::App& app, Context& context, int* exit_code) {
  CLI::App* command = app.add_subcommand(
      "decode", "Decode a recording's pattern stacks into depth maps and clouds (and their error, with ground truth)");
  auto options = std::make_shared<DecodeCommandOptions>();
  command->add_option("--input", options->input, "Recording folder")->required();
  command->add_option("--out", options->out, "Output folder (decode.json, frames/NNNNNN/depth.pfm, cloud.ply)")
      ->required();
  command->add_option("--device", options->device, "cpu, cuda or cuda:N (default: cuda when a GPU is present)");
  command->add_option("--calibration", options->calibration,
                      "Decode with this calibration.yml instead of the recording's (e.g. a new calibration of the head)");
  command->add_flag("--no-clouds", options->no_clouds, "Write depth maps and decode.json only");
  command->callback([&context, exit_code, options] {
    run_command(context, "decode", [&context, options] { return run_decode(context, *options); }, exit_code);
  });
}

}  // namespace sls::cli
