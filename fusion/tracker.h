// Frame-to-model tracking (paper section II, DESIGN.md section 3): KinectFusion projective ICP,
// point-to-plane, coarse to fine over a pyramid of the live depth map, against the model's
// vertex and normal maps raycast from the previous pose. Each Gauss–Newton step reduces the
// 6x6 normal equations over all pixels (on the GPU for a CUDA tracker; one per-pixel body in
// track_shared.h for both backends) and solves them on the host.
//
//   Tracker tracker(Device::cuda(), camera, TrackingOptions{});
//   RaycastResult model(MemoryType::kDevice);                      // (kHost for a CPU tracker)
//   raycaster.raycast(volume, T_world_model, model);               // camera frame of T_world_model
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
//
// Optional photometric term (TrackingOptions::photometric_weight > 0, Kintinuous-style,
// photometric_shared.h): the live frame's grey texture (white − black of the pattern stack)
// against the reference frame's, warped through the reference's depth, added to the same
// 6x6 system at every level (a texture pyramid beside the depth pyramid). It pins what the
// geometry leaves free (a textured plane sliding in itself) and tells periodic geometry apart
// when the texture is not periodic too.
//
// Optional pose prior (fusion/pose_prior.h, track()'s `prior`): the rotation expected at a
// pose, about an axis with one σ and about the perpendicular axes with another (a turntable's
// recorded angles and its wobble), added to the same 6x6 system in information form (s²Λ
// against the ICP normal equations, s² their residuals' variance), so the directions the
// surface constrains well follow the surface and the ones it leaves weak (a knob's spin)
// follow the prior. The reference frame is the last one tracked (not
// lost) with a texture, kept by the tracker with its pose, or one given by
// set_reference_frame (a frame fused without tracking: the first one, a known pose).
// Brightness constancy holds for albedo, not for shading: the projector moves with the
// camera, so the shading of relief moves with the view. On a straight knurl turned by one
// tooth the flanks' shading repeats with the teeth and the term keeps the alias as depth
// does (tests/unit/fusion/test_tracker.cpp: KnurledScrewTurnedByOneTooth has the figures).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "fusion/pose_prior.h"
#include "fusion/raycaster.h"
#include "sdk/core/camera_model_shared.h"
#include "sdk/core/device.h"
#include "sdk/core/gpu_stream.h"
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
  // Creases: ICP sets aside the live pixels whose match lies within crease_radius_m of a crease
  // of the model, where its surface turns by more than crease_angle_deg (track_shared.h's
  // near_crease: normals over normal_baseline_m from the model's points, compared
  // crease_radius_m apart); 0 turns the test off. Point-to-plane ICP takes the surface as
  // planar around each match, and near a crease neither the decoder's depth nor the model's
  // is. The radius is the decoder's: on the decoded demo knurl its depth error is biased up to
  // 3-4 pixels (45-60 µm) from a crease (mean -4.8 / -3.4 / -1.7 / -0.9 / -0.4 µm at 0-4
  // pixels, -0.1 µm beyond; docs/benchmarks.md), what its camera and projector blur spans. A
  // smooth surface turns by r / R over r: 15° over 60 µm is a radius of curvature of 0.23 mm,
  // far sharper than a surface ICP can take as planar at that scale. Measured on the decoded
  // demo revolutions: docs/benchmarks.md.
  double crease_angle_deg = 15.0;
  double crease_radius_m = 60e-6;
  // Measurement weights: with a confidence map given to track() (the decoder's
  // DecodedFrame::confidence, 1 / (1 + (σ/σ₀)²): the inverse of its predicted variance, scaled
  // to [0, 1]) each live pixel's residual counts in proportion to it, at every pyramid level
  // (a coarse pixel carries the mean of its block's). The decoder's least trusted pixels (on
  // knurl creases, at grazing angles) then pull the least. false: every pixel counts the same.
  bool weight_by_confidence = true;
  // Robust weights on the ICP residuals, at a scale of a factor times the previous reduction's
  // residual RMS (the first reduction of a frame is plain least squares; track_shared.h's
  // robust_weight): Tukey's biweight at tukey_rms_factor (4.685: 95 % efficiency on Gaussian
  // noise) when it is > 0, else Huber's at huber_rms_factor when that is > 0 (Huber's also
  // weighs the photometric term's residuals). A decoder's outliers (remnants of crease
  // errors, the edges of the projector's shadows) are tens of µm off: Huber's bounds their
  // pull, Tukey's removes it. Measured against a model fused at the true poses (decoded demo
  // knurled screw / knob, 120 frames): a bias of -0.0033° / -0.0032° per frame under Huber's,
  // -0.0017° / -0.0020° under Tukey's, the first as with exact depth (docs/benchmarks.md).
  double tukey_rms_factor = 4.685;
  double huber_rms_factor = 2.0;
  // Lost-frame tests (after the finest level).
  double min_inlier_fraction = 0.25;    // of the live pixels with a depth
  double max_residual_rms_m = 60e-6;    // point-to-plane RMS of the inliers
  double max_correction_m = 3e-3;       // how far the result moves the model's centroid in view from the guess
  double max_correction_deg = 10.0;
  // The photometric term's weight w in E = E_icp + w·E_rgb; 0 = off (the default: then the
  // texture is ignored and results are those of depth alone). Unit-free: both terms are
  // Huber-weighted at their own residual scale, and the photometric normal matrix is scaled
  // so that its largest eigenvalue is w times the ICP one's; w = 1 makes the stiffest
  // direction of each term count the same, Kintinuous' w_rgb = 0.1 a tenth. In directions the
  // geometry leaves free the photometric term alone decides, whatever w; but they stay
  // degenerate (keep the guess) unless their eigenvalue reaches degenerate_eigen_ratio of the
  // largest: with w near degenerate_eigen_ratio or below, the texture has no say there (a
  // chessboard sliding in itself is still recovered at w = 0.03).
  double photometric_weight = 0.0;
  // Reference pixels whose texture gradient (central differences, in fractions of the
  // reference's mean intensity per pixel of the level) is below this are not used: flat
  // texture pins nothing and only adds noise (Kintinuous selects by gradient too).
  double photometric_min_gradient = 0.02;
  // Throws sls::Error(kInvalidArgument) naming the bad value.
  void validate() const;
};

