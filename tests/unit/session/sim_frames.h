// Frames of the simulated scanner for scan-session tests: depth maps, turntable angles and
// true poses, frame by frame (no recording on disk); a chessboard sliding in its plane.
#pragma once

#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "drivers/sim/renderer.h"
#include "drivers/sim/sim_scanner.h"
#include "sdk/session/scan_session.h"

namespace sls::session {

constexpr double kDegree = M_PI / 180.0;

// The ci preset's camera (400x300, 30 µm pixels on the object) looking at a sim object on a
// turntable of `frames_per_revolution` steps: depth maps and true poses frame by frame.
class SimFrames {
 public:
  SimFrames(const std::string& object, int frames_per_revolution, const Device& device = Device::cpu()) {
    sim::RigOptions rig;
    rig.preset = "ci";
    rig.frames = frames_per_revolution;
    scanner_ = sim::SimScanner::create(object, rig, device);
    turntable_ = scanner_->turntable();
    turntable_->home(std::chrono::milliseconds(1000));
  }
  const sim::SimRig& rig() const { return scanner_->rig(); }
  ScannerCalibration calibration() const { return rig().calibration(); }

  // Frame k: its depth map, turntable angle and (kept aside) the true T_object_camera.
  ScanFrame frame(int k) {
    turntable_->move_to_deg(rig().commanded_angle_deg(k), std::chrono::milliseconds(1000));
    ScanFrame frame;
    frame.index = k;
    frame.timestamp_ns = static_cast<std::int64_t>(k) * 333'333'333;
    frame.turntable_angle_deg = turntable_->position_deg();
    frame.depth_m = scanner_->depth_map();
    truth_.push_back(scanner_->ground_truth().T_object_camera);
    return frame;
  }
  const Pose& truth(std::size_t i) const { return truth_.at(i); }

 private:
  std::shared_ptr<sim::SimScanner> scanner_;
  std::unique_ptr<drivers::Turntable> turntable_;
  std::vector<Pose> truth_;
};

// A chessboard sliding in its own plane, 0.1 mm, -0.05 mm and 0.3° a frame (the ci camera at
// 320x240, a perfect turntable standing still): depth alone sees the same plane in every
// frame, the texture sees the slide. Frames as pattern stacks, true poses in the board's frame.
struct SlidingChessboard {
  sim::Scene scene = sim::make_chessboard_scene();
  sim::SimRig rig;
  SlidingChessboard() {
    sim::RigOptions options;
    options.preset = "ci";
    options.camera_width = 320;
    options.angle_jitter_deg = 0.0;
    options.mount_tilt_deg = 0.0;
    options.mount_offset_m = 0.0;
    rig = sim::make_rig(options, scene);
  }
  sim::SimRig rig_at(int k) const {
    const Pose step(Eigen::Quaterniond(Eigen::AngleAxisd(0.3 * kDegree, Eigen::Vector3d::UnitZ())),
                    Eigen::Vector3d(0.1e-3, -0.05e-3, 0.0));
    sim::SimRig moved = rig;
    moved.T_table_object = rig.T_table_object * Pose::exp(step.log() * static_cast<double>(k));
    moved.noise_seed = rig.noise_seed + static_cast<std::uint64_t>(k);
    return moved;
  }
  Pose truth(int k) const { return rig_at(k).T_object_camera(0); }
  // Frame k as the pattern stack the camera captures.
  ScanFrame stack(int k) const {
    sim::Renderer renderer(rig_at(k), scene, Device::cpu());
    renderer.set_frame(0);
    ScanFrame frame;
    frame.index = k;
    frame.timestamp_ns = static_cast<std::int64_t>(k) * 333'333'333;
    for (std::size_t j = 0; j < rig.patterns.size(); ++j) {
      frame.images.push_back(renderer.render_pattern(static_cast<int>(j)));
    }
    return frame;
  }
};

inline ScanSessionOptions small_options(const Device& device) {
  ScanSessionOptions options;
  options.device = device;
  options.max_voxels = 4e6;  // a 12 x 9 x 6 mm volume at ~50 µm: tests stay fast on 2 cores
  return options;
}

// Relative pose error of frame i against frame 0, estimated against true: of the camera,
// and of the surface in view (how far the error moves the focus point, 0.1 m in front of
// camera i: turning about the object 0.1 m away, 0.01 degree moves the camera 20 µm but the
// surface it sees only ~3 µm).
struct RelativeError {
  double translation_m;
  double rotation_deg;
  double surface_m;
};
inline RelativeError relative_error(const Pose& estimated_0, const Pose& estimated_i, const Pose& true_0,
                                    const Pose& true_i) {
  const Pose true_motion = true_0.inverse() * true_i;
  const Pose estimated_motion = estimated_0.inverse() * estimated_i;
  const Eigen::Vector3d focus_camera(0.0, 0.0, 0.1);
  const double surface = ((true_motion * focus_camera) - (estimated_motion * focus_camera)).norm();
  const Pose error = true_motion.inverse() * estimated_motion;
  return {error.translation().norm(), error.angle_rad() / kDegree, surface};
}

}  // namespace sls::session
