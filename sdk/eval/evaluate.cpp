#include "sdk/eval/evaluate.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <numeric>
#include <utility>

#include <Eigen/Geometry>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/image_io.h"
#include "sdk/core/ply.h"
#include "sdk/core/recording.h"
#include "sdk/core/trajectory.h"

namespace sls::eval {
namespace {

constexpr std::int64_t kCellOffset = std::int64_t{1} << 20;  // 21 bits per axis in a key

std::uint64_t pack_key(const std::int64_t cell[3]) {
  return (static_cast<std::uint64_t>(cell[0] + kCellOffset) << 42) |
         (static_cast<std::uint64_t>(cell[1] + kCellOffset) << 21) | static_cast<std::uint64_t>(cell[2] + kCellOffset);
}

std::vector<Eigen::Vector3d> positions_of(const PointCloud& cloud) {
  std::vector<Eigen::Vector3d> out(cloud.size());
  for (std::size_t n = 0; n < cloud.size(); ++n) out[n] = cloud.positions[n].cast<double>();
  return out;
}

bool exists(const std::string& path) { return std::filesystem::exists(path); }

}  // namespace

// ---------------------------------------------------------------------------------------
// PointGrid

PointGrid::PointGrid(std::vector<Eigen::Vector3d> points, double cell_size_m) : cell_size_m_(cell_size_m) {
  if (!(cell_size_m > 0.0) || !std::isfinite(cell_size_m)) {
    throw_error(ErrorCode::kInvalidArgument, "point grid: cell size {} m is not positive and finite", cell_size_m);
  }
  if (points.size() >= std::numeric_limits<std::uint32_t>::max()) {
    throw_error(ErrorCode::kInvalidArgument, "point grid: {} points, more than 2^32", points.size());
  }
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed(points.size());
  for (std::size_t n = 0; n < points.size(); ++n) {
    std::int64_t cell[3];
    keyed[n] = {key_of(points[n], cell), static_cast<std::uint32_t>(n)};
  }
  std::sort(keyed.begin(), keyed.end());
  points_.resize(points.size());
  for (std::size_t n = 0; n < keyed.size(); ++n) {
    points_[n] = points[keyed[n].second];
    if (n == 0 || keyed[n].first != keyed[n - 1].first) {
      cell_keys_.push_back(keyed[n].first);
      cell_begin_.push_back(static_cast<std::uint32_t>(n));
    }
  }
  cell_begin_.push_back(static_cast<std::uint32_t>(points_.size()));
}

std::uint64_t PointGrid::key_of(const Eigen::Vector3d& p, std::int64_t cell[3]) const {
  for (int axis = 0; axis < 3; ++axis) {
    const double c = std::floor(p[axis] / cell_size_m_);
    if (!(std::fabs(c) < static_cast<double>(kCellOffset))) {
      throw_error(ErrorCode::kInvalidArgument,
                  "point grid: coordinate {} m is more than 2^20 cells of {} m from the origin (or not finite)",
                  p[axis], cell_size_m_);
    }
    cell[axis] = static_cast<std::int64_t>(c);
  }
  return pack_key(cell);
}

template <typename Visit>
void PointGrid::visit_near(const Eigen::Vector3d& p, double radius_m, const Visit& visit) const {
  if (points_.empty()) return;
  std::int64_t lo[3], hi[3];
  key_of(p - Eigen::Vector3d::Constant(radius_m), lo);
  key_of(p + Eigen::Vector3d::Constant(radius_m), hi);
  for (std::int64_t x = lo[0]; x <= hi[0]; ++x) {
    for (std::int64_t y = lo[1]; y <= hi[1]; ++y) {
      for (std::int64_t z = lo[2]; z <= hi[2]; ++z) {
        const std::int64_t cell[3] = {x, y, z};
        const std::uint64_t key = pack_key(cell);
        const auto found = std::lower_bound(cell_keys_.begin(), cell_keys_.end(), key);
        if (found == cell_keys_.end() || *found != key) continue;
        const auto c = static_cast<std::size_t>(found - cell_keys_.begin());
        for (std::uint32_t n = cell_begin_[c]; n < cell_begin_[c + 1]; ++n) {
          if (!visit(n)) return;
        }
      }
    }
  }
}

std::ptrdiff_t PointGrid::nearest(const Eigen::Vector3d& p, double max_distance_m, double* distance_m) const {
  std::ptrdiff_t best = -1;
  double best_squared = max_distance_m * max_distance_m;
  visit_near(p, max_distance_m, [&](std::uint32_t n) {
    const double squared = (points_[n] - p).squaredNorm();
    if (squared <= best_squared) {
      best_squared = squared;
      best = static_cast<std::ptrdiff_t>(n);
    }
    return true;
  });
  if (best >= 0 && distance_m != nullptr) *distance_m = std::sqrt(best_squared);
  return best;
}

bool PointGrid::any_within(const Eigen::Vector3d& p, double radius_m) const {
  bool found = false;
  const double squared = radius_m * radius_m;
  visit_near(p, radius_m, [&](std::uint32_t n) {
    found = (points_[n] - p).squaredNorm() <= squared;
    return !found;
  });
  return found;
}

// ---------------------------------------------------------------------------------------
// Statistics and surface errors

DistanceStats distance_stats(std::vector<double> distances_m) {
  DistanceStats stats;
  stats.count = distances_m.size();
  if (distances_m.empty()) return stats;
  double sum = 0.0, squares = 0.0;
  for (const double d : distances_m) {
    sum += d;
    squares += d * d;
    stats.max_m = std::max(stats.max_m, d);
  }
  const double n = static_cast<double>(distances_m.size());
  stats.mean_m = sum / n;
  stats.rms_m = std::sqrt(squares / n);
  const auto rank = static_cast<std::size_t>(std::ceil(0.95 * n));  // nearest rank, 1-based
  const auto nth = distances_m.begin() + static_cast<std::ptrdiff_t>(std::max<std::size_t>(rank, 1) - 1);
  std::nth_element(distances_m.begin(), nth, distances_m.end());
  stats.p95_m = *nth;
  return stats;
}

SurfaceErrors surface_errors(const std::vector<Eigen::Vector3d>& points_object, const sim::Scene& scene,
                             double edge_band_m, std::vector<float>* point_errors_m) {
  const std::size_t count = points_object.size();
  const bool has_creases = !scene.creases().empty();
  std::vector<double> distance(count);
  std::vector<std::uint8_t> near_crease(count, 0);
  const auto signed_count = static_cast<std::ptrdiff_t>(count);
#pragma omp parallel for schedule(dynamic, 1024)
  for (std::ptrdiff_t n = 0; n < signed_count; ++n) {
    const auto i = static_cast<std::size_t>(n);
    distance[i] = std::fabs(scene.signed_distance(points_object[i]));
    if (has_creases) near_crease[i] = scene.distance_to_creases(points_object[i]) <= edge_band_m ? 1 : 0;
  }
  SurfaceErrors errors;
  errors.has_creases = has_creases;
  std::vector<double> edge;
  for (std::size_t i = 0; i < count; ++i) {
    if (near_crease[i] != 0) edge.push_back(distance[i]);
  }
  if (point_errors_m != nullptr) {
    point_errors_m->resize(count);
    for (std::size_t i = 0; i < count; ++i) (*point_errors_m)[i] = static_cast<float>(distance[i]);
  }
  errors.all = distance_stats(std::move(distance));
  errors.edge = distance_stats(std::move(edge));
  return errors;
}

// ---------------------------------------------------------------------------------------
// Trajectory errors

std::optional<TrajectoryErrors> trajectory_errors(const std::vector<StampedPose>& estimated,
                                                  const std::vector<StampedPose>& truth, std::string* why,
                                                  double timestamp_tolerance_s) {
  auto by_time = [](const std::vector<StampedPose>& poses) {
    std::vector<std::size_t> order(poses.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return poses[a].timestamp_s < poses[b].timestamp_s; });
    return order;
  };
  const std::vector<std::size_t> truth_order = by_time(truth);
  std::vector<std::pair<const Pose*, const Pose*>> matches;  // (estimated, true)
  TrajectoryErrors errors;
  for (const std::size_t e : by_time(estimated)) {
    const double t = estimated[e].timestamp_s;
    auto candidate = std::lower_bound(truth_order.begin(), truth_order.end(), t - timestamp_tolerance_s,
                                      [&](std::size_t n, double value) { return truth[n].timestamp_s < value; });
    // The nearest of the true poses within the tolerance (the first two after t - tolerance).
    const StampedPose* best = nullptr;
    for (int k = 0; k < 2 && candidate != truth_order.end(); ++k, ++candidate) {
      const StampedPose& pose = truth[*candidate];
      if (std::fabs(pose.timestamp_s - t) > timestamp_tolerance_s) continue;
      if (best == nullptr || std::fabs(pose.timestamp_s - t) < std::fabs(best->timestamp_s - t)) best = &pose;
    }
    if (best == nullptr) {
      ++errors.unmatched_frames;
      continue;
    }
    matches.emplace_back(&estimated[e].T_world_camera, &best->T_world_camera);
    if (matches.size() == 1) errors.first_timestamp_s = t;
    errors.last_timestamp_s = t;
  }
  errors.matched_frames = matches.size();
  if (matches.size() < 2) {
    if (why != nullptr) {
      *why = fmt::format("{} of the {} estimated poses match a true pose by timestamp (within {} s); at least 2 needed",
                         matches.size(), estimated.size(), timestamp_tolerance_s);
    }
    return std::nullopt;
  }

