// sls scan: the scan pipeline, from a recording or the built-in simulator, to a model.
// It runs the stages that exist in this build and names the first one that does not;
// it never writes made-up output. Devices given by URI (--camera/--projector/--turntable,
// hardware or sim://) are scanned through the capture sequencer first. With --poses
// groundtruth (simulated recordings) every
// frame is decoded (or its depth map read) and fused with its true pose into one volume
// around the object; --poses track needs the tracker of issue #6.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <optional>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "drivers/device_registry.h"
#include "drivers/sim/sim_recording.h"
#include "fusion/extract.h"
#include "fusion/integrator.h"
#include "fusion/raycaster.h"
#include "samples/sls/commands.h"
#include "sdk/core/device.h"
#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/image_io.h"
#include "sdk/core/ply.h"
#include "sdk/core/recording.h"
#include "sdk/core/trajectory.h"
#include "sdk/decode/decoder.h"
#include "sdk/session/capture_sequencer.h"

namespace sls::cli {
namespace {

struct ScanOptions {
  std::string input;
  std::string sim_preset;
  std::string camera_uri;      // devices by URI (sls devices lists them): capture through the sequencer
  std::string projector_uri;
  std::string turntable_uri;
  std::string calibration;     // calibration.yml of those devices, stored in the recording
  std::string object = "knurled-screw";
  int frames = 0;
  std::string out;
  std::string device = "cuda";
  std::string fusion = "gtsdf";
  std::string poses = "track";
  double voxel_um = 0.0;          // 0: twice the camera's pixel footprint, grown to fit max_voxels
  double max_voxels_million = 0;  // 0: 256 on a GPU, 48 on the CPU
  bool device_given = false;
};

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// The volume around the object: the bounding box of the ground truth's reference surface
// plus a margin of the integration band, at the requested (or automatic) voxel size.
fusion::VolumeGeometry object_volume(const RecordingReader& recording, const ScanOptions& options,
                                     const Device& device, const fusion::IntegrationOptions& fusion_options) {
  const std::string reference_path = recording.groundtruth_folder() + "/reference.ply";
  if (!std::filesystem::exists(reference_path)) {
    throw_error(ErrorCode::kInvalidArgument, "{} has no ground-truth reference.ply to place the volume around",
                recording.folder());
  }
  const PointCloud reference = read_ply_cloud(reference_path);
  if (reference.empty()) throw_error(ErrorCode::kFormat, "{} holds no points", reference_path);
  Eigen::Vector3d lo = reference.positions[0].cast<double>(), hi = lo;
  for (const Eigen::Vector3f& p : reference.positions) {
    lo = lo.cwiseMin(p.cast<double>());
    hi = hi.cwiseMax(p.cast<double>());
  }
  const CameraIntrinsics& camera = recording.calibration().camera;
  double voxel = options.voxel_um * 1e-6;
  if (voxel <= 0.0) {
    // Twice the pixel footprint at the working distance (the median depth is ~ the focus).
    const double working_distance = 0.1;
    voxel = 2.0 * working_distance / camera.fx;
  }
  const double budget = (options.max_voxels_million > 0.0 ? options.max_voxels_million
                                                          : (device.is_cuda() ? 256.0 : 48.0)) * 1e6;
  for (;;) {
    const double margin = (fusion_options.eta_voxels + 2.0) * voxel;
    const Eigen::Vector3d size = (hi - lo).array() + 2.0 * margin;
    const Eigen::Vector3i counts = (size / voxel).array().ceil().cast<int>();
    const double total = static_cast<double>(counts.x()) * counts.y() * counts.z();
    if (total <= budget || options.voxel_um > 0.0) {
      return fusion::VolumeGeometry::centred(0.5 * (lo + hi), counts.x(), counts.y(), counts.z(), voxel);
    }
    voxel *= std::cbrt(total / budget) * 1.001;
  }
}

// Fuses every frame with its ground-truth pose and writes the model; returns the report.
nlohmann::json fuse_with_groundtruth(const Context& context, const RecordingReader& recording,
                                     const ScanOptions& options, const Device& device) {
  const std::string trajectory_path = recording.groundtruth_folder() + "/trajectory.txt";
  if (!std::filesystem::exists(trajectory_path)) {
    throw_error(ErrorCode::kInvalidArgument,
                "--poses groundtruth: {} has no ground-truth trajectory (only simulated recordings do)",
                recording.folder());
  }
  const std::vector<StampedPose> truth = read_tum_trajectory(trajectory_path);
  if (truth.size() != recording.frame_count()) {
    throw_error(ErrorCode::kFormat, "{}: {} poses for {} frames", trajectory_path, truth.size(),
                recording.frame_count());
  }
  const RecordingInfo& info = recording.info();
  const CameraIntrinsics& camera = recording.calibration().camera;
  const fusion::IntegrationOptions fusion_options = fusion::parse_fusion_method(options.fusion);
  const fusion::VolumeGeometry geometry = object_volume(recording, options, device, fusion_options);
  fusion::Volume volume(geometry, fusion::VoxelFormat::kCompact, device);
  fusion::Integrator integrator(device, fusion_options);
  if (!context.options.json) {
    std::cerr << fmt::format("volume {} x {} x {} voxels of {:.1f} um ({:.0f} MiB, {}), {} fusion on {}\n",
                             geometry.nx, geometry.ny, geometry.nz, geometry.voxel_size_m * 1e6,
                             static_cast<double>(volume.bytes()) / 1048576.0,
                             fusion::voxel_format_name(volume.format()), options.fusion, device.to_string());
  }

  std::optional<Decoder> decoder;
  if (info.images_per_frame > 0) {
    DecodeOptions decode_options;
    decode_options.bit_depth = info.camera.bit_depth;
    decoder.emplace(pattern_set_from_json(info.pattern_set_json), recording.calibration(), device, decode_options);
  }
  double decode_ms = 0.0, integrate_ms = 0.0, read_ms = 0.0;
  nlohmann::json skipped = nlohmann::json::array();
  std::vector<StampedPose> used;
  std::size_t active = 0;
  const ProgressCallback progress = context.progress_callback("fuse");
  for (std::size_t i = 0; i < recording.frame_count(); ++i) {
    report_progress(progress, {"fuse", i, recording.frame_count(), ""});
    Image32f depth;
    try {
      if (decoder) {
        if (!recording.frame(i).complete) throw_error(ErrorCode::kFormat, "incomplete pattern stack");
        auto start = Clock::now();
        const std::vector<Image16u> images = recording.load_images(i);
        read_ms += ms_since(start);
        start = Clock::now();
        depth = decoder->decode(images).depth_m;
        decode_ms += ms_since(start);
      } else {
        const auto start = Clock::now();
        std::optional<Image32f> map = recording.load_depth_m(i);
        read_ms += ms_since(start);
        if (!map) throw_error(ErrorCode::kFormat, "no depth map");
        depth = std::move(*map);
      }
    } catch (const Error& error) {
      // A bad frame is reported and skipped; the frames fused so far are kept.
      skipped.push_back({{"frame", i}, {"reason", error.what()}});
      continue;
    }
    const auto start = Clock::now();
    active += integrator.integrate(volume, depth, camera, truth[i].T_world_camera).active_voxels;
    integrate_ms += ms_since(start);
    used.push_back(truth[i]);
  }
  report_progress(progress, {"fuse", recording.frame_count(), recording.frame_count(), ""});

  auto start = Clock::now();
  const fusion::Volume on_host = volume.to_host();
  const fusion::ExtractedSurface surface = fusion::extract_surface(on_host);
  const PointCloud& cloud = surface.cloud;
  const TriangleMesh& mesh = surface.mesh;
  const double extract_ms = ms_since(start);
  std::filesystem::create_directories(options.out);
  // A shaded picture of the model seen from the first fused view, with the camera's own
  // model (render.png): the fused surface at the scanner's resolution.
  if (!used.empty()) {
    fusion::RaycastOptions raycast_options;
    raycast_options.truncation_voxels = fusion_options.truncation_voxels;
    fusion::Raycaster raycaster(device, camera, raycast_options);
    write_png(options.out + "/render.png", raycaster.raycast(volume, used.front().T_world_camera).shaded);
  }
  write_ply(options.out + "/cloud.ply", cloud);
  write_ply(options.out + "/mesh.ply", mesh);
  write_tum_trajectory(options.out + "/trajectory.txt", used);

  nlohmann::json report;
  report["format"] = "slscan-scan-report";
  report["format_version"] = 1;
  report["input"] = recording.folder();
  report["device"] = device.to_string();
  report["poses"] = "groundtruth";
  report["fusion"] = {{"method", options.fusion},
                      {"truncation_voxels", fusion_options.truncation_voxels},
                      {"eta_voxels", fusion_options.eta_voxels},
                      {"weight_max", fusion_options.weight_max},
                      {"lambda", fusion_options.lambda},
                      {"beta", fusion_options.beta},
                      {"kappa", fusion_options.kappa},
                      {"penalty", fusion::penalty_name(fusion_options.penalty)},
                      {"iterations", fusion_options.iterations}};
  report["voxel_size_m"] = geometry.voxel_size_m;
  report["volume"] = {{"voxels", {geometry.nx, geometry.ny, geometry.nz}},
                      {"format", fusion::voxel_format_name(volume.format())},
                      {"bytes", volume.bytes()}};
  report["frames"] = recording.frame_count();
  report["frames_fused"] = used.size();
  report["lost_frames"] = skipped;
  report["active_voxels_per_frame"] = used.empty() ? 0.0 : static_cast<double>(active) / static_cast<double>(used.size());
  report["ms_per_stage"] = {{"read", read_ms}, {"decode", decode_ms}, {"integrate", integrate_ms},
                            {"extract", extract_ms}};
  report["points"] = cloud.size();
  report["triangles"] = mesh.faces.size();
  report["outputs"] = {{"cloud", options.out + "/cloud.ply"}, {"mesh", options.out + "/mesh.ply"},
                       {"render", options.out + "/render.png"},
                       {"trajectory", options.out + "/trajectory.txt"}, {"report", options.out + "/report.json"}};
  write_file_atomic(options.out + "/report.json", report.dump(2) + "\n");
  return report;
}

int run_scan(const Context& context, const ScanOptions& options) {
  // An explicit --device cuda without a GPU is an error, not a silent fallback.
  const Device device = options.device_given ? parse_device(options.device) : default_device();
  require_device(device);

  std::string input = options.input;
  if (!options.camera_uri.empty()) {
    // Devices by URI (hardware or sim://): the capture sequencer scans into OUT/recording,
    // appending every stack as it arrives, so an interrupted scan keeps what it captured.
    if (options.projector_uri.empty()) {
      throw_error(ErrorCode::kInvalidArgument, "--camera needs --projector (the device that shows the patterns)");
    }
    drivers::OpenOptions open_options;
    open_options.sim_device = device;
    const std::unique_ptr<drivers::Projector> projector = drivers::open_projector(options.projector_uri, open_options);
    const std::unique_ptr<drivers::Camera> camera = drivers::open_camera(options.camera_uri, open_options);
    const std::unique_ptr<drivers::Turntable> turntable =
        options.turntable_uri.empty() ? nullptr : drivers::open_turntable(options.turntable_uri, open_options);
    GrayPhaseOptions pattern_options;
    pattern_options.projector_width = projector->info().width;
    pattern_options.projector_height = projector->info().height;
    const PatternSet patterns = make_gray_phase_pattern_set(pattern_options);
    std::optional<ScannerCalibration> calibration;
    if (!options.calibration.empty()) calibration = read_calibration(options.calibration);
    session::CaptureOptions capture;
    capture.frames_per_revolution = options.frames > 0 ? options.frames : (turntable ? 36 : 1);
    capture.frames = capture.frames_per_revolution;
    session::CaptureSequencer sequencer(*projector, {camera.get()}, turntable.get(), patterns, capture);
    input = options.out + "/recording";
    RecordingWriter writer =
        RecordingWriter::create(input, session::make_recording_info(*projector, *camera, patterns), calibration);
    const session::CaptureStatistics stats = sequencer.run({&writer}, {}, context.progress_callback("capture"));
    if (!context.options.json) {
      std::cerr << fmt::format("captured {} frame(s) ({} incomplete, {} re-captured stacks) x {} images from {} into {}\n",
                               stats.frames, stats.incomplete_frames, stats.retries, patterns.size(),
                               options.camera_uri, input);
    }
    if (!calibration) {
      throw_error(ErrorCode::kInvalidArgument,
                  "captured {} frame(s) into {}; without --calibration they cannot be decoded (the recording is kept)",
                  stats.frames, input);
    }
  } else if (!options.sim_preset.empty()) {
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
  if (options.poses == "groundtruth") {
    const nlohmann::json report = fuse_with_groundtruth(context, recording, options, device);
    if (context.options.json) {
      std::cout << report.dump(2) << "\n";
    } else {
      std::cout << fmt::format("fused {} of {} frames: {} points, {} triangles\n  {}\n  {}\n  {}\n",
                               report["frames_fused"].get<std::size_t>(), report["frames"].get<std::size_t>(),
                               report["points"].get<std::size_t>(), report["triangles"].get<std::size_t>(),
                               report["outputs"]["cloud"].get<std::string>(),
                               report["outputs"]["mesh"].get<std::string>(),
                               report["outputs"]["report"].get<std::string>());
    }
    return 0;
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
              "{}; the tracker (--poses track) is not in this build yet, so no trajectory, cloud or mesh can be "
              "made. Missing stage: tracking. A simulated recording can be fused with --poses groundtruth.",
              done);
}

}  // namespace

void add_scan_command(CLI::App& app, Context& context, int* exit_code) {
  CLI::App* command = app.add_subcommand("scan", "Scan an object: recording or simulator -> decode -> track -> fuse -> model");
  auto options = std::make_shared<ScanOptions>();
  auto* input = command->add_option("--input", options->input, "Recording folder to scan");
  auto* sim = command->add_option("--sim", options->sim_preset, "Scan the simulated scanner with this preset")
                  ->check(CLI::IsMember({"ci", "demo", "paper"}));
  auto* camera = command->add_option("--camera", options->camera_uri,
                                     "Scan with devices by URI (see `sls devices`): the camera, e.g. gige://192.168.1.20");
  command->add_option("--projector", options->projector_uri, "With --camera: the projector, e.g. dlpc350://");
  command->add_option("--turntable", options->turntable_uri, "With --camera: the turntable, e.g. headctl://");
  command->add_option("--calibration", options->calibration, "With --camera: calibration.yml of these devices");
  input->excludes(sim);
  sim->excludes(input);
  camera->excludes(input);
  camera->excludes(sim);
  command->add_option("--object", options->object, "Simulated object (with --sim)")
      ->check(CLI::IsMember({"knurled-screw", "knurled-knob", "chessboard", "plane", "sphere"}))
      ->capture_default_str();
  command->add_option("--frames", options->frames,
                      "Frames per revolution (--sim: 0 is the preset's; --camera: 0 is 36 with a turntable, else 1)")
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
  command->add_option("--voxel-um", options->voxel_um,
                      "Voxel size in um (0: twice the pixel footprint, grown to fit --max-voxels)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  command->add_option("--max-voxels", options->max_voxels_million,
                      "Largest volume in millions of voxels for the automatic voxel size (0: 256 on a GPU, 48 on the CPU)")
      ->check(CLI::NonNegativeNumber);
  command->callback([&context, exit_code, options, command] {
    run_command(context, "scan", [&context, options, command] {
      if (options->input.empty() && options->sim_preset.empty() && options->camera_uri.empty()) {
        throw_error(ErrorCode::kInvalidArgument, "give --input REC, --sim PRESET or --camera URI --projector URI");
      }
      options->device_given = command->count("--device") > 0;
      return run_scan(context, *options);
    }, exit_code);
  });
}

}  // namespace sls::cli
