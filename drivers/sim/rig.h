// The simulated scanner rig: camera and projector (optics from drivers/sim/optics_shared.h,
// documented in docs/simulator-optics.md), their placement, the turntable and the object's
// mount on it, and the presets ci / demo / paper.
//
// Frames. World = the turntable frame: z up along the turntable axis, origin on the axis at
// the table top. The object stands on the table (object z along its own axis, which the mount
// tilts and offsets by a few micrometres: that is the wobble). The camera looks horizontally
// at the object's side along −x world, image rows running down the object (y_camera = −z
// world); the projector sits 25° around the vertical axis through the focus point, so its
// column stripes run parallel to the axis (and to straight knurl ridges).
//
// Per frame k of a revolution of N: commanded angle θ_k = 360° k / N, true angle θ_k + jitter;
//   T_world_object(k) = Rz(true θ_k) · T_table_object,
//   T_object_camera(k) = T_world_object(k)⁻¹ · T_world_camera   (the ground-truth pose).
// A calibration capture (drivers/sim/sim_calibration_capture.h) instead lists a placement
// per frame: the board on the table at a commanded angle on a mount of its own, or held off
// the table (by hand) at a pose in the world.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "drivers/sim/material_shared.h"
#include "drivers/sim/optics_shared.h"
#include "drivers/sim/scene.h"
#include "sdk/core/calibration.h"
#include "sdk/core/camera_model_shared.h"
#include "sdk/core/pose.h"
#include "sdk/decode/pattern_set.h"

namespace sls::sim {

struct TurntableModel {
  int steps_per_revolution = 440;  // frames per revolution (the paper: 440 at 3 Hz)
  double angle_jitter_deg = 0.002; // σ of the true angle about the commanded one (stepper + backlash)
  double mount_tilt_deg = 0.02;    // the object's axis against the table's: wobble as it turns
  double mount_offset_m = 30e-6;   // the object's axis off the table's axis (eccentricity)
  std::uint64_t seed = 1;          // jitter draws
};

// Where the object is in one frame of a calibration capture.
struct ObjectPlacement {
  // On the table at this commanded angle (jittered as a scan's steps are); nullopt: off the
  // table, not moved by it.
  std::optional<double> commanded_angle_deg;
  Pose mount;  // on the table: T_table_object; off it: T_world_object
};

struct SimRig {
  std::string preset;
  RigOptics optics;            // sensor size per preset; physical parameters per the document
  CameraIntrinsics camera;     // pinhole from the optics plus a small lens distortion
  CameraIntrinsics projector;
  Pose T_world_camera;
  Pose T_camera_projector;     // projector frame -> camera frame (what a calibration stores)
  TurntableModel turntable;
  Pose T_table_object;         // the mount (tilt + offset), fixed during a scan
  PatternSet patterns;
  // Empty for a scan: frame k is turntable step k with the object on T_table_object. A
  // calibration capture lists one placement per frame (other frames are an error).
  std::vector<ObjectPlacement> placements;
  std::uint64_t noise_seed = 1;
  bool noise = true;           // false: noise-free renders (tests, pictures)
  // The object's finish: Lambertian with the scene's albedo (painted), or metal's specular
  // lobe (drivers/sim/material_shared.h).
  SurfaceMaterial material;

  // The calibration a perfect calibration of this rig would give (camera, projector, their
  // pose, the turntable axis in the camera frame).
  ScannerCalibration calibration() const;
  // The table angle of stepper position `step` (360° step / steps_per_revolution).
  double step_angle_deg(int step) const;
  // Commanded and true turntable angles of frame k, in degrees (0 for a frame off the table).
  double commanded_angle_deg(int frame) const;
  double true_angle_deg(int frame) const;
  // Ground truth: the object's pose in the world and the camera's pose in the object frame.
  Pose T_world_object(int frame) const;
  Pose T_object_camera(int frame) const;
};

struct RigOptions {
  std::string preset = "demo";  // ci | demo | paper
  int frames = 0;               // frames per revolution; 0: the preset's
  int camera_width = 0;         // 0: the preset's; the field of view stays 12 x 9 mm
  std::string projector = "dlpc350";  // dlpc350 (DLP4500, 912x1140) or 1080p (1920x1080)
  int bit_depth = 12;           // ADC: 8, 10, 12 or 16 bits; gain and black level scale with it
  double gamma = 1.0;           // sensor response exponent (1: linear, as machine vision)
  double projector_gamma = 1.0; // projector response exponent (1: linear, a DLP in pattern mode)
  // Turntable imperfections (TurntableModel); 0 turns each off.
  double angle_jitter_deg = TurntableModel{}.angle_jitter_deg;
  double mount_tilt_deg = TurntableModel{}.mount_tilt_deg;
  double mount_offset_m = TurntableModel{}.mount_offset_m;
  std::uint64_t seed = 1;
  bool noise = true;
  // Project this set instead of the preset's (use_pattern_set: its DMD size wins).
  std::optional<PatternSet> patterns;
  // The object's finish, "painted" or "metal" (material_shared.h); SimScanner::create sets
  // SimRig::material from it.
  std::string material = "painted";
};

// The rig for a preset looking at `scene` (the focus point is the object's surface nearest
// the camera at mid-height). Throws sls::Error(kInvalidArgument) for an unknown preset or
// bad sizes.
SimRig make_rig(const RigOptions& options, const Scene& scene);

// Projects `patterns` (any family, pattern_families.h) instead of the preset's set. A set
// made for another DMD size gets a DMD of that size behind the same lens (same pixel pitch,
// principal point at the new centre), so captures described for e.g. a 1024 x 768 projector
// render with ground truth; rig.optics keeps the preset's physical model. Throws
// sls::Error(kInvalidArgument) for an invalid set.
void use_pattern_set(SimRig& rig, const PatternSet& patterns);

// The presets' names and one-line descriptions, for --help.
std::string preset_help();

}  // namespace sls::sim
