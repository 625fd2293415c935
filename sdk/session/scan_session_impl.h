// The scan session's state (scan_session.h), shared by its two sources: scan_session.cpp
// (the frame loop) and scan_session_deformation.cpp (online deformation's results: the
// deformed model and trajectory, the loop closure). Internal to sdk/session.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "sdk/core/gpu_stream.h"
#include "sdk/session/scan_session.h"


namespace sls::session {

// The median of the valid depths (the focus distance of a first frame).
double median_depth(const Image32f& depth_m);

// A CUDA session's streams, made once and handed down to every stage (issue 18); none on the CPU.
struct SessionStreams {
  GpuStream frame;   // a frame's decode, tracking, integration and raycast, and the volume's resampling, in order
  GpuStream upload;  // the next pattern stack's upload, beside the frame before it
  GpuStream ship;    // a move's shipping, beside the frame loop
  explicit SessionStreams(const Device& device)
      : frame(GpuStream::create(device)), upload(GpuStream::create(device)), ship(GpuStream::create(device)) {}
};

struct ScanSession::Impl {
  ScannerCalibration calibration;
  ScanSessionOptions options;
  SessionStreams streams;
  std::optional<Decoder> decoder;
  // Each frame is decoded into these same images (a 12-megapixel frame's depth and confidence
  // are 96 MB: fresh memory every frame costs page faults and zeroing). Valid for the frame
  // being processed; nothing keeps a pointer into them past it.
  DecodedFrame decoded;
  // The rows of a GPU's depth map a keyframe's samples read, page-locked (~2 MB at 12 MP; the
  // whole map page-locked took 16 ms to allocate, at the first keyframe).
  Image32f depth_rows{MemoryType::kPinned};
  fusion::Integrator integrator;
  fusion::Tracker tracker;
  fusion::Raycaster raycaster;
  std::optional<fusion::MovingVolume> moving;
  std::optional<fusion::Volume> fixed;

  bool have_model = false;                 // a fused frame exists (and the model was raycast)
  Pose T_world_model;                      // the pose the model was last raycast from
  // The model maps raycast from T_world_model, where the tracker reads them (on a GPU there).
  fusion::RaycastResult model;
  // The last two fused frames: the constant-velocity prior.
  struct Fused {
    int index = 0;
    Pose T_world_camera;
    std::optional<double> angle_deg;
  };
  std::optional<Fused> last, before_last;
  std::optional<Fused> first;              // the first fused frame (the loop closure's reference)
  // RevisitPolicy: the fused poses' rotation summed frame to frame, how far the scan turned (the
  // turntable's angle when the frames have one), and the frame merging began at.
  double rotation_travelled_deg = 0.0;
  double turned_deg = 0.0;
  std::optional<int> revisits_merged_from;
  // After a frame is fused at T_world_camera: counts the turn, and merges revisits once the
  // policy says so (RevisitPolicy::kAfterFirstRevolution).
  void count_turn(int frame, const Pose& T_world_camera, std::optional<double> angle_deg);
  // Whether the scan has turned a revolution and one move's rotation (moving.max_rotation_deg):
  // where revisits start to merge (kAfterFirstRevolution) and the graph stops growing
  // (DeformationOptions::first_revolution_only).
  bool past_first_revolution() const { return turned_deg >= 360.0 + options.moving.max_rotation_deg; }

  // Online deformation (scan_deformation.h): made with the moving volume.
  std::unique_ptr<ScanDeformation> deformation;
  double focus_distance_m = 0.0;           // the moving volume's (a pose's focus point)
  bool gpu_budget_shrank_volume = false;   // max_gpu_bytes made the volume's extent smaller
  // Where each shipped part ends in the moving volume's shipped cloud and mesh, and the last
  // frame it was observed in (the frame before the move): what the map deformation binds by.
  struct ShippedPart {
    int time = 0;
    std::size_t cloud_end = 0;
    std::size_t mesh_vertex_end = 0;
  };
  std::vector<ShippedPart> parts;
  // The loop closure's reference: the model seen from the first pose, raycast before the
  // volume first moves away from it (where the model maps live).
  bool reference_taken = false;
  fusion::RaycastResult reference_model;
  fusion::VolumeGeometry reference_volume;  // the volume it was raycast from
  // The last loop_frames fused frames (a ring, oldest overwritten): what close_loop()
  // registers to the first frame's surface. Copies of their depth and the decoder's confidence
  // where the maps were (the decoder's images hold the next frame by then): on a GPU there,
  // reusing the slot's memory.
  struct LoopFrame {
    int index = -1;                    // -1: an empty slot
    Pose T_world_camera;
    std::optional<double> angle_deg;
    Image32f depth;
    Image32f confidence;               // empty: none
  };
  std::vector<LoopFrame> loop_frames;
  std::size_t loop_frames_next = 0;
  void keep_loop_frame(int frame, const Pose& T_world_camera, std::optional<double> angle_deg, FrameMaps& maps);
  std::optional<LoopClosureReport> loop;

