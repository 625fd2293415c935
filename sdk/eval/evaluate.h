// Quality of a fused model against a simulated recording's ground truth (DESIGN.md section
// 4), for `sls eval`, the C API (sls_eval.h), tests and benchmarks. Library sls_eval (sdk/eval):
// it needs the simulator's exact scene (drivers/sim), which the fusion library must not see.
//
// Definitions (all distances in metres here; `sls eval` prints µm):
//   c2c          for each output point p (cloud.ply, object frame): |sdf(p)|, the scene's
//                exact signed distance; mean, RMS, 95th percentile (nearest rank), max.
//   edge c2c     the same over the points within edge_band_voxels (3) voxels of a ground-truth
//                crease (knurl ridge and groove lines, cap outlines); absent for scenes
//                without creases (plane, sphere).
//   coverage     the fraction of the reference points (groundtruth/reference.ply: dense exact
//                samples) that have an output point within coverage_radius_voxels (2) voxels,
//                counting only reference points the recording saw: in some frame the point
//                faces the camera, projects onto a pixel whose ground truth is valid (visible
//                and lit), and that pixel's true depth is within max(coverage radius, 4
//                pixel footprints) of the point's depth (nothing in front of it). Without per-frame
//                ground truth, over the reference points inside the output's bounding box
//                grown by the radius (coverage_basis "bounding-box").
//   ate          absolute trajectory error, the TUM RGB-D benchmark's definition: the result's
//                camera positions (trajectory.txt) matched by timestamp to the true ones
//                (groundtruth/trajectory.txt, T_object_camera), rigidly aligned onto them
//                (Horn/Umeyama, rotation + translation, no scale: a metric scanner has no
//                scale freedom), then the RMS and max of the remaining position differences.
//   loop closure the error of the relative motion from the first to the last matched frame,
//                E = (T_true_first^-1 T_true_last)^-1 (T_est_first^-1 T_est_last): its
//                translation norm and rotation angle. Relative motions do not depend on either
//                trajectory's world frame, so no alignment enters. After a full turntable
//                revolution the last view is (nearly) the first again, so this is the drift
//                accumulated around the loop: what loop closure must remove.
// The output is taken to be in the recording's object frame (the frame of T_object_camera in
// groundtruth/trajectory.txt; `sls scan --poses groundtruth` fuses there). When the result
// holds trajectory.txt, its first pose is aligned to the true pose of the frame with the same
// timestamp, so a tracked scan that started from another frame is compared fairly.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "drivers/sim/scene.h"
#include "sdk/core/camera_model_shared.h"
#include "sdk/core/image.h"
#include "sdk/core/point_cloud.h"
#include "sdk/core/pose.h"
#include "sdk/core/progress.h"
#include "sdk/core/trajectory.h"

namespace sls::eval {

// Radius-limited nearest-neighbour queries over a fixed point set: a uniform grid of
// `cell_size_m` cells (sorted cell keys), so a query within one cell size reads 27 cells.
class PointGrid {
 public:
  // sls::Error(kInvalidArgument) for a cell size that is not positive, or points so far from
  // the origin that cell indices overflow (more than 2^20 cells out).
  PointGrid(std::vector<Eigen::Vector3d> points, double cell_size_m);

  std::size_t size() const { return points_.size(); }
  // The nearest point within max_distance_m of p: its index (and distance), or -1.
  std::ptrdiff_t nearest(const Eigen::Vector3d& p, double max_distance_m, double* distance_m = nullptr) const;
  bool any_within(const Eigen::Vector3d& p, double radius_m) const;

 private:
  std::uint64_t key_of(const Eigen::Vector3d& p, std::int64_t offset[3]) const;
  template <typename Visit>
  void visit_near(const Eigen::Vector3d& p, double radius_m, const Visit& visit) const;

