// Raycasting the volume from any pose (DESIGN.md section 3): the vertex, normal and depth maps
// the tracker compares frames with (issue #6), and shaded pictures, with the SLS camera model
// (the camera's ray map). CPU or CUDA over raycast_shared.h.
#pragma once

#include <memory>
#include <vector>

#include "fusion/raycast_shared.h"
#include "fusion/volume.h"
#include "sdk/core/camera_model_shared.h"
#include "sdk/core/device.h"
#include "sdk/core/gpu_stream.h"
#include "sdk/core/image.h"
#include "sdk/core/pose.h"

namespace sls::fusion {

struct RaycastResult {
  Image32f depth_m;                 // camera-frame z; 0 = no surface
  std::vector<Vec3f> points_camera;  // row-major, {0,0,0} where depth is 0
  std::vector<Vec3f> normals_camera;
  Image8u shaded;                   // Lambertian, light at the camera
};

struct RaycastOptions {
  double min_depth_m = 0.0;
  double max_depth_m = 10.0;
  double truncation_voxels = 4.0;   // the integration's δ (IntegrationOptions::truncation_voxels)
  // Guided raycasts search the guide's depth range under a ray (or around it) widened by this
  // many δ on either side: the model's surface is within δ of a depth just integrated where
  // the two agreed, and 3 δ leaves room where an earlier, drifted view still holds it.
  double guide_margin_truncations = 3.0;
};

class Raycaster {
 public:
  // On a GPU, work is queued on `stream` (a session's; one of its own when none is given). The
  // camera's ray map is shared with every stage that views through the same camera.
  Raycaster(const Device& device, const CameraIntrinsics& camera, const RaycastOptions& options = {},
            const GpuStream& stream = {});
  ~Raycaster();
  Raycaster(Raycaster&&) noexcept;
  Raycaster& operator=(Raycaster&&) noexcept;

  const CameraIntrinsics& camera() const;
  const Device& device() const;

  // The volume from T_world_camera. The volume must live on the raycaster's device.
  RaycastResult raycast(const Volume& volume, const Pose& T_world_camera);
  // Guided (raycast_shared.h, RaycastGuideView): `guide_depth_m` is a depth map measured from
  // the same pose, at least the raycaster's size (e.g. the full live map for a halved
  // raycaster); each ray searches only near the guide's depths under it (raycast_shared.h).
  // Equal to the unguided raycast wherever the first surface lies within that range; about
  // twice as fast on a 960³ volume.
  RaycastResult raycast(const Volume& volume, const Pose& T_world_camera, const Image32f& guide_depth_m);
#if defined(SLS_HAVE_CUDA)
  // Leaves the result on the GPU (depth, points, normals: width x height each), for the
  // tracker and for timing; asynchronous on the raycaster's stream until synchronize().
  void raycast_device(const Volume& volume, const Pose& T_world_camera);
  // Guided, with the guide on the GPU (guide_width x guide_height floats, complete when called).
  void raycast_device(const Volume& volume, const Pose& T_world_camera, const float* guide_depth_device,
                      int guide_width, int guide_height);
  void synchronize();
  // The maps of the last raycast_device (width x height each, row-major; what RaycastResult
  // holds, on the GPU): for the tracker. Read them after synchronize().
  const float* depth_device() const;
  const Vec3f* points_device() const;
  const Vec3f* normals_device() const;
#endif

 private:
#if defined(SLS_HAVE_CUDA)
  void download(RaycastResult* result);  // the last raycast_device's maps (synchronizes)
#endif
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sls::fusion