  const auto count = static_cast<Eigen::Index>(matches.size());
  Eigen::Matrix3Xd estimated_positions(3, count), true_positions(3, count);
  for (Eigen::Index n = 0; n < count; ++n) {
    estimated_positions.col(n) = matches[static_cast<std::size_t>(n)].first->translation();
    true_positions.col(n) = matches[static_cast<std::size_t>(n)].second->translation();
  }
  // Umeyama's closed form (Horn's for the rigid case; no scale), the TUM benchmark's choice.
  // It handles the reflection case; with collinear positions the rotation about the line is
  // arbitrary, but the residuals (all ATE depends on) are the same for every choice.
  const Eigen::Matrix4d T = Eigen::umeyama(estimated_positions, true_positions, false);
  errors.T_truth_estimate = Pose(Eigen::Matrix3d(T.topLeftCorner<3, 3>()), Eigen::Vector3d(T.topRightCorner<3, 1>()));
  double squares = 0.0;
  for (Eigen::Index n = 0; n < count; ++n) {
    const double residual =
        (errors.T_truth_estimate * Eigen::Vector3d(estimated_positions.col(n)) - true_positions.col(n)).norm();
    squares += residual * residual;
    errors.ate_max_m = std::max(errors.ate_max_m, residual);
  }
  errors.ate_rmse_m = std::sqrt(squares / static_cast<double>(count));

