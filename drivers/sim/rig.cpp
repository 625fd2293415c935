#include "drivers/sim/rig.h"

#include <cmath>

#include "drivers/sim/noise_shared.h"
#include "sdk/core/error.h"

namespace sls::sim {
namespace {

constexpr double kDegree = M_PI / 180.0;

struct Preset {
  const char* name;
  int camera_width;  // 4:3 sensor; the pitch scales so the field of view stays 12 x 9 mm
  int frames;
  const char* description;
};

// ci: a full revolution renders in well under a minute on 2 cores; demo: the README's main
// job, fused by a 2-core CPU in a few minutes; paper: the paper's 4000x3000 x 440 frames.
constexpr Preset kPresets[] = {
    {"ci", 400, 36, "400x300 camera (30 um/px on the object), 36 frames per revolution"},
    {"demo", 800, 120, "800x600 camera (15 um/px), 120 frames per revolution"},
    {"paper", 4000, 440, "4000x3000 camera (3 um/px), 440 frames per revolution, as the paper"},
};

const Preset& find_preset(const std::string& name) {
  for (const Preset& preset : kPresets) {
    if (name == preset.name) return preset;
  }
  throw_error(ErrorCode::kInvalidArgument, "unknown simulator preset '{}' (expected ci, demo or paper)", name);
}

// Where the camera focuses, and the object's mount, per kind of scene: knurled objects and
// the sphere turn about their axis with their side facing the camera; sheets (plane,
// chessboard) stand upright on the table facing the camera at angle 0.
struct Placement {
  Eigen::Vector3d focus_world;
  Pose T_table_object_nominal;
};

Placement place_object(const Scene& scene) {
  const SceneShapeT<double>& shape = scene.shape();
  switch (scene.kind()) {
    case SceneKind::kKnurledScrew:
      return {{shape.screw.ridge_radius, 0.0, 0.5 * shape.screw.height}, Pose()};
    case SceneKind::kKnurledKnob:
      return {{shape.knob.outer_radius, 0.0, 0.5 * shape.knob.height}, Pose()};
    case SceneKind::kSphere: {
      const Eigen::Vector3d centre(shape.sphere.center.x, shape.sphere.center.y, shape.sphere.center.z);
      // Stand the sphere on the axis at 1.5 radii above the table.
      const Pose mount(Eigen::Quaterniond::Identity(),
                       Eigen::Vector3d(0.0, 0.0, 1.5 * shape.sphere.radius) - centre);
      return {{shape.sphere.radius, 0.0, 1.5 * shape.sphere.radius}, mount};
    }
    case SceneKind::kPlane:
    case SceneKind::kChessboard: {
      // Object z (the sheet's normal) -> world +x, object x -> world y, object y -> world z.
      Eigen::Matrix3d rotation;
      rotation.col(0) = Eigen::Vector3d::UnitY();
      rotation.col(1) = Eigen::Vector3d::UnitZ();
      rotation.col(2) = Eigen::Vector3d::UnitX();
      const double height = 0.01;
      return {{0.0, 0.0, height}, Pose(rotation, Eigen::Vector3d(0.0, 0.0, height))};
    }
  }
  throw_error(ErrorCode::kInternal, "unknown scene kind");
}

// A camera at `centre` looking at `target` with image rows running down the world z axis.
Pose look_at(const Eigen::Vector3d& centre, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - centre).normalized();
  Eigen::Vector3d y = -Eigen::Vector3d::UnitZ();
  y = (y - y.dot(z) * z).normalized();
  const Eigen::Vector3d x = y.cross(z);
  Eigen::Matrix3d rotation;
  rotation.col(0) = x;
  rotation.col(1) = y;
  rotation.col(2) = z;
  return Pose(rotation, centre);
}

// A deterministic standard normal draw for (seed, frame), for the turntable's jitter.
double jitter_draw(std::uint64_t seed, int frame) {
  NoiseKey key;
  key.seed = seed;
  key.frame = static_cast<std::uint32_t>(frame);
  NoiseStream stream = make_noise_stream(key, kUserStream);
  return stream.normal();
}

}  // namespace

std::string preset_help() {
  std::string text;
  for (const Preset& preset : kPresets) text += std::string(preset.name) + ": " + preset.description + "\n";
  return text;
}

