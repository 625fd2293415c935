// The Tracker's state and the types its two halves share: tracker.cpp (options, the
// Gauss–Newton loop and its tests, the CPU path), cuda/tracker_gpu.cpp (the CUDA path) and
// tracker_reference.cpp (the photometric reference frame).
// Internal to fusion/: included by tracker.cpp, cuda/tracker_gpu.cpp, no_cuda.cpp,
// tracker_reference.cpp and pose_prior.cpp only.
#pragma once

#include <Eigen/Core>

#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "fusion/photometric_shared.h"
#include "fusion/track_shared.h"
#include "fusion/tracker.h"
#include "sdk/core/error.h"
#include "sdk/core/ray_map.h"

namespace sls::fusion {
namespace tracking_detail {

using Sums = std::array<double, kTrackSums>;
using FrameSums = std::array<double, kFrameSums>;
using PhotometricSums = std::array<double, kPhotometricSums>;
using TextureSums = std::array<double, kTextureSums>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

// JᵀJ from a reduction's first 21 sums (the upper triangle, row-major; track_shared.h).
Matrix6d normal_matrix(const double* sums);

// One level of the live pyramid: its camera and ray map (shared with the other stages that
// view through that camera; on a GPU also in its memory), and on the CPU its depth,
// measurement weights and normals (level 0's depth and weights are the caller's).
struct Level {
  CameraIntrinsics camera;
  std::shared_ptr<const SharedRayMap> shared_rays;
  const RayMap* rays = nullptr;  // shared_rays->host
  std::vector<float> depth;
  std::vector<float> weight;  // with options.weight_by_confidence
  std::vector<Vec3f> normals;
  std::size_t pixels() const {
    return static_cast<std::size_t>(camera.width) * static_cast<std::size_t>(camera.height);
  }
};

// The centre c and scale L of the parameterisation (track_shared.h) from the frame sums.
struct Frame {
  std::size_t live_pixels = 0;          // with a depth, inside the model volume when there is one
  std::size_t live_pixels_outside = 0;  // with a depth, outside it
  std::size_t model_points = 0;
  Vec3f centre{0.0f, 0.0f, 0.0f};
  double scale = 1.0;
};

// What the photometric term needs for a frame beyond the per-level maps.
struct PhotometricSetup {
  Pose T_model_ref;        // T_world_model⁻¹ · T_world_ref
  double live_mean = 0.0;  // the frames' mean texture over their depth pixels (level 0)
  double ref_mean = 0.0;
};

}  // namespace tracking_detail

struct Tracker::Impl {
  using Sums = tracking_detail::Sums;
  using FrameSums = tracking_detail::FrameSums;
  using PhotometricSums = tracking_detail::PhotometricSums;
  using Level = tracking_detail::Level;
  using Frame = tracking_detail::Frame;
  using PhotometricSetup = tracking_detail::PhotometricSetup;

  Device device;
  CameraIntrinsics live_camera;  // the live depth maps' camera
  CameraIntrinsics camera;       // ICP's finest level, the model maps' camera
  TrackingOptions options;
  // The current track() call's pose prior (null: none) and the volume its model was raycast
  // from (null: unknown); set for the call only (CallScope).
  const PosePrior* pose_prior = nullptr;
  const VolumeGeometry* model_volume = nullptr;
  struct CallScope {
    Impl& impl;
    CallScope(Impl& i, const PosePrior* prior, const VolumeGeometry* volume) : impl(i) {
      if (prior != nullptr) prior->validate();
      if (volume != nullptr) volume->validate();
      impl.pose_prior = prior != nullptr && prior->active() ? prior : nullptr;
      impl.model_volume = volume;
    }
    ~CallScope() {
      impl.pose_prior = nullptr;
      impl.model_volume = nullptr;
    }
    CallScope(const CallScope&) = delete;
    CallScope& operator=(const CallScope&) = delete;
  };
  // The frame statistics' region (track_shared.h): the model volume's box with the live
  // pixels placed by the guess; inactive without a model volume.
  TrackRegion region(const Pose& T_world_camera_guess) const {
    TrackRegion r;
    if (model_volume == nullptr) return r;
    r.active = true;
    r.T_volume_live = (model_volume->T_world_volume.inverse() * T_world_camera_guess).to_rigid3f();
    const Eigen::Vector3d size = model_volume->size_m();
    r.size_m = Vec3f{static_cast<float>(size.x()), static_cast<float>(size.y()), static_cast<float>(size.z())};
    return r;
  }
  // The live camera halved down to `camera` (empty when they are the same), and the host
  // buffers of those halvings (the last is ICP's finest live depth).
  std::vector<CameraIntrinsics> input_cameras;
  std::vector<std::vector<float>> input_depth;
  std::vector<std::vector<float>> input_weight;  // with options.weight_by_confidence
  std::vector<Level> levels;
  // The crease test on the model maps (level 0's size; on the device for CUDA): the model's
  // normals over the baseline, and the marks.
  std::vector<Vec3f> crease_normals;
  std::vector<std::uint8_t> crease_mask;
  bool crease_test() const { return options.crease_angle_deg > 0.0; }
  float crease_min_cos() const { return static_cast<float>(std::cos(options.crease_angle_deg * M_PI / 180.0)); }
  // The photometric term (options.photometric_weight > 0): on the CPU the live texture's
  // halvings down to level 0 and its pyramid (level 0 is the input or its last halving).
  bool photometric_on = false;
  std::vector<std::vector<float>> input_texture;
  std::vector<std::vector<float>> texture;
  // The reference frame: the last frame tracked with a texture, or set_reference_frame's.
  struct Reference {
    bool valid = false;
    Pose T_world_camera;
    double mean = 0.0;                               // its texture's mean over its depth pixels
    std::vector<std::vector<float>> depth, texture;  // per level (CPU)
  } reference_frame;
  using ReducePhotometric = std::function<PhotometricSums(int, const PhotometricParams&)>;
  GpuStream gpu_stream;  // the session's, or its own (CUDA)
  // A CUDA tracker's stream and device buffers (fusion/cuda/tracker_gpu.cpp): made by
  // allocate_on_device(); none in a build without CUDA, where no tracker lives on a GPU.
  struct Gpu;
  struct GpuDelete {
    void operator()(Gpu* gpu) const;
  };
  std::unique_ptr<Gpu, GpuDelete> gpu;
  // The pyramid, normals, frame statistics and Gauss–Newton steps on the device: one
  // device-to-host copy of the sums per step, no allocation.
  TrackingResult track_on_device(const float* depth_device, const Vec3f* model_points, const Vec3f* model_normals,
                                 const Pose& T_world_model, const Pose& T_world_camera_guess,
                                 const float* texture_device, const float* weight_device_in);
  // The live depth pyramid from a map at the live camera's size (normals too when asked), and
  // its weights' when weight_in is not null (else level_weight stays null).
  void depth_pyramid_device(const float* depth_device, const float* weight_in, const float* level_depth[8],
                            const float* level_weight[8], bool with_normals);
  void texture_pyramid_device(const float* texture_in, const float* level_texture[8]);
  double texture_mean_device(const float* texture0, const float* depth0);
  void keep_reference_device(const float* const level_depth[8], const float* const level_texture[8], double mean,
                             const Pose& T_world_camera);
  void set_reference_on_device(const float* depth_device, const float* texture_in, const Pose& T_world_camera);

