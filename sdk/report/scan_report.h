// A self-contained HTML report of one scan (OUT/report.html with PNG figures beside it), for
// people: the summary of report.json (frames, lost frames and why, time per stage, fusion
// settings), the quality figures of `sls eval` when there are any, shaded renders of the
// fused cloud, an error heat map against ground truth, and the camera trajectory. With online
// deformation (report["deformation"]["enabled"]): the graph and the loop closure, the quality
// with and without deformation side by side, the trajectory's error (or correction) per frame
// before and after, and a heat map of how far deformation moved each point.
// Library sls_report (sdk/report); it knows nothing of `sls scan`'s internals,
// everything comes in through ScanReportInputs.
//
// The renders are a CPU splatting renderer (no GPU, no mesh needed): every point is drawn as
// a disc about one point spacing wide into an orthographic z-buffer and shaded from its
// normal with a Lambertian key light and a raking light from the side, which brings out
// fine relief (knurls, ridges) that frontal light flattens.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "sdk/eval/evaluate.h"
#include "sdk/core/point_cloud.h"
#include "sdk/core/trajectory.h"

namespace sls::report {

// A frame that was not fused. Its marker on the trajectory plot goes where the camera was:
// the true pose at timestamp_s when there is a true trajectory (or truth[frame] when the
// timestamp is NaN and truth holds one pose per recording frame), otherwise the last
// estimated pose before timestamp_s.
struct LostFrame {
  std::size_t frame = 0;
  double timestamp_s = std::numeric_limits<double>::quiet_NaN();
  std::string reason;
};

struct ScanReportInputs {
  nlohmann::json report;                // sls scan's report.json object; any key may be missing
  // The final cloud in the world frame (normals used when present; with deformation its float
  // property "correction", how far each point moved in metres, gives the correction heat map).
  const PointCloud* cloud = nullptr;
  std::vector<StampedPose> trajectory;  // estimated T_world_camera per fused frame
  // With online deformation: the same frames' poses as tracked, before the deformation
  // (`trajectory` then holds them deformed). Empty otherwise.
  std::vector<StampedPose> trajectory_undeformed;
  // Empty if none; already in the estimate's world frame (eval::truth_in_estimate_frame).
  std::vector<StampedPose> truth;
  std::vector<float> point_errors_m;               // empty, or one per cloud point (heat map)
  const eval::EvalReport* evaluation = nullptr;    // sls eval's figures, optional
  // Empty: the markers come from report["lost_frames"] ({frame, reason}) with truth[frame].
  std::vector<LostFrame> lost_frames;
  std::string title = "Scan report";
  int image_size_px = 800;  // longer side of each render
};

// What was written (absolute or as given: out_dir + "/" + name).
struct ScanReportFiles {
  std::string html;
  std::vector<std::string> images;
};

// Writes OUT/report.html and its PNGs (report_view_*.png, report_error_*.png, and with
// deformation report_correction_*.png) atomically, creating OUT. sls::Error
// (kInvalidArgument) for point errors whose count differs from the cloud's, kIo when OUT
// cannot be written.
ScanReportFiles write_scan_report_html(const std::string& out_dir, const ScanReportInputs& inputs);

// ---------------------------------------------------------------------------------------
// The pieces, public for tests and other figures.

// An orthographic view: looking along `forward` (eye to object), `up` is the image's up.
struct View {
  std::string name;
  Eigen::Vector3d forward = -Eigen::Vector3d::UnitZ();
  Eigen::Vector3d up = Eigen::Vector3d::UnitY();
};

// Three views about the cloud's symmetry axis, which is up in each: two from the side, 90
// degrees apart, and one obliquely from above. The axis is the principal axis whose extent
// differs most from the other two (turned parts: the longest for a screw, the shortest for a
// ring), pointing to +z when it is mostly vertical (a turntable's axis).
std::vector<View> principal_views(const PointCloud& cloud);

struct RgbImage {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgb;      // width*height*3
  std::vector<std::uint8_t> covered;  // width*height: 1 where a point was drawn
  std::size_t covered_count() const;
  std::array<std::uint8_t, 3> at(int x, int y) const;
};

struct SplatOptions {
  int size_px = 800;            // the longer image side; the cloud fills it less a margin
  double splat_radius_m = 0.0;  // 0: from the point spacing (estimated)
  // Heat map: colour points by point_errors_m over [0, error_max_m] instead of a material.
  const std::vector<float>* point_errors_m = nullptr;
  double error_max_m = 0.0;
};

// The point spacing the splat size follows: sqrt(surface area / points), the
// area counted as occupied cells of a grid about four points per cell coarse.
double estimate_point_spacing(const PointCloud& cloud);

RgbImage render_cloud(const PointCloud& cloud, const View& view, const SplatOptions& options = {});

// Viridis (matplotlib's perceptually uniform map) at t in [0, 1] (clamped).
std::array<std::uint8_t, 3> viridis(double t);

// Nearest-rank 95th percentile of the errors, the heat map's top; never 0 (1 um floor).
double heat_map_max_m(const std::vector<float>& point_errors_m);

// An inline SVG of camera positions: top view (the trajectory's own plane: a turntable
// circle appears round) and side view (along the plane: the axis points up).
std::string trajectory_svg(const std::vector<StampedPose>& trajectory, const std::vector<StampedPose>& truth,
                           const std::vector<LostFrame>& lost_frames);

// An inline SVG line chart over the frames of the trajectory before and after deformation.
// With a true trajectory (at least two poses matching by timestamp): each trajectory's
// position error against the truth per frame, each rigidly aligned onto the truth as the ATE
// is (eval::trajectory_errors), so the curves' RMS are the two ATEs. Otherwise the correction
// per frame: the distance between the deformed and the tracked camera position (matched by
// timestamp). `frame_numbers`: the recording frame of each pose of `deformed` (the x axis);
// empty or of another length: 0, 1, 2, ... (fused frames). Says so when there is nothing to
// draw.
std::string deformation_chart_svg(const std::vector<StampedPose>& deformed,
                                  const std::vector<StampedPose>& undeformed,
                                  const std::vector<StampedPose>& truth,
                                  const std::vector<std::size_t>& frame_numbers = {});

}  // namespace sls::report