SimRig make_rig(const RigOptions& options, const Scene& scene) {
  const Preset& preset = find_preset(options.preset);
  SimRig rig;
  rig.preset = preset.name;
  rig.optics = default_rig_optics();
  const int width = options.camera_width > 0 ? options.camera_width : preset.camera_width;
  if (width < 16 || width > 16384 || width % 4 != 0) {
    throw_error(ErrorCode::kInvalidArgument, "camera width {} must be a multiple of 4 in 16..16384", width);
  }
  // Same 13.8 x 10.35 mm sensor area: a coarser pixel grid keeps the 12 x 9 mm field.
  SensorModel& sensor = rig.optics.camera_sensor;
  sensor.pixel_pitch_m *= static_cast<double>(sensor.width) / width;
  sensor.width = width;
  sensor.height = width * 3 / 4;

  if (options.bit_depth != 8 && options.bit_depth != 10 && options.bit_depth != 12 && options.bit_depth != 16) {
    throw_error(ErrorCode::kInvalidArgument, "camera bit depth {} (expected 8, 10, 12 or 16)", options.bit_depth);
  }
  if (!(options.gamma > 0.1 && options.gamma < 10.0)) {
    throw_error(ErrorCode::kInvalidArgument, "sensor gamma {} outside 0.1 .. 10", options.gamma);
  }
  // The same full well over the ADC's range: gain and black level scale by 2^(bits - 12).
  const double scale = std::ldexp(1.0, options.bit_depth - sensor.bit_depth);
  sensor.gain_e_per_dn /= scale;
  sensor.black_level_dn *= scale;
  sensor.bit_depth = options.bit_depth;
  sensor.gamma = options.gamma;
  if (options.projector == "1080p") {
    rig.optics.projector = projector_optics_1080p();
  } else if (options.projector != "dlpc350") {
    throw_error(ErrorCode::kInvalidArgument, "unknown simulated projector '{}' (expected dlpc350 or 1080p)",
                options.projector);
  }
  if (!(options.projector_gamma > 0.1 && options.projector_gamma < 10.0)) {
    throw_error(ErrorCode::kInvalidArgument, "projector gamma {} outside 0.1 .. 10", options.projector_gamma);
  }
  rig.optics.projector.gamma = options.projector_gamma;
  rig.camera = camera_intrinsics(rig.optics.camera_lens, sensor);
  // A well-corrected macro lens: 0.2 % barrel distortion in the corners, slight decentring.
  rig.camera.k1 = -0.3;
  rig.camera.p1 = 2e-4;
  rig.camera.p2 = -1e-4;
  rig.projector = projector_intrinsics(rig.optics.projector);
  rig.projector.k1 = -0.1;

  const Placement placement = place_object(scene);
  const Eigen::Vector3d focus = placement.focus_world;
  const Eigen::Vector3d camera_centre = focus + rig.optics.working_distance_m * Eigen::Vector3d::UnitX();
  rig.T_world_camera = look_at(camera_centre, focus);
  const double throw_distance = rig.optics.projector.lens.focus_distance_m;
  const Eigen::Vector3d projector_centre =
      focus + throw_distance * (Eigen::AngleAxisd(rig.optics.triangulation_angle_rad, Eigen::Vector3d::UnitZ()) *
                                Eigen::Vector3d::UnitX());
  const Pose T_world_projector = look_at(projector_centre, focus);
  rig.T_camera_projector = rig.T_world_camera.inverse() * T_world_projector;

  rig.turntable.steps_per_revolution = options.frames > 0 ? options.frames : preset.frames;
  rig.turntable.seed = options.seed;
  rig.turntable.angle_jitter_deg = options.angle_jitter_deg;
  rig.turntable.mount_tilt_deg = options.mount_tilt_deg;
  rig.turntable.mount_offset_m = options.mount_offset_m;
  if (!(options.angle_jitter_deg >= 0.0 && options.angle_jitter_deg < 1.0) ||
      !(std::fabs(options.mount_tilt_deg) < 5.0) || !(std::fabs(options.mount_offset_m) < 0.005)) {
    throw_error(ErrorCode::kInvalidArgument,
                "turntable jitter {}° (0..1), mount tilt {}° (|.| < 5) or offset {} m (|.| < 5 mm) out of range",
                options.angle_jitter_deg, options.mount_tilt_deg, options.mount_offset_m);
  }
  if (rig.turntable.steps_per_revolution > 100000) {
    throw_error(ErrorCode::kInvalidArgument, "{} frames per revolution is too many", rig.turntable.steps_per_revolution);
  }
  // The mount: the nominal placement, tilted about the world y axis and offset along x.
  const Pose mount_error(Eigen::Quaterniond(Eigen::AngleAxisd(rig.turntable.mount_tilt_deg * kDegree,
                                                              Eigen::Vector3d::UnitY())),
                         Eigen::Vector3d(rig.turntable.mount_offset_m, 0.0, 0.0));
  rig.T_table_object = mount_error * placement.T_table_object_nominal;

  GrayPhaseOptions pattern_options;
  pattern_options.projector_width = rig.projector.width;
  pattern_options.projector_height = rig.projector.height;
  rig.patterns = make_gray_phase_pattern_set(pattern_options);
  if (options.patterns) use_pattern_set(rig, *options.patterns);
  rig.noise_seed = options.seed;
  rig.noise = options.noise;
  return rig;
}