  // The Gauss–Newton loop over the levels, coarse to fine, and the lost-frame tests; `reduce`
  // (level, params) returns the level's sums for one estimate; with `photometric`,
  // `reduce_photometric` the photometric term's, added to the same system.
  using Reduce = std::function<Sums(int, const TrackParams&)>;
  TrackingResult run(const Frame& frame, const Pose& T_world_model, const Pose& guess, const Reduce& reduce,
                     const PhotometricSetup* photometric = nullptr,
                     const ReducePhotometric& reduce_photometric = {}) const;
  Frame frame_from_sums(const FrameSums& first, const FrameSums& second, Vec3f reference) const;
  // Two passes of `statistics(reference)`: about the origin for the centroid, then about it.
  template <typename Statistics>
  Frame frame_from_statistics(Statistics&& statistics) const {
    const FrameSums first = statistics(Vec3f{0.0f, 0.0f, 0.0f});
    Vec3f centre{0.0f, 0.0f, 0.0f};
    if (first[0] > 0.0) {
      centre = Vec3f{static_cast<float>(first[1] / first[0]), static_cast<float>(first[2] / first[0]),
                     static_cast<float>(first[3] / first[0])};
    }
    return frame_from_sums(first, statistics(centre), centre);
  }
  TrackModelView model_view(const Vec3f* points, const Vec3f* point_normals) const {
    TrackModelView view;
    view.points = points;
    view.normals = point_normals;
    view.camera = camera.cast<float>();
    return view;
  }
  // The CPU's pyramids: level_depth[l] / level_texture[l] point at the input (level 0 when the
  // live camera is ICP's finest) or at the tracker's buffers.
  void depth_pyramid(const float* depth_in, const float* weight_in, const float* level_depth[8],
                     const float* level_weight[8], bool with_normals);
  void texture_pyramid(const float* texture_in, const float* level_texture[8]);
  double texture_mean(const float* texture0, const float* depth0) const;
  void keep_reference(const float* const level_depth[8], const float* const level_texture[8], double mean,
                      const Pose& T_world_camera);
  // The photometric term for a frame with (or without) a live texture whose mean over the
  // depth pixels is live_mean: on when there is a reference, else off with the reason.
  std::optional<PhotometricSetup> photometric_setup(bool have_texture, double live_mean, const Pose& T_world_model,
                                                    std::string* skipped) const;
  // A CUDA tracker's track() and set_reference_frame() (cuda/tracker_gpu.cpp): maps on the GPU
  // read in place, host maps uploaded. kUnsupported in a build without CUDA.
  TrackingResult track_gpu(const Image32f& depth_m, const Image<Vec3f>& model_points,
                           const Image<Vec3f>& model_normals, const Pose& T_world_model, const Pose& guess,
                           const Image32f* live_texture, const Image32f* live_weight);
  void set_reference_gpu(const Image32f& depth_m, const Image32f& reference_texture_in, const Pose& T_world_camera);
  // The CUDA path's buffers, at construction (nothing in a build without CUDA).
  void allocate_on_device();
  // A CPU tracker reads host maps only.
  template <typename T>
  void check_on_host(const Image<T>& image, const char* what) const {
    if (image.memory_type() == MemoryType::kDevice) {
      throw_error(ErrorCode::kInvalidArgument, "tracking: the {} is on a GPU; a tracker for {} reads host maps",
                  what, device.to_string());
    }
  }
  void check_size(const Image32f& image, const char* what) const {
    if (image.width() != live_camera.width || image.height() != live_camera.height) {
      throw_error(ErrorCode::kInvalidArgument, "tracking: the {} is {}x{}, the camera {}x{}", what, image.width(),
                  image.height(), live_camera.width, live_camera.height);
    }
  }
};

}  // namespace sls::fusion
