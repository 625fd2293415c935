// Textured frames for the photometric term's tests (test_tracker.cpp, test_tracker_cuda.cpp),
// rendered by the simulator (drivers/sim): the ci rig's camera at 320x240 (37.5 um pixels on
// the object at 0.1 m), depth maps with the noise of a phase-shift decode (render_depth), and
// the texture a scan session derives from the pattern stack: the white image minus the black
// one (shading by the projector that moves with the camera, ambient light, sensor noise).
// World = the object's frame; the model is the reference frame's depth integrated into a
// volume around the object and raycast from its pose, as a scan session builds it.
#pragma once

#include <cstdint>

#include "drivers/sim/renderer.h"
#include "drivers/sim/rig.h"
#include "drivers/sim/scene.h"
#include "fusion/integrator.h"
#include "fusion/raycaster.h"
#include "fusion/volume.h"
#include "sdk/core/error.h"
#include "sdk/core/image.h"
#include "sdk/core/pose.h"

namespace sls::fusion::test {

// The ci preset at 320x240 with a perfect turntable (no jitter, tilt or offset), so frame k
// is the object turned by exactly 360° k / frames about its axis.
inline sim::SimRig textured_rig(const sim::Scene& scene, int frames = 36) {
  sim::RigOptions options;
  options.preset = "ci";
  options.camera_width = 320;
  options.frames = frames;
  options.angle_jitter_deg = 0.0;
  options.mount_tilt_deg = 0.0;
  options.mount_offset_m = 0.0;
  return sim::make_rig(options, scene);
}

// The same rig with the object moved by `motion` in its own frame (a chessboard's sheet is
// its z = 0 plane: a motion in x, y and about z slides it in itself), with another noise draw.
inline sim::SimRig moved_rig(const sim::SimRig& rig, const Pose& motion, std::uint64_t noise_seed) {
  sim::SimRig moved = rig;
  moved.T_table_object = rig.T_table_object * motion;
  moved.noise_seed = noise_seed;
  return moved;
}

// A slide of the chessboard in its plane: 0.2 mm, -0.15 mm and 1 degree about its normal
// (the surface in view moves 0.26 mm RMS, 7 pixels of 37.5 um).
inline Pose chessboard_slide() {
  return Pose(Eigen::Quaterniond(Eigen::AngleAxisd(1.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ())),
              Eigen::Vector3d(0.2e-3, -0.15e-3, 0.0));
}

// The chessboard's volume (object frame: the sheet z = 0): 15 x 12 x 1.6 mm of 50 um voxels.
inline VolumeGeometry chessboard_volume() {
  return VolumeGeometry::centred(Eigen::Vector3d::Zero(), 300, 240, 32, 50e-6);
}

struct TexturedFrame {
  Image32f depth_m;     // with the decode's noise; 0 where not measurable
  Image32f texture;     // white − black, DN
  Pose T_world_camera;  // the truth: the camera in the object's frame
};

inline int pattern_index(const PatternSet& set, PatternKind kind) {
  for (std::size_t i = 0; i < set.size(); ++i) {
    if (set.patterns[i].kind == kind) return static_cast<int>(i);
  }
  throw_error(ErrorCode::kInvalidArgument, "the pattern set has no {} pattern",
              kind == PatternKind::kWhite ? "white" : "black");
}

// Frame `frame` of `rig` looking at `scene`.
inline TexturedFrame render_textured_frame(const sim::SimRig& rig, const sim::Scene& scene, int frame) {
  sim::Renderer renderer(rig, scene, Device::cpu());
  renderer.set_frame(frame);
  TexturedFrame out;
  out.depth_m = renderer.render_depth();
  const Image16u white = renderer.render_pattern(pattern_index(rig.patterns, PatternKind::kWhite));
  const Image16u black = renderer.render_pattern(pattern_index(rig.patterns, PatternKind::kBlack));
  out.texture = Image32f(white.width(), white.height(), 0.0f);
  for (std::size_t i = 0; i < out.texture.pixel_count(); ++i) {
    out.texture.data()[i] = static_cast<float>(white.data()[i]) - static_cast<float>(black.data()[i]);
  }
  out.T_world_camera = rig.T_object_camera(frame);
  return out;
}

// The model of a reference frame: its depth integrated (plain TSDF, 50 um voxels) into
// `geometry`, raycast from its pose with `model_camera` (Tracker::model_camera()).
struct TexturedModel {
  Volume volume;
  RaycastResult raycast;
  TexturedModel(const VolumeGeometry& geometry, const TexturedFrame& reference, const CameraIntrinsics& camera,
                const CameraIntrinsics& model_camera)
      : volume(geometry, VoxelFormat::kFloat32, Device::cpu()) {
    const IntegrationOptions integration = IntegrationOptions::tsdf();
    Integrator(Device::cpu(), integration).integrate(volume, reference.depth_m, camera, reference.T_world_camera);
    RaycastOptions options;
    options.truncation_voxels = integration.truncation_voxels;
    options.min_depth_m = 1e-3;
    raycast = Raycaster(Device::cpu(), model_camera, options).raycast(volume, reference.T_world_camera);
  }
};

}  // namespace sls::fusion::test