  std::vector<FrameReport> frames;
  ScanSession::FrameObserver frame_observer;  // set_frame_observer()
  StageTimes totals;
  Image32f depth_upload{MemoryType::kDevice};  // a depth-map frame on the GPU (decoded frames stay there)
  Image32f texture_on_device{MemoryType::kDevice};  // the frame's texture (photometric term), uploaded once

  Impl(const ScannerCalibration& calibration_in, const ScanSessionOptions& options_in)
      : calibration(calibration_in),
        options(options_in),
        streams(options_in.device),
        integrator(options_in.device, options_in.integration, streams.frame),
        tracker(options_in.device, calibration_in.camera, options_in.tracking, streams.frame),
        raycaster(options_in.device, tracker.model_camera(), raycast_options(options_in), streams.frame),
        model(maps_memory(options_in.device)),
        reference_model(maps_memory(options_in.device)) {}

  // Where the stages' maps live: on the session's GPU, else the host.
  static MemoryType maps_memory(const Device& device) {
    return device.is_cuda() ? MemoryType::kDevice : MemoryType::kHost;
  }

  static fusion::RaycastOptions raycast_options(const ScanSessionOptions& options) {
    fusion::RaycastOptions raycast;
    raycast.truncation_voxels = options.integration.truncation_voxels;
    raycast.min_depth_m = options.decode.min_depth_m;
    raycast.max_depth_m = options.decode.max_depth_m;
    return raycast;
  }

  fusion::Volume* volume() {
    if (fixed) return &*fixed;
    return moving ? &moving->volume() : nullptr;
  }
  const fusion::Volume* volume() const {
    if (fixed) return &*fixed;
    return moving ? &moving->volume() : nullptr;
  }

  // The pose guess for a frame: the turntable's angle about its calibrated axis when asked
  // and known, else constant velocity from the last two fused frames.
  Pose predict(const ScanFrame& frame) const {
    const Pose& base = last->T_world_camera;
    if (options.turntable_prior && calibration.turntable && frame.turntable_angle_deg && last->angle_deg) {
      return base * turntable_camera_motion(*calibration.turntable, *frame.turntable_angle_deg - *last->angle_deg);
    }
    if (!before_last) return base;
    const Pose step = before_last->T_world_camera.inverse() * base;
    const double frames_between = static_cast<double>(last->index - before_last->index);
    const double frames_ahead = static_cast<double>(frame.index - last->index);
    if (!(frames_between > 0.0) || !(frames_ahead > 0.0)) return base;
    return base * Pose::exp(step.log() * (frames_ahead / frames_between));
  }

  // The turntable's motion as a pose prior (fusion/pose_prior.h) for a camera the table turned
  // from T_world_reference to T_world_expected (turntable_camera_motion of the two recorded
  // angles): its rotation about the axis with σ √2 · the table's angle repeatability, about
  // the axes across it with √2 · its tilt σ (the difference of two positions; a σ of 0 is
  // taken as 1e-6°: the table then decides that rotation; one the calibration lacks leaves
  // that rotation to the surface). nullopt without the prior, an axis or either σ.
  std::optional<fusion::PosePrior> turntable_pose_prior(const Pose& T_world_reference,
                                                        const Pose& T_world_expected) const {
    if (!options.turntable_prior || !calibration.turntable) return std::nullopt;
    const TurntableAxis& axis = *calibration.turntable;
    if (!axis.angle_sigma_deg && !axis.tilt_sigma_deg) return std::nullopt;
    const auto sigma_rad = [](const std::optional<double>& sigma_deg) {
      return sigma_deg ? std::sqrt(2.0) * std::max(*sigma_deg, 1e-6) * M_PI / 180.0 : fusion::PosePrior::kNone;
    };
    fusion::PosePrior prior;
    prior.T_world_camera = T_world_expected;
    prior.axis_world = (T_world_reference.rotation() * axis.direction_camera).normalized();
    prior.sigma_rad = sigma_rad(axis.angle_sigma_deg);
    prior.tilt_sigma_rad = sigma_rad(axis.tilt_sigma_deg);
    return prior;
  }

