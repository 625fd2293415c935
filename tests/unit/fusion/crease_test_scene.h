// The knurled screw with a decoder's groove errors, for the tracker's crease test
// (test_tracker.cpp, test_tracker_cuda.cpp): on the demo preset a decoder misplaces the pixels
// along a knurl's grooves, whose blur mixes the two flanks' codes (lines of 1-2 pixels, 20-30
// um in front of the groove; docs/benchmarks.md). Frames of the ci rig at 320x240 (37.5 um
// pixels), noise-free, the object turned 1 degree between the model's frame and the live one.
#pragma once

#include <cmath>
#include <cstddef>

#include "drivers/sim/scene.h"
#include "sdk/core/ray_map.h"
#include "tests/unit/fusion/photometric_test_scenes.h"

namespace sls::fusion::test {

struct GroovedScrew {
  sim::Scene scene = sim::make_knurled_screw_scene();
  sim::SimRig rig;
  CameraIntrinsics camera;
  TexturedFrame reference, live;
  // The reference's depth in 50 um voxels around the surface in view (the ridges at 16.1 mm
  // from the axis, 7.4 mm up), raycast from its pose.
  TexturedModel model;
  Pose model_pose;
  Image32f biased;  // the live depth with -25 um within 40 um of every groove line
  Image32f clean;   // the live depth without those pixels (where the registration is measured)
  std::size_t lines = 0;

  GroovedScrew()
      : rig(noise_free(textured_rig(scene, 360))),
        camera(rig.camera),
        reference(render_textured_frame(rig, scene, 0)),
        live(render_textured_frame(rig, scene, 1)),
        model(VolumeGeometry::centred(Eigen::Vector3d(15.3e-3, 0.0, 7.4e-3), 52, 280, 200, 50e-6), reference, camera,
              camera),
        model_pose(reference.T_world_camera),
        biased(live.depth_m),
        clean(live.depth_m) {
    const sim::KnurledScrewParameters parameters;
    const double groove_radius = 0.5 * parameters.diameter - 0.508e-3;  // the V's root
    const RayMap rays = compute_ray_map(camera);
    for (int y = 0; y < camera.height; ++y) {
      for (int x = 0; x < camera.width; ++x) {
        const float z = live.depth_m(x, y);
        if (!(z > 0.0f)) continue;
        const Vec3f ray = rays.ray(x, y);
        const Eigen::Vector3d p =
            live.T_world_camera * (Eigen::Vector3d(ray.x, ray.y, ray.z) * static_cast<double>(z));
        const bool near_groove = std::hypot(p.x(), p.y()) < groove_radius + 0.1e-3;
        if (near_groove && scene.distance_to_creases(p) < 40e-6) {
          biased(x, y) = z - 25e-6f;
          clean(x, y) = 0.0f;
          ++lines;
        }
      }
    }
  }

 private:
  static sim::SimRig noise_free(sim::SimRig rig) {
    rig.noise = false;
    return rig;
  }
};

}  // namespace sls::fusion::test