  const Pose& estimated_first = *matches.front().first;
  const Pose& estimated_last = *matches.back().first;
  const Pose& true_first = *matches.front().second;
  const Pose& true_last = *matches.back().second;
  const Pose E = (true_first.inverse() * true_last).inverse() * (estimated_first.inverse() * estimated_last);
  errors.loop_closure_error_m = E.translation().norm();
  errors.loop_closure_error_rad = E.angle_rad();
  return errors;
}

std::vector<StampedPose> truth_in_estimate_frame(const std::vector<StampedPose>& truth,
                                                 const TrajectoryErrors& errors) {
  const Pose T_estimate_truth = errors.T_truth_estimate.inverse();
  std::vector<StampedPose> out = truth;
  for (StampedPose& pose : out) pose.T_world_camera = T_estimate_truth * pose.T_world_camera;
  return out;
}

// ---------------------------------------------------------------------------------------
// Visibility and coverage

VisibilityMask::VisibilityMask(std::vector<Eigen::Vector3d> points, std::vector<Eigen::Vector3d> normals)
    : points_(std::move(points)), normals_(std::move(normals)), visible_(points_.size(), 0) {
  if (!normals_.empty() && normals_.size() != points_.size()) {
    throw_error(ErrorCode::kInvalidArgument, "visibility: {} normals for {} points", normals_.size(),
                points_.size());
  }
}

