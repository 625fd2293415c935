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

// The maps a raycast gives, each the raycaster's camera size, row-major, where they were made
// to live (RaycastResult(MemoryType::kDevice): on the GPU, for the tracker).
struct RaycastResult {
  RaycastResult() = default;
  explicit RaycastResult(MemoryType memory)
      : depth_m(memory), points_camera(memory), normals_camera(memory), shaded(memory) {}
  // Where the maps are (or will be, before the first raycast).
  MemoryType memory_type() const { return depth_m.memory_requested(); }

  Image32f depth_m;                 // camera-frame z; 0 = no surface
  Image<Vec3f> points_camera;       // {0,0,0} where depth is 0
  Image<Vec3f> normals_camera;
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

  // The volume from T_world_camera into `out`, in the memory its maps were made for, sized to
  // the camera on first use and reused after (no allocation per frame). The volume must live on
  // the raycaster's device. A CUDA raycaster writes device maps in place, asynchronously on its
  // stream: stages on the same stream (a session's) read them in order, others call
  // synchronize() first; host maps are complete on return. A CPU raycaster writes host maps
  // only (sls::Error(kInvalidArgument) for device ones).
  // `guide_depth_m` (null: none): a guided raycast (raycast_shared.h, RaycastGuideView), from a
  // depth map measured from the same pose, at least the raycaster's size (e.g. the full live
  // map for a halved raycaster), read where it lives (a host map is uploaded to a GPU, a device
  // map read in place; a CPU raycaster takes host maps): each ray searches only near the
  // guide's depths under it. Equal to the unguided raycast wherever the first surface lies
  // within that range; about twice as fast on a 960³ volume.
  void raycast(const Volume& volume, const Pose& T_world_camera, RaycastResult& out,
               const Image32f* guide_depth_m = nullptr);
  // The same, into new host maps.
  RaycastResult raycast(const Volume& volume, const Pose& T_world_camera);
  RaycastResult raycast(const Volume& volume, const Pose& T_world_camera, const Image32f& guide_depth_m);
  // Waits for the raycaster's queued work (nothing to wait for on a CPU).
  void synchronize();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sls::fusion