void use_pattern_set(SimRig& rig, const PatternSet& patterns) {
  validate_pattern_set(patterns);
  CameraIntrinsics& p = rig.projector;
  p.cx += 0.5 * (patterns.projector_width - p.width);
  p.cy += 0.5 * (patterns.projector_height - p.height);
  p.width = patterns.projector_width;
  p.height = patterns.projector_height;
  rig.patterns = patterns;
}

namespace {

const ObjectPlacement& placement_of(const SimRig& rig, int frame) {
  if (frame < 0 || static_cast<std::size_t>(frame) >= rig.placements.size()) {
    throw_error(ErrorCode::kInvalidArgument, "frame {} of a capture of {} placements", frame, rig.placements.size());
  }
  return rig.placements[static_cast<std::size_t>(frame)];
}

Pose table_rotation(double angle_deg) {
  return Pose(Eigen::Quaterniond(Eigen::AngleAxisd(angle_deg * kDegree, Eigen::Vector3d::UnitZ())),
              Eigen::Vector3d::Zero());
}

}  // namespace

double SimRig::step_angle_deg(int step) const {
  return 360.0 * static_cast<double>(step) / static_cast<double>(turntable.steps_per_revolution);
}

double SimRig::commanded_angle_deg(int frame) const {
  if (placements.empty()) return step_angle_deg(frame);
  return placement_of(*this, frame).commanded_angle_deg.value_or(0.0);
}

double SimRig::true_angle_deg(int frame) const {
  if (!placements.empty() && !placement_of(*this, frame).commanded_angle_deg) return 0.0;
  return commanded_angle_deg(frame) + turntable.angle_jitter_deg * jitter_draw(turntable.seed, frame);
}

Pose SimRig::T_world_object(int frame) const {
  if (placements.empty()) return table_rotation(true_angle_deg(frame)) * T_table_object;
  const ObjectPlacement& placement = placement_of(*this, frame);
  if (!placement.commanded_angle_deg) return placement.mount;
  return table_rotation(true_angle_deg(frame)) * placement.mount;
}

Pose SimRig::T_object_camera(int frame) const { return T_world_object(frame).inverse() * T_world_camera; }

ScannerCalibration SimRig::calibration() const {
  ScannerCalibration calibration;
  calibration.camera = camera;
  calibration.projector = projector;
  calibration.T_camera_projector = T_camera_projector;
  TurntableAxis axis;
  const Pose T_camera_world = T_world_camera.inverse();
  axis.point_camera = T_camera_world * Eigen::Vector3d::Zero();
  axis.direction_camera = T_camera_world.rotation() * Eigen::Vector3d::UnitZ();
  axis.angle_sigma_deg = turntable.angle_jitter_deg;  // the true angle's σ about the recorded one
  axis.tilt_sigma_deg = 0.0;  // it turns about its axis and nothing else (the mount's tilt turns with it)
  calibration.turntable = axis;
  calibration.reprojection_rms_px = 0.0;
  calibration.description = "slscan simulator, preset " + preset + " (exact calibration of the simulated rig)";
  return calibration;
}

}  // namespace sls::sim