void VisibilityMask::add_frame(const CameraIntrinsics& camera, const Pose& T_object_camera, const Image32f& depth_m,
                               const Image8u& valid, double min_depth_tolerance_m) {
  if (depth_m.width() != camera.width || depth_m.height() != camera.height || valid.width() != camera.width ||
      valid.height() != camera.height) {
    throw_error(ErrorCode::kInvalidArgument,
                "visibility: depth {}x{} and valid {}x{} images do not match the {}x{} camera", depth_m.width(),
                depth_m.height(), valid.width(), valid.height(), camera.width, camera.height);
  }
  const Pose T_camera_object = T_object_camera.inverse();
  const Eigen::Vector3d centre = T_object_camera.translation();
  const auto count = static_cast<std::ptrdiff_t>(points_.size());
#pragma omp parallel for schedule(dynamic, 4096)
  for (std::ptrdiff_t n = 0; n < count; ++n) {
    const auto i = static_cast<std::size_t>(n);
    if (visible_[i] != 0) continue;
    if (!normals_.empty() && normals_[i].dot(centre - points_[i]) <= 0.0) continue;  // faces away
    const Eigen::Vector3d pc = T_camera_object * points_[i];
    Vec2d pixel{0.0, 0.0};
    if (!project(camera, Vec3d{pc.x(), pc.y(), pc.z()}, &pixel)) continue;
    const double x = std::round(pixel.x), y = std::round(pixel.y);
    if (!(x >= 0.0 && y >= 0.0 && x < camera.width && y < camera.height)) continue;
    const int px = static_cast<int>(x), py = static_cast<int>(y);
    if (valid(px, py) == 0) continue;
    const double z = static_cast<double>(depth_m(px, py));
    if (!(z > 0.0)) continue;
    // The pixel centre's surface is up to half a pixel away from the point: allow a slope of
    // ~80 degrees over 4 footprints, and never less than the caller's floor.
    const double tolerance = std::max(min_depth_tolerance_m, 4.0 * pc.z() / camera.fx);
    if (std::fabs(z - pc.z()) <= tolerance) visible_[i] = 1;
  }
}

std::size_t VisibilityMask::visible_count() const {
  return static_cast<std::size_t>(std::count(visible_.begin(), visible_.end(), std::uint8_t{1}));
}

Coverage coverage(const std::vector<Eigen::Vector3d>& reference, const std::vector<std::uint8_t>* mask,
                  const PointGrid& output, double radius_m) {
  if (mask != nullptr && mask->size() != reference.size()) {
    throw_error(ErrorCode::kInvalidArgument, "coverage: mask of {} for {} reference points", mask->size(),
                reference.size());
  }
  std::size_t considered = 0, covered = 0;
  const auto count = static_cast<std::ptrdiff_t>(reference.size());
#pragma omp parallel for schedule(dynamic, 4096) reduction(+ : considered, covered)
  for (std::ptrdiff_t n = 0; n < count; ++n) {
    const auto i = static_cast<std::size_t>(n);
    if (mask != nullptr && (*mask)[i] == 0) continue;
    ++considered;
    if (output.any_within(reference[i], radius_m)) ++covered;
  }
  return {considered, covered};
}

// ---------------------------------------------------------------------------------------
// Against a simulated recording