  std::vector<Eigen::Vector3d> points_;  // sorted by cell
  std::vector<std::uint64_t> cell_keys_; // one per non-empty cell, ascending
  std::vector<std::uint32_t> cell_begin_;  // first point of each cell; one extra at the end
  double cell_size_m_ = 0.0;
};

struct DistanceStats {
  std::size_t count = 0;
  double mean_m = 0.0;
  double rms_m = 0.0;
  double p95_m = 0.0;  // nearest-rank 95th percentile
  double max_m = 0.0;
};

DistanceStats distance_stats(std::vector<double> distances_m);

struct SurfaceErrors {
  DistanceStats all;
  bool has_creases = false;
  DistanceStats edge;  // points within the edge band of a crease (count 0 without creases)
};

// c2c and edge c2c of object-frame points against the scene (OpenMP over points). With
// point_errors_m, also each point's |signed distance|, in the points' order (for heat maps).
SurfaceErrors surface_errors(const std::vector<Eigen::Vector3d>& points_object, const sim::Scene& scene,
                             double edge_band_m, std::vector<float>* point_errors_m = nullptr);

// Rigid point-to-plane registration of points onto the scene's surface, starting at
// `initial` (T_object_points): Gauss–Newton on the signed distance (its gradient by central
// differences), over up to 20 000 of the points, those within 3 robust σ of the surface (at
// least two voxels) counting. `sls eval --register`.
Pose register_onto_surface(const std::vector<Eigen::Vector3d>& points, const sim::Scene& scene, double voxel_m,
                           const Pose& initial);

// ATE and loop-closure error of an estimated trajectory against the truth (see above).
struct TrajectoryErrors {
  std::size_t matched_frames = 0;    // estimated poses with a true pose at the same timestamp
  std::size_t unmatched_frames = 0;  // estimated poses without one (not counted)
  double ate_rmse_m = 0.0;
  double ate_max_m = 0.0;
  // The rigid alignment found: p_truth ~ T_truth_estimate * p_estimate.
  Pose T_truth_estimate;
  double first_timestamp_s = 0.0;  // the matched frames the loop closure spans
  double last_timestamp_s = 0.0;
  double loop_closure_error_m = 0.0;
  double loop_closure_error_rad = 0.0;
};

// Timestamps match within this (both trajectories come from the same recording's frame
// list, printed in shortest exact form).
constexpr double kTimestampTolerance_s = 1e-6;

// nullopt (and *why set) when fewer than two estimated poses match a true one: neither figure
// means anything then. Timestamps may come in any order and either side may lack frames (lost
// frames in the estimate); matches are taken in the estimate's timestamp order.
std::optional<TrajectoryErrors> trajectory_errors(const std::vector<StampedPose>& estimated,
                                                  const std::vector<StampedPose>& truth, std::string* why = nullptr,
                                                  double timestamp_tolerance_s = kTimestampTolerance_s);

// The true trajectory moved into the estimate's world frame by the ATE alignment
// (T_estimate_truth = T_truth_estimate^-1), for plotting the two together.
std::vector<StampedPose> truth_in_estimate_frame(const std::vector<StampedPose>& truth,
                                                 const TrajectoryErrors& errors);

// Which reference points a recording's frames saw (see coverage above).
class VisibilityMask {
 public:
  // Reference points and their outward normals, object frame (normals may be empty: then no
  // facing test).
  VisibilityMask(std::vector<Eigen::Vector3d> points, std::vector<Eigen::Vector3d> normals);
  // Marks the points this frame sees. depth_m: the true camera-frame z per pixel (0: no
  // surface); valid: nonzero where the surface is visible and lit. Both camera-sized.
  void add_frame(const CameraIntrinsics& camera, const Pose& T_object_camera, const Image32f& depth_m,
                 const Image8u& valid, double min_depth_tolerance_m);
  const std::vector<std::uint8_t>& visible() const { return visible_; }
  std::size_t visible_count() const;