struct TrackingResult {
  Pose T_world_camera;          // the registered pose (the guess when lost)
  bool lost = false;
  std::string reason;           // why it is lost (empty otherwise)
  // Lost because too little of the view matches the model (the model does not reach it, or too
  // few inliers), not because the fit is bad: the pose is unverified rather than wrong, and a
  // prior the caller trusts (a turntable's angle) may stand in for it.
  bool too_little_overlap = false;
  std::size_t live_pixels = 0;  // finest level pixels with a depth (inside the model's volume, when given)
  std::size_t live_pixels_outside_model = 0;  // with a model volume: those whose point the guess puts outside it
  std::size_t inliers = 0;      // of those, matched at the last iteration
  std::size_t crease_pixels = 0;  // of those, set aside at the last iteration: their match is on a crease
  double inlier_fraction = 0.0;   // inliers / (live_pixels - crease_pixels)
  double residual_rms_m = 0.0;  // point-to-plane RMS of the inliers, finest level
  double condition = 0.0;       // largest / smallest eigenvalue of the last normal matrix (finest
                                //  level, scaled parameterisation; infinity when singular)
  int degenerate_directions = 0;
  int iterations = 0;           // Gauss–Newton steps taken over all levels
  // The photometric term: whether it was used; when photometric_weight > 0 but it was not,
  // why (no live texture, no reference frame). Its finest-level figures at the last
  // iteration: the selected pixels, their residual RMS (fractions of the mean intensity), and
  // the live/reference brightness ratio (`gain`) it measured over the matched pixels.
  bool photometric = false;
  std::string photometric_skipped;
  std::size_t photometric_pixels = 0;
  double photometric_rms = 0.0;
  double photometric_gain = 1.0;
  // The pose prior (track()'s `prior`, when active): the registered pose's rotation beyond the
  // prior's (degrees) about its axis (signed) and about the perpendicular axes (the tilt's
  // size), the σ of each that the surface alone gives (the ICP normal matrix over its
  // residuals' variance, finest level, last iteration, the pixels taken as independent; the
  // tilt's the RMS of the two axes; infinity where the surface leaves it free), and the
  // prior's own (infinity: that rotation free).
  bool prior = false;
  double prior_offset_deg = 0.0;
  double prior_tilt_offset_deg = 0.0;
  double prior_surface_sigma_deg = 0.0;
  double prior_surface_tilt_sigma_deg = 0.0;
  double prior_sigma_deg = 0.0;
  double prior_tilt_sigma_deg = 0.0;
};

class Tracker {
 public:
  // camera: the live depth map's camera (ICP's finest level is it, halved to max_model_width).
  // On a GPU, work is queued on `stream` (a session's; one of its own when none is given).
  Tracker(const Device& device, const CameraIntrinsics& camera, const TrackingOptions& options = {},
          const GpuStream& stream = {});
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
  // `texture`: the live frame's grey texture (linear intensity, any scale, the camera's size;
  // sls::Error(kInvalidArgument) naming it otherwise), for the photometric term. With
  // photometric_weight > 0 and no texture the term is off for this frame and the result says
  // so (photometric_skipped); a frame tracked with a texture becomes the next reference.
  // `confidence`: the live pixels' measurement weights (the camera's size; see
  // TrackingOptions::weight_by_confidence), or null for equal weights; pixels of weight 0,
  // negative or not finite are not used. `prior`: a pose prior (pose_prior.h; null or σ = ∞:
  // none), validated (sls::Error(kInvalidArgument) naming the problem). `model_volume`: the
  // volume the model was raycast from (null: unknown). Nothing outside it is in the model, so
  // the overlap test (min_inlier_fraction) counts only the live pixels whose point the guess
  // puts inside it: a view that sees more than a small volume holds is not lost for that.
  // Every map is read where it lives (Image::memory_type()): a CUDA tracker reads maps on the
  // GPU in place — the decoder's depth and confidence, a raycast into
  // RaycastResult(MemoryType::kDevice) — and uploads host maps into buffers made once (no
  // allocation per frame); maps on the GPU must be complete in the tracker's stream order (made
  // on the same stream, a session's, or synchronized). A CPU tracker reads host maps
  // (sls::Error(kInvalidArgument) naming a map on a GPU).
  TrackingResult track(const Image32f& depth_m, const RaycastResult& model, const Pose& T_world_model,
                       const Pose& T_world_camera_guess, const Image32f* texture = nullptr,
                       const Image32f* confidence = nullptr, const PosePrior* prior = nullptr,
                       const VolumeGeometry* model_volume = nullptr);
  // The photometric term's reference for the next track(): a frame fused without tracking
  // (its depth map and texture, the camera's size, and the pose it was fused at). Ignored when
  // photometric_weight is 0. sls::Error(kInvalidArgument) for images of another size. Read
  // where they live, as track() reads its maps; copied before it returns.
  void set_reference_frame(const Image32f& depth_m, const Image32f& texture, const Pose& T_world_camera);
  void clear_reference_frame();
  bool has_reference_frame() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sls::fusion