  // Whether predict() gives the turntable's pose for this frame.
  bool turntable_guess(const ScanFrame& frame) const {
    return options.turntable_prior && calibration.turntable && frame.turntable_angle_deg && last && last->angle_deg;
  }

  // How far (degrees) the rotation from the last fused frame to `T_world_camera` differs from
  // the turntable's between the two, and the turntable's step; nullopt without angles or axis.
  std::optional<std::pair<double, double>> turntable_disagreement_deg(const ScanFrame& frame,
                                                                     const Pose& T_world_camera) const {
    if (!calibration.turntable || !frame.turntable_angle_deg || !last || !last->angle_deg) return std::nullopt;
    const double step_deg = *frame.turntable_angle_deg - *last->angle_deg;
    const Pose expected = turntable_camera_motion(*calibration.turntable, step_deg);
    const Pose tracked = last->T_world_camera.inverse() * T_world_camera;
    return std::pair{(expected.inverse() * tracked).angle_rad() * 180.0 / M_PI, step_deg};
  }

  // What a CUDA session still allocates after placing its volume (kGpuBytesPerPixelAfterPlacement).
  double gpu_bytes_after_placement() const {
    return kGpuBytesPerPixelAfterPlacement * static_cast<double>(calibration.camera.width) *
           static_cast<double>(calibration.camera.height);
  }
  double gpu_budget_voxels() const {
    return session::gpu_budget_voxels(options, static_cast<double>(gpu_allocations().in_use_bytes),
                                      gpu_bytes_after_placement());
  }

  void place_volume(const Pose& T_world_camera, FrameMaps& maps) {
    if (options.fixed_volume) {
      if (!fixed) {
        fixed.emplace(*options.fixed_volume, options.voxel_format, options.device, options.integration.average_storage());
      }
      return;
    }
    if (moving) return;
    fusion::MovingVolumeOptions moving_options = options.moving;
    if (options.revisits == RevisitPolicy::kMerge) moving_options.merge_revisits = true;
    if (!(moving_options.focus_distance_m > 0.0)) moving_options.focus_distance_m = median_depth(*maps.host_depth());
    // On a GPU a move's surface is shipped beside the frame loop (collect_ship()).
    moving_options.ship_in_background = options.ship_in_background && options.device.is_cuda();
    const double focus = moving_options.focus_distance_m;
    const CameraIntrinsics& camera = calibration.camera;
    Eigen::Vector3d size = options.volume_size_m;
    if (!(size.minCoeff() > 0.0)) {
      const double width = camera.width / camera.fx * focus, height = camera.height / camera.fy * focus;
      size = Eigen::Vector3d(width, height, 0.5 * width);
    }
    double voxel = options.voxel_size_m;
    const double budget_voxels = gpu_budget_voxels();
    const auto refuse = [&](const std::string& volume) {
      throw_error(ErrorCode::kOutOfMemory,
                  "a GPU memory budget of {:.2f} GB leaves room for {:.1f} million voxels a buffer ({:.2f} GB held "
                  "already, {:.2f} GB kept for the frames' buffers, two buffers of {} bytes a voxel){}, under the 64 "
                  "a side a scan needs; raise the budget or the voxel size",
                  options.max_gpu_bytes * 1e-9, budget_voxels * 1e-6,
                  static_cast<double>(gpu_allocations().in_use_bytes) * 1e-9, gpu_bytes_after_placement() * 1e-9,
                  fusion::bytes_per_voxel(options.voxel_format, options.integration.average_storage()), volume);
    };
    if (budget_voxels < 64.0 * 64.0 * 64.0) refuse("");
    if (!(voxel > 0.0)) {
      voxel = 2.0 * focus / camera.fx;
      const double voxels = (size / voxel).prod();
      const double most = std::min(options.max_voxels, budget_voxels);
      if (voxels > most) voxel *= std::cbrt(voxels / most) * 1.001;
    }
    Eigen::Vector3i counts = (size / voxel).array().ceil().cast<int>().cwiseMax(2);
    if (counts.cast<double>().prod() > budget_voxels) {
      // A given voxel size keeps its size under the budget: the extent shrinks.
      const double scale = std::cbrt(budget_voxels / counts.cast<double>().prod());
      counts = (counts.cast<double>() * scale).array().floor().cast<int>();
      gpu_budget_shrank_volume = true;
      if (counts.minCoeff() < 64) {
        refuse(fmt::format(": a volume of {}x{}x{} voxels of {:.1f} um", counts.x(), counts.y(), counts.z(),
                           voxel * 1e6));
      }
    }
    moving.emplace(counts.x(), counts.y(), counts.z(), voxel, options.voxel_format, options.device, moving_options,
                   options.integration.average_storage(), streams.frame, streams.ship);
    moving->place(T_world_camera);
    focus_distance_m = focus;
    if (options.deformation.enabled) {
      const Eigen::Vector3d extent = moving->volume().geometry().size_m();
      const DeformationOptions& d = options.deformation;
      const double spacing = d.node_spacing_m > 0.0 ? d.node_spacing_m : 0.25 * extent.minCoeff();
      const double region = d.region_radius_m > 0.0 ? d.region_radius_m : 0.5 * extent.maxCoeff();
      deformation = std::make_unique<ScanDeformation>(d, spacing, region, voxel);
    }
  }