 private:
  std::vector<Eigen::Vector3d> points_;
  std::vector<Eigen::Vector3d> normals_;
  std::vector<std::uint8_t> visible_;
};

struct Coverage {
  std::size_t considered = 0;  // reference points counted (visible ones)
  std::size_t covered = 0;     // of those, with an output point within the radius
  double fraction() const { return considered > 0 ? static_cast<double>(covered) / static_cast<double>(considered) : 0.0; }
};

// Coverage of `reference` by the output points in `output` (a grid of them); `mask` (same
// length as reference, or null for all) selects the points that count.
Coverage coverage(const std::vector<Eigen::Vector3d>& reference, const std::vector<std::uint8_t>* mask,
                  const PointGrid& output, double radius_m);

struct EvalOptions {
  double voxel_size_m = 0.0;  // 0: from the result's report.json ("voxel_size_m")
  double edge_band_voxels = 3.0;
  double coverage_radius_voxels = 2.0;
  int visibility_stride = 1;  // test every n-th frame's visibility (paper-size recordings)
  bool align_first_pose = true;
  // Then register the cloud rigidly onto the exact surface (point-to-plane on its signed
  // distance): the shape's error alone, whatever frame the result's calibration defines (a
  // calibration's principal point traded for a small turn of the camera frame moves the whole
  // model). As CloudCompare's fine registration before the paper's C2C.
  bool register_to_surface = false;
  // Fill EvalReport::cloud_point_errors_m (one float per cloud point: 4 bytes a point).
  bool keep_point_errors = false;
};

struct EvalReport {
  std::string result_folder;
  std::string recording_folder;
  std::string scene_name;
  double voxel_size_m = 0.0;
  std::string voxel_size_source;  // "option" or "report.json"
  std::size_t cloud_points = 0;
  SurfaceErrors cloud;
  std::optional<SurfaceErrors> mesh;  // mesh.ply's vertices, when present
  std::size_t mesh_vertices = 0;
  double edge_band_m = 0.0;
  std::size_t reference_points = 0;
  Coverage coverage;
  std::string coverage_basis;  // "visible" or "bounding-box"
  double coverage_radius_m = 0.0;
  std::size_t frames_checked = 0;  // frames whose visibility was tested
  std::string alignment;           // "none", "first-pose", "registered" or "first-pose+registered"
  Pose T_object_world;             // applied to the output before comparing
  // With EvalOptions::keep_point_errors: |sdf| of each cloud.ply point after T_object_world,
  // in the file's point order (so the cloud as read, in its own world frame, can be coloured
  // by it). Empty otherwise.
  std::vector<float> cloud_point_errors_m;
  // ATE and loop closure, when RESULT/trajectory.txt and groundtruth/trajectory.txt exist and
  // at least two frames match; otherwise nullopt and trajectory_note says why.
  std::optional<TrajectoryErrors> trajectory;
  std::string trajectory_note;
};

// Evaluates RESULT (cloud.ply, optional mesh.ply, report.json, trajectory.txt) against the
// simulated recording REC. sls::Error naming the file and what to do: kNotFound (no cloud.ply,
// no recording, missing ground-truth files), kInvalidArgument (a recording without ground
// truth, an empty cloud, no voxel size anywhere, bad options), kFormat (corrupt files).
EvalReport evaluate_result(const std::string& result_folder, const std::string& recording_folder,
                           const EvalOptions& options, const ProgressCallback& progress = {});

// The figures shown side by side, with and without deformation (`sls eval`'s text, the
// report's table): their label, their key in the evaluation JSON, decimals and unit.
enum class FigureUnit { kMicrometres, kDegrees, kNone };
struct SideBySideFigure {
  const char* label;
  const char* key;
  int decimals;
  FigureUnit unit;
};
inline constexpr SideBySideFigure kSideBySideFigures[] = {
    {"C2C mean", "c2c_mean_um", 2, FigureUnit::kMicrometres},
    {"C2C RMS", "c2c_rms_um", 2, FigureUnit::kMicrometres},
    {"C2C p95", "c2c_p95_um", 2, FigureUnit::kMicrometres},
    {"edge C2C mean", "c2c_edge_mean_um", 2, FigureUnit::kMicrometres},
    {"coverage", "coverage", 4, FigureUnit::kNone},
    {"ATE RMSE", "ate_rmse_um", 2, FigureUnit::kMicrometres},
    {"loop closure error", "loop_closure_error_um", 2, FigureUnit::kMicrometres},
    {"loop closure angle", "loop_closure_error_deg", 4, FigureUnit::kDegrees}};

}  // namespace sls::eval