namespace {

double voxel_size_from_report(const std::string& result_folder) {
  const std::string path = result_folder + "/report.json";
  if (!exists(path)) return 0.0;
  nlohmann::json report;
  try {
    report = nlohmann::json::parse(read_file_text(path));
  } catch (const nlohmann::json::exception& error) {
    throw_error(ErrorCode::kFormat, "{}: not valid JSON ({})", path, error.what());
  }
  const auto found = report.find("voxel_size_m");
  if (found == report.end()) return 0.0;
  if (!found->is_number() || !(found->get<double>() > 0.0)) {
    throw_error(ErrorCode::kFormat, "{}: voxel_size_m is not a positive number", path);
  }
  return found->get<double>();
}

// T_object_world from the result's first pose and the true pose at the same timestamp.
bool first_pose_alignment(const std::string& result_folder, const std::string& truth_folder, Pose* T_object_world) {
  const std::string estimated_path = result_folder + "/trajectory.txt";
  const std::string truth_path = truth_folder + "/trajectory.txt";
  if (!exists(estimated_path) || !exists(truth_path)) return false;
  const std::vector<StampedPose> estimated = read_tum_trajectory(estimated_path);
  const std::vector<StampedPose> truth = read_tum_trajectory(truth_path);
  if (estimated.empty()) return false;
  for (const StampedPose& pose : truth) {
    if (std::fabs(pose.timestamp_s - estimated.front().timestamp_s) <= 1e-6) {
      *T_object_world = pose.T_world_camera * estimated.front().T_world_camera.inverse();
      return true;
    }
  }
  throw_error(ErrorCode::kInvalidArgument,
              "{}: its first timestamp {} s matches no ground-truth pose in {}; is the result from this recording?",
              estimated_path, estimated.front().timestamp_s, truth_path);
}

}  // namespace

Pose register_onto_surface(const std::vector<Eigen::Vector3d>& points, const sim::Scene& scene, double voxel_m,
                           const Pose& initial) {
  const std::size_t stride = std::max<std::size_t>(1, points.size() / 20000);
  std::vector<Eigen::Vector3d> sample;
  for (std::size_t i = 0; i < points.size(); i += stride) sample.push_back(points[i]);
  Pose T = initial;
  const double h = 1e-6;
  for (int iteration = 0; iteration < 30; ++iteration) {
    std::vector<double> residuals(sample.size());
    for (std::size_t i = 0; i < sample.size(); ++i) residuals[i] = scene.signed_distance(T * sample[i]);
    std::vector<double> magnitudes(residuals.size());
    for (std::size_t i = 0; i < residuals.size(); ++i) magnitudes[i] = std::fabs(residuals[i]);
    if (magnitudes.empty()) return initial;  // nothing to register
    std::nth_element(magnitudes.begin(), magnitudes.begin() + static_cast<std::ptrdiff_t>(magnitudes.size() / 2),
                     magnitudes.end());
    const double gate = std::max(2.0 * voxel_m, 3.0 * 1.4826 * magnitudes[magnitudes.size() / 2]);
    Eigen::Matrix<double, 6, 6> normal = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> gradient = Eigen::Matrix<double, 6, 1>::Zero();
    for (std::size_t i = 0; i < sample.size(); ++i) {
      if (!(std::fabs(residuals[i]) <= gate)) continue;
      const Eigen::Vector3d p = T * sample[i];
      Eigen::Vector3d n;
      for (int a = 0; a < 3; ++a) {
        Eigen::Vector3d step = Eigen::Vector3d::Zero();
        step[a] = h;
        n[a] = (scene.signed_distance(p + step) - scene.signed_distance(p - step)) / (2.0 * h);
      }
      // d sdf / d (rho, omega) of exp(twist) * p: n · (rho + omega × p).
      Eigen::Matrix<double, 6, 1> j;
      j << n, p.cross(n);
      normal += j * j.transpose();
      gradient += j * residuals[i];
    }
    const Eigen::Matrix<double, 6, 1> twist = -normal.ldlt().solve(gradient);
    if (!twist.allFinite()) break;
    T = Pose::exp(twist) * T;
    if (twist.head<3>().norm() < 1e-9 && twist.tail<3>().norm() < 1e-9) break;
  }
  return T;
}