  // Online deformation's share of a fused frame (scan_session_deformation.cpp): the reference
  // raycast, a shipped part recorded and queued, the last frame kept, a keyframe queued.
  void capture_reference(const fusion::Volume& volume);
  // graph_grows(): whether a part shipped now joins the graph, decided at its move.
  bool graph_grows() const;
  void record_shipped(int time, std::size_t shipped_before, bool graph_grows);
  // A move shipping in the background (GPU): the frame its part is recorded under, the
  // shipped cloud's size before it and the keyframes queued since. collect_ship() waits for
  // it, records it (with online deformation) and returns its figures (nullopt when none is
  // pending). The frame loop collects it before the next move, and before a keyframe that
  // could match it (ship_matchable_by_next_keyframe): until then the part's place in the
  // worker's queue changes nothing of what the worker computes, as a shipped part binds to the
  // nodes made up to its time whenever it comes, and only parts revisit_gap_nodes older than a
  // keyframe are matched. So the frame loop waits for a ship only where the result needs it.
  struct PendingShip {
    int time = 0;
    std::size_t shipped_before = 0;
    bool graph_grows = true;
    int keyframes = 0;
  };
  std::optional<PendingShip> pending_ship;
  std::optional<fusion::MoveStats> collect_ship();
  bool ship_matchable_by_next_keyframe() const;
  // The turntable's prior on a keyframe node's rotation (scan_session_deformation.cpp);
  // nullopt unless the table's angles, axis and σ are known and used.
  std::optional<fusion::deformation::RotationPrior> turntable_rotation_prior(const Pose& T_world_camera,
                                                                             std::optional<double> angle_deg) const;
  FrameDeformation feed_deformation(int frame, const Pose& T_world_camera, std::optional<double> angle_deg,
                                    FrameMaps& maps);
  // A keyframe (node and samples) or the frame's turntable prior, into the graph.
  void add_to_graph(int frame, const Pose& T_world_camera, std::optional<double> angle_deg, FrameMaps& maps,
                    FrameDeformation* out);
  // The model (shipped parts and the current volume), deformed or not.
  fusion::ExtractedSurface surface(bool deformed, ModelTimes* times = nullptr) const;

  // A keyframe's samples of its depth map (and the loop closure's), made at the first keyframe.
  std::optional<DepthMapSampler> depth_sampler;
  const DepthMapSampler& keyframe_sampler() {
    if (!depth_sampler) depth_sampler.emplace(calibration.camera, options.deformation.keyframe_samples);
    return *depth_sampler;
  }

  Eigen::Vector3d focus_point(const Pose& T_world_camera) const {
    return T_world_camera * Eigen::Vector3d(0.0, 0.0, focus_distance_m);
  }
};

}  // namespace sls::session
