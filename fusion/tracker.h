// Frame-to-model tracking (paper section II, DESIGN.md section 3): KinectFusion projective ICP,
// point-to-plane, coarse to fine over a pyramid of the live depth map, against the model's
// vertex and normal maps raycast from the previous pose. Each Gauss–Newton step reduces the
// 6x6 normal equations over all pixels (on the GPU for a CUDA tracker; one per-pixel body in
// track_shared.h for both backends) and solves them on the host.
//
//   Tracker tracker(Device::cuda(), camera, TrackingOptions{});
//   raycaster.raycast(volume, T_world_model)                       -> model (camera frame of T_world_model)
//   TrackingResult r = tracker.track(depth_m, model, T_world_model, T_world_camera_guess);
//   if (!r.lost) integrate with r.T_world_camera;
//
// Live pixels at every level associate against the finest model maps (projected with the
// full camera model); the update is a left increment of T_model_live about the model points'
// centroid with the rotation scaled by their RMS radius (track_shared.h), so the eigenvalues
// compared for degeneracy share units. Solved on the host in double.
//
// Degenerate geometry (a cylinder slides along its axis, a plane in three directions) leaves
// directions of the 6x6 system unconstrained: those directions keep the guess (the prior) and
// are counted in TrackingResult::degenerate_directions; they do not make a frame lost.
// A frame is lost when too few pixels match, the residual stays large, or the motion the ICP
// wants is implausibly large: the result then carries the guess and `reason`.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "fusion/raycaster.h"
#include "sdk/core/camera_model_shared.h"
#include "sdk/core/device.h"
#include "sdk/core/image.h"
#include "sdk/core/pose.h"

namespace sls::fusion {

struct TrackingOptions {
  // Gauss–Newton iterations per pyramid level, finest first (level l halves the size l times).
  std::vector<int> iterations = {4, 4, 6};
  // Projective association: a pair is kept when the points are closer than this and their
  // normals agree within max_normal_angle_deg (distance in metres at the finest level; it
  // doubles per coarser level).
  double max_distance_m = 200e-6;
  double max_normal_angle_deg = 30.0;
  // Live normals from differences over about this much surface (see track_shared.h's
  // live_normal): 30 µm is one pixel of the ci preset, ten of the paper's 3 µm pixels.
  double normal_baseline_m = 30e-6;
  // Stop a level early when the update is smaller than these.
  double min_translation_step_m = 0.05e-6;
  double min_rotation_step_rad = 1e-7;
  // Directions whose eigenvalue of the normal matrix (in the scaled form below) is below this
  // fraction of the largest are degenerate: they keep the guess. 1 %: a straight-knurled
  // screw seen from its side (a cylinder with ridges along its axis) pins sliding along the
  // axis only through noise and the view's rim (eigenvalue ratios of 1e-4 .. 2e-3 measured);
  // left free, the noise walks the pose along the axis by tens of µm a frame and the
  // constant-velocity guess carries the walk on. A ridged knob with a wave pattern: ~0.07.
  double degenerate_eigen_ratio = 1e-2;
  // ICP's finest level: the live camera halved until its width is at most this; the model
  // maps are raycast at that size (model_camera()). Halving a 4000 x 3000 camera quarters the
  // raycast (12.3 -> 3.7 ms on an H200) but, measured over the paper-size revolution of the
  // knurled knob, multiplies the loop-closure drift by 25 (10 µm -> 263 µm): full resolution
  // by default.
  int max_model_width = 4096;
  // Robust weights: Huber's, at this many times the previous reduction's residual RMS (the
  // first reduction of a frame is plain least squares); 0 turns them off.
  double huber_rms_factor = 2.0;
  // Lost-frame tests (after the finest level).
  double min_inlier_fraction = 0.25;    // of the live pixels with a depth
  double max_residual_rms_m = 60e-6;    // point-to-plane RMS of the inliers
  double max_correction_m = 3e-3;       // how far the result moves the model's centroid in view from the guess
  double max_correction_deg = 10.0;
  // Throws sls::Error(kInvalidArgument) naming the bad value.
  void validate() const;
};

struct TrackingResult {
  Pose T_world_camera;          // the registered pose (the guess when lost)
  bool lost = false;
  std::string reason;           // why it is lost (empty otherwise)
  std::size_t live_pixels = 0;  // finest level pixels with a depth
  std::size_t inliers = 0;      // of those, matched at the last iteration
  double inlier_fraction = 0.0;
  double residual_rms_m = 0.0;  // point-to-plane RMS of the inliers, finest level
  double condition = 0.0;       // largest / smallest eigenvalue of the last normal matrix (finest
                                //  level, scaled parameterisation; infinity when singular)
  int degenerate_directions = 0;
  int iterations = 0;           // Gauss–Newton steps taken over all levels
};

class Tracker {
 public:
  // camera: the live depth map's camera (ICP's finest level is it, halved to max_model_width).
  Tracker(const Device& device, const CameraIntrinsics& camera, const TrackingOptions& options = {});
  ~Tracker();
  Tracker(Tracker&&) noexcept;
  Tracker& operator=(Tracker&&) noexcept;

  const TrackingOptions& options() const;
  const Device& device() const;
  // The camera the model maps must be raycast with (the live camera at ICP's finest level).
  const CameraIntrinsics& model_camera() const;

  // Registers a live depth map (camera-frame z in metres, 0 = none, the camera's size) to the
  // model seen from T_world_model (a raycast from that pose with model_camera()), starting
  // from T_world_camera_guess. sls::Error(kInvalidArgument) for maps of another size.
  TrackingResult track(const Image32f& depth_m, const RaycastResult& model, const Pose& T_world_model,
                       const Pose& T_world_camera_guess);
#if defined(SLS_HAVE_CUDA)
  // Both on the GPU: the live depth map (the decoder's output, width x height floats, complete
  // when called: synchronize its stream first) and the model in `raycaster` (a CUDA raycaster
  // with the tracker's camera) after raycast_device(volume, T_world_model); the raycaster's
  // stream is synchronized here. No allocation: the pyramid lives in buffers made once.
  TrackingResult track_device(const float* depth_device, Raycaster& raycaster, const Pose& T_world_model,
                              const Pose& T_world_camera_guess);
#endif

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sls::fusion