EvalReport evaluate_result(const std::string& result_folder, const std::string& recording_folder,
                           const EvalOptions& options, const ProgressCallback& progress) {
  if (!(options.edge_band_voxels > 0.0) || !(options.coverage_radius_voxels > 0.0) || options.visibility_stride < 1 ||
      options.voxel_size_m < 0.0) {
    throw_error(ErrorCode::kInvalidArgument,
                "eval: edge band {} and coverage radius {} voxels must be positive, stride {} at least 1, voxel "
                "size {} m not negative",
                options.edge_band_voxels, options.coverage_radius_voxels, options.visibility_stride,
                options.voxel_size_m);
  }
  EvalReport report;
  report.result_folder = result_folder;
  report.recording_folder = recording_folder;
  const std::string cloud_path = result_folder + "/cloud.ply";
  if (!exists(result_folder)) {
    throw_error(ErrorCode::kNotFound, "result folder {} does not exist (a scan's output folder, e.g. sls scan --out)",
                result_folder);
  }
  if (!exists(cloud_path)) {
    throw_error(ErrorCode::kNotFound, "{} not found: the result folder must hold the fused cloud.ply", cloud_path);
  }
  const RecordingReader recording = RecordingReader::open(recording_folder);
  const std::string truth = recording.groundtruth_folder();
  if (truth.empty()) {
    throw_error(ErrorCode::kInvalidArgument,
                "{} has no ground truth: sls eval compares against a simulated recording (sls sim, sls scan --sim)",
                recording_folder);
  }
  for (const char* name : {"scene.json", "reference.ply"}) {
    if (!exists(truth + "/" + name)) {
      throw_error(ErrorCode::kNotFound, "{}/{} not found: the recording's ground truth is incomplete", truth, name);
    }
  }

  if (options.voxel_size_m > 0.0) {
    report.voxel_size_m = options.voxel_size_m;
    report.voxel_size_source = "option";
  } else {
    report.voxel_size_m = voxel_size_from_report(result_folder);
    report.voxel_size_source = "report.json";
    if (!(report.voxel_size_m > 0.0)) {
      throw_error(ErrorCode::kInvalidArgument,
                  "no voxel size: {}/report.json has no voxel_size_m; give it (sls eval --voxel-um, "
                  "sls_eval_config.voxel_size_m)", result_folder);
    }
  }
  report.edge_band_m = options.edge_band_voxels * report.voxel_size_m;
  report.coverage_radius_m = options.coverage_radius_voxels * report.voxel_size_m;

  const sim::Scene scene = sim::scene_from_json(read_file_text(truth + "/scene.json"));
  report.scene_name = scene.name();
  report.alignment = "none";
  if (options.align_first_pose && first_pose_alignment(result_folder, truth, &report.T_object_world)) {
    report.alignment = "first-pose";
  }
  // Trajectory figures need no scene: ATE aligns on its own, loop closure needs no alignment.
  const std::string estimated_trajectory = result_folder + "/trajectory.txt";
  if (!exists(estimated_trajectory)) {
    report.trajectory_note = "the result has no trajectory.txt";
  } else if (!exists(truth + "/trajectory.txt")) {
    report.trajectory_note = "the recording has no groundtruth/trajectory.txt";
  } else {
    report.trajectory = trajectory_errors(read_tum_trajectory(estimated_trajectory),
                                          read_tum_trajectory(truth + "/trajectory.txt"), &report.trajectory_note);
  }
  auto to_object = [&](const PointCloud& cloud) {
    std::vector<Eigen::Vector3d> points = positions_of(cloud);
    for (Eigen::Vector3d& p : points) p = report.T_object_world * p;
    return points;
  };

  const PointCloud cloud = read_ply_cloud(cloud_path);
  if (cloud.empty()) throw_error(ErrorCode::kInvalidArgument, "{} holds no points", cloud_path);
  if (options.register_to_surface) {
    report_progress(progress, {"register", 0, 1, ""});
    report.T_object_world =
        register_onto_surface(positions_of(cloud), scene, report.voxel_size_m, report.T_object_world);
    report.alignment = report.alignment == "none" ? "registered" : report.alignment + "+registered";
  }
  const std::vector<Eigen::Vector3d> points = to_object(cloud);
  report.cloud_points = points.size();
  report_progress(progress, {"c2c", 0, 1, ""});
  report.cloud = surface_errors(points, scene, report.edge_band_m,
                                options.keep_point_errors ? &report.cloud_point_errors_m : nullptr);
  if (exists(result_folder + "/mesh.ply")) {
    const TriangleMesh mesh = read_ply_mesh(result_folder + "/mesh.ply");
    report.mesh_vertices = mesh.vertices.size();
    if (!mesh.vertices.empty()) report.mesh = surface_errors(to_object(mesh.vertices), scene, report.edge_band_m);
  }
  report_progress(progress, {"c2c", 1, 1, ""});

  // Coverage over the reference points the recording saw.
  const PointCloud reference = read_ply_cloud(truth + "/reference.ply");
  report.reference_points = reference.size();
  const std::vector<Eigen::Vector3d> reference_points = positions_of(reference);
  std::vector<Eigen::Vector3d> reference_normals(reference.normals.size());
  for (std::size_t n = 0; n < reference.normals.size(); ++n) reference_normals[n] = reference.normals[n].cast<double>();

  std::vector<std::uint8_t> mask;
  const bool has_frames = exists(truth + "/trajectory.txt") && exists(truth + "/frames") && recording.has_calibration();
  if (has_frames) {
    const std::vector<StampedPose> poses = read_tum_trajectory(truth + "/trajectory.txt");
    const std::size_t frames = std::min(poses.size(), recording.frame_count());
    VisibilityMask visibility(reference_points, std::move(reference_normals));
    const CameraIntrinsics& camera = recording.calibration().camera;
    const auto stride = static_cast<std::size_t>(options.visibility_stride);
    for (std::size_t i = 0; i < frames; i += stride) {
      const std::string folder = fmt::format("{}/frames/{:06d}", truth, recording.frame(i).index);
      if (!exists(folder + "/depth.pfm") || !exists(folder + "/valid.png")) {
        throw_error(ErrorCode::kNotFound, "{}: depth.pfm or valid.png missing (ground truth incomplete)", folder);
      }
      visibility.add_frame(camera, poses[i].T_world_camera, read_pfm(folder + "/depth.pfm"),
                           read_png_u8(folder + "/valid.png"), report.coverage_radius_m);
      ++report.frames_checked;
      report_progress(progress, {"visibility", i + 1, frames, ""});
    }
    mask = visibility.visible();
    report.coverage_basis = "visible";
  } else {
    // No per-frame truth: the fused region, the output's bounding box grown by the radius.
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(HUGE_VAL), hi = Eigen::Vector3d::Constant(-HUGE_VAL);
    for (const Eigen::Vector3d& p : points) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    lo -= Eigen::Vector3d::Constant(report.coverage_radius_m);
    hi += Eigen::Vector3d::Constant(report.coverage_radius_m);
    mask.resize(reference_points.size());
    for (std::size_t n = 0; n < reference_points.size(); ++n) {
      const Eigen::Vector3d& p = reference_points[n];
      mask[n] = (p.array() >= lo.array()).all() && (p.array() <= hi.array()).all() ? 1 : 0;
    }
    report.coverage_basis = "bounding-box";
  }
  const PointGrid grid(points, report.coverage_radius_m);
  report.coverage = coverage(reference_points, &mask, grid, report.coverage_radius_m);
  return report;
}

}  // namespace sls::eval
