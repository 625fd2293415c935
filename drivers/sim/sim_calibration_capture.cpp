#include "drivers/sim/sim_calibration_capture.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <optional>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "drivers/sim/noise_shared.h"
#include "drivers/sim/sim_capture.h"
#include "drivers/sim/sim_scanner.h"
#include "sdk/core/calibration.h"
#include "sdk/core/camera_model_shared.h"
#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/recording.h"
#include "sdk/core/trajectory.h"

namespace sls::sim {
namespace {

constexpr double kDegree = M_PI / 180.0;

// Hand poses (docs/simulator.md). Tilts of 18° and 28° (±2°), alternating, about in-plane
// axes whose directions go once round the circle, so views differ by up to ~50° about two
// axes and the focal length is observable; in-plane rotation small enough that the corner
// nearest the image's top-left stays the board's first (a 10 x 8 board is symmetric under
// 180°); depth well inside the ±5 mm depth of field. Across the field each board goes out
// from the centre perpendicular to its tilt axis (the direction its tilt foreshortens, so it
// gets furthest), to a corner of the field when that direction is within 30° of a diagonal,
// else to the middle of an edge, as far as the plate stays in view and lit with
// kHandReachMarginFraction of margin. The directions go round with the axes, so over the
// views the corners reach out to every edge and corner of the image, as calibration wants
// (distortion and the principal point are constrained by corners near the image's edges).
// How far is bounded by the plate's light border, which stays in view: the 12 default poses'
// corners span 78 % x 71 % of the image (test_calibration_capture.cpp).
constexpr double kHandTiltsDeg[2] = {28.0, 18.0};
constexpr double kHandTiltSpreadDeg = 2.0;
constexpr double kHandAzimuthSpreadRad = 0.2;
constexpr double kHandRollDeg = 8.0;
constexpr double kHandShiftDepthM = 1.5e-3;     // along the camera's axis
constexpr double kHandReachMarginFraction = 0.012;  // of the image (and DMD) size; the check asks 0.01

// Turntable mount: the board leans back 12° (so its plane is not parallel to the axis, and
// the axis is not in it), turned 3° in its plane, its face 0.5 mm in front of the axis;
// table angles spread over ±40° (it faces the camera at 0°): the projector, 25° to the side,
// then lights it at up to 65° incidence.
constexpr double kMountLeanBackDeg = 12.0;
constexpr double kMountRollDeg = 3.0;
constexpr double kMountFaceOffsetM = 0.5e-3;
constexpr double kTableHalfRangeDeg = 40.0;

// What every pose must keep (checked by make_calibration_rig): the plate at least 1 % of the
// image (and DMD) size from its edges, faces seen at < 80° from their normal, and depth
// within the ±5 mm usable depth of field (docs/simulator-optics.md).
constexpr double kEdgeMarginFraction = 0.01;
constexpr double kMaxIncidenceDeg = 80.0;
constexpr double kDepthOfFieldM = 5e-3;
// A ChArUco board may be larger than the field and leave it: what must stay in view and in
// the projector's light is its core, this share of its inner corners' span each way (centred),
// so the hand poses push its corners out to the image's edges (partial views).
constexpr double kCharucoCoreFraction = 0.5;

// The lenses of cameras 1, 2, 3 of a head (camera 0 has the rig's: k1 −0.3, p1 2e-4, p2
// −1e-4): barrel distortion and decentring of the same order, each its own, so that a
// calibration that mixed the cameras up would show in their truth figures.
struct SimCameraLens {
  double k1, p1, p2;
};
constexpr SimCameraLens kSimHeadLenses[kMaxSimCalibrationCameras - 1] = {
    {-0.25, -1e-4, 1.5e-4},
    {-0.2, 1e-4, 2e-4},
    {-0.35, -2e-4, -5e-5},
};

Eigen::Matrix3d rotation(double angle_rad, const Eigen::Vector3d& axis) {
  return Eigen::AngleAxisd(angle_rad, axis.normalized()).toRotationMatrix();
}

// The board frame facing the camera upright: x -> world +y (image right), y -> world −z
// (image down), z -> world −x (away from the camera, which looks along −x). A head of several
// cameras has the boards face the middle of them: this turned by `facing_rad` about the
// vertical (world z) through the focus.
Eigen::Matrix3d facing_camera(double facing_rad) {
  Eigen::Matrix3d r;
  r.col(0) = Eigen::Vector3d::UnitY();
  r.col(1) = -Eigen::Vector3d::UnitZ();
  r.col(2) = -Eigen::Vector3d::UnitX();
  return rotation(facing_rad, Eigen::Vector3d::UnitZ()) * r;
}

Eigen::Vector3d board_centre(const ChessboardParameters& board) {
  return {0.5 * (board.inner_corners_x - 1) * board.square, 0.5 * (board.inner_corners_y - 1) * board.square, 0.0};
}

// T_world_board for a board centred at `centre_world`, turned by `turn` from facing the
// cameras (facing_camera).
Pose board_pose(const ChessboardParameters& board, const Eigen::Vector3d& centre_world, const Eigen::Matrix3d& turn,
                double facing_rad) {
  const Eigen::Matrix3d r = facing_camera(facing_rad) * turn;
  return Pose(r, centre_world - r * board_centre(board));
}

// T_table_board: the fixed mount. The world origin is on the axis (world = turntable frame).
// The board stands where the head focuses: on the axis for a head set up for flat targets,
// 16.1 mm in front of it for the knurled screw's (its surface).
Pose turntable_mount(const ChessboardParameters& board, const Eigen::Vector3d& focus, double facing_rad) {
  const Eigen::Vector3d centre(std::max(kMountFaceOffsetM, focus.x()), 0.0, focus.z());
  return board_pose(board, centre,
                    rotation(-kMountLeanBackDeg * kDegree, Eigen::Vector3d::UnitX()) *
                        rotation(kMountRollDeg * kDegree, Eigen::Vector3d::UnitZ()),
                    facing_rad);
}

// Commanded angle of turntable pose `index` of `count`: spread over ±half_range_deg, rounded
// to whole steps and reported in [0°, 360°) as the table does.
double turntable_angle_deg(const SimRig& rig, int index, int count, double half_range_deg) {
  const double angle = count > 1 ? -half_range_deg + 2.0 * half_range_deg * index / (count - 1) : 0.0;
  const int steps = rig.turntable.steps_per_revolution;
  const long step = std::lround(angle / 360.0 * steps);
  return rig.step_angle_deg(static_cast<int>(((step % steps) + steps) % steps));
}

struct PlateView {
  std::vector<Eigen::Vector2d> camera_px;
  std::vector<Eigen::Vector2d> projector_px;
};

// Exact camera and projector pixels (lens distortion included) of board-frame points.
PlateView project_board_points(const SimRig& rig, const Pose& T_camera_board,
                               const std::vector<Eigen::Vector3d>& points_board) {
  const Pose T_projector_board = rig.T_camera_projector.inverse() * T_camera_board;
  PlateView view;
  for (const Eigen::Vector3d& p : points_board) {
    const Eigen::Vector3d c = T_camera_board * p, q = T_projector_board * p;
    Vec2d camera{NAN, NAN}, projector{NAN, NAN};
    project(rig.camera, Vec3d{c.x(), c.y(), c.z()}, &camera);
    project(rig.projector, Vec3d{q.x(), q.y(), q.z()}, &projector);
    view.camera_px.emplace_back(camera.x, camera.y);
    view.projector_px.emplace_back(projector.x, projector.y);
  }
  return view;
}

std::vector<Eigen::Vector3d> inner_corners_board(const ChessboardParameters& board) {
  std::vector<Eigen::Vector3d> corners;
  for (int j = 0; j < board.inner_corners_y; ++j) {
    for (int i = 0; i < board.inner_corners_x; ++i) corners.emplace_back(i * board.square, j * board.square, 0.0);
  }
  return corners;
}

Pose T_camera_board(const SimRig& rig, const ChessboardParameters& board, int frame) {
  return rig.T_world_camera.inverse() * rig.T_world_object(frame) * board_frame_in_object(board);
}

bool inside(const Eigen::Vector2d& px, int width, int height, double margin_fraction) {
  const double mx = margin_fraction * width, my = margin_fraction * height;
  return px.x() >= mx && px.y() >= my && px.x() <= width - 1 - mx && px.y() <= height - 1 - my;
}

// Whether the board at T_camera_board shows the whole plate inside the image and the
// projector's light (by `margin_fraction` of their sizes), its face turned to both by less
// than kMaxIncidenceDeg, within the depth of field. When not, *why (optional) says where.
bool plate_fits(const SimRig& rig, const ChessboardParameters& board, const Pose& T_camera, double margin_fraction,
                std::string* why) {
  // The plate's outline in the board frame, margin included; of a ChArUco board only its core
  // (kCharucoCoreFraction of the inner corners' span, centred), the rest may leave the view.
  double left = -board.square - board.margin, top = -board.square - board.margin;
  double right = board.inner_corners_x * board.square + board.margin;
  double bottom = board.inner_corners_y * board.square + board.margin;
  if (board.is_charuco()) {
    const double w = (board.inner_corners_x - 1) * board.square, h = (board.inner_corners_y - 1) * board.square;
    left = 0.5 * (1.0 - kCharucoCoreFraction) * w;
    right = w - left;
    top = 0.5 * (1.0 - kCharucoCoreFraction) * h;
    bottom = h - top;
  }
  const std::vector<Eigen::Vector3d> outline = {{left, top, 0.0}, {right, top, 0.0}, {right, bottom, 0.0},
                                                {left, bottom, 0.0}};
  const PlateView view = project_board_points(rig, T_camera, outline);
  // The printed face's normal is −z of the board frame.
  const Eigen::Vector3d face_normal = T_camera.rotation() * -Eigen::Vector3d::UnitZ();
  const double min_cos = std::cos(kMaxIncidenceDeg * kDegree);
  for (std::size_t i = 0; i < outline.size(); ++i) {
    const Eigen::Vector3d p = T_camera * outline[i];
    const bool seen = inside(view.camera_px[i], rig.camera.width, rig.camera.height, margin_fraction) &&
                      face_normal.dot(-p.normalized()) > min_cos;
    const bool lit = inside(view.projector_px[i], rig.projector.width, rig.projector.height, margin_fraction) &&
                     face_normal.dot((rig.T_camera_projector.translation() - p).normalized()) > min_cos;
    const bool sharp = std::fabs(p.z() - rig.optics.working_distance_m) < kDepthOfFieldM;
    if (!(seen && lit && sharp)) {
      if (why != nullptr) {
        *why = fmt::format(
            "the {:.2f} x {:.2f} mm board{} leaves the camera's view, the projector's light or the depth of field "
            "(corner at camera pixel ({:.1f}, {:.1f}), projector pixel ({:.1f}, {:.1f}), {:.2f} mm from the camera)",
            (right - left) * 1e3, (bottom - top) * 1e3, board.is_charuco() ? " (ChArUco core)" : "", view.camera_px[i].x(), view.camera_px[i].y(),
            view.projector_px[i].x(), view.projector_px[i].y(), p.z() * 1e3);
      }
      return false;
    }
  }
  return true;
}

// plate_fits for every camera of the head (each rig one camera with the same projector).
bool plate_fits_all(const std::vector<SimRig>& rigs, const ChessboardParameters& board, const Pose& T_world_board,
                    double margin_fraction) {
  return std::all_of(rigs.begin(), rigs.end(), [&](const SimRig& rig) {
    return plate_fits(rig, board, rig.T_world_camera.inverse() * T_world_board, margin_fraction, nullptr);
  });
}

// Throws when frame `frame` shows part of the plate outside the image or the projector's
// light, or turns its face away from either, or leaves the depth of field (naming the camera
// in a head of several).
void check_board_in_view(const std::vector<SimRig>& rigs, const ChessboardParameters& board, int frame) {
  for (std::size_t k = 0; k < rigs.size(); ++k) {
    std::string why;
    if (!plate_fits(rigs[k], board, T_camera_board(rigs[k], board, frame), kEdgeMarginFraction, &why)) {
      throw_error(ErrorCode::kInvalidArgument, "calibration frame {}{}: {}", frame,
                  rigs.size() > 1 ? fmt::format(", camera {}", k) : "", why);
    }
  }
}

// Hand pose `index` of `count` (see kHandTiltsDeg): T_world_board, in view of every camera.
Pose hand_pose(const std::vector<SimRig>& rigs, const ChessboardParameters& board, const Eigen::Vector3d& focus,
               double facing_rad, std::uint64_t seed, int index, int count) {
  NoiseKey key;
  key.seed = seed;
  key.frame = static_cast<std::uint32_t>(index);
  NoiseStream draws = make_noise_stream(key, kUserStream + 1);  // kUserStream: the table's jitter
  const auto symmetric = [&draws](double half_range) { return half_range * (2.0 * draws.uniform() - 1.0); };
  const double tilt = (kHandTiltsDeg[index % 2] + symmetric(kHandTiltSpreadDeg)) * kDegree;
  const double nominal_azimuth = 2.0 * M_PI * index / count;
  const double azimuth = nominal_azimuth + symmetric(kHandAzimuthSpreadRad);
  const double roll = symmetric(kHandRollDeg) * kDegree;
  const double depth = symmetric(kHandShiftDepthM);
  const Eigen::Vector3d tilt_axis(std::cos(azimuth), std::sin(azimuth), 0.0);
  const Eigen::Matrix3d turn = rotation(tilt, tilt_axis) * rotation(roll, Eigen::Vector3d::UnitZ());
  // Where in the field: the direction perpendicular to the nominal tilt axis, (cos, sin) of
  // azimuth + 90° in the image (x right, y down), stretched onto the border of a square and
  // clipped to it, so that directions within 30° of a diagonal go to that corner of the field:
  // every image corner gets views, every edge its middle. Then scaled to the reach in x and y
  // (how far the plate goes towards that side and still fits), backed off until it fits.
  const double direction = nominal_azimuth + 0.5 * M_PI;
  const double side_x = std::clamp(2.0 * std::cos(direction), -1.0, 1.0);
  const double side_y = std::clamp(2.0 * std::sin(direction), -1.0, 1.0);
  const Eigen::Vector3d centre = focus + rotation(facing_rad, Eigen::Vector3d::UnitZ()) * Eigen::Vector3d(depth, 0.0, 0.0);
  // Image x is world +y, image y world −z (of a camera the boards face).
  const Eigen::Matrix3d facing = rotation(facing_rad, Eigen::Vector3d::UnitZ());
  const auto pose_at = [&](double x, double y) {
    return board_pose(board, centre + facing * Eigen::Vector3d(0.0, x, -y), turn, facing_rad);
  };
  const auto fits = [&](double x, double y) { return plate_fits_all(rigs, board, pose_at(x, y), kHandReachMarginFraction); };
  if (!fits(0.0, 0.0)) return pose_at(0.0, 0.0);  // left to check_board_in_view's report
  // The largest t in [0, limit] with fits(t) (those that fit are an interval from 0).
  const auto farthest = [](double limit, const auto& fits_at) {
    double fitting = 0.0, failing = limit;
    if (fits_at(failing)) return failing;
    for (int i = 0; i < 40; ++i) {
      const double mid = 0.5 * (fitting + failing);
      (fits_at(mid) ? fitting : failing) = mid;
    }
    return fitting;
  };
  const double field = 0.02;  // beyond any field of view here
  const double reach_x = side_x == 0.0 ? 0.0 : farthest(field, [&](double t) { return fits(side_x * t, 0.0); });
  const double reach_y = side_y == 0.0 ? 0.0 : farthest(field, [&](double t) { return fits(0.0, side_y * t); });
  const double scale = farthest(1.0, [&](double t) { return fits(t * side_x * reach_x, t * side_y * reach_y); });
  return pose_at(scale * side_x * reach_x, scale * side_y * reach_y);
}

nlohmann::json points_json(const std::vector<Eigen::Vector2d>& points) {
  nlohmann::json list = nlohmann::json::array();
  for (const Eigen::Vector2d& p : points) list.push_back({p.x(), p.y()});
  return list;
}

nlohmann::json matrix_json(const Pose& pose) {
  const Eigen::Matrix4d m = pose.matrix();
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
  return rows;
}

// The colour of the square between corners 0, 1, cols and cols + 1 (the scene's pattern).
bool square_beyond_origin_is_dark(const ChessboardParameters& board) {
  if (board.is_charuco()) {  // square (1, 1) of the board frame's table
    return board.charuco.dark_square.at(static_cast<std::size_t>(board.inner_corners_x + 1 + 1)) != 0;
  }
  const ChessboardT<double> shape{board.inner_corners_x + 1, board.inner_corners_y + 1, board.square, board.margin,
                                  board.albedo_dark, board.albedo_light};
  const Eigen::Vector3d centre = board_frame_in_object(board) * Eigen::Vector3d(0.5 * board.square, 0.5 * board.square, 0.0);
  return chessboard_square(shape, centre.x(), centre.y()) >= 0 &&
         chessboard_albedo(shape, centre.x(), centre.y()) == board.albedo_dark;
}

std::string board_json(const ChessboardParameters& board) {
  nlohmann::json object_points = nlohmann::json::array();
  for (const Eigen::Vector3d& p : inner_corners_board(board)) object_points.push_back({p.x(), p.y(), p.z()});
  nlohmann::json json = {
      {"kind", "chessboard"},
      {"inner_corners", {board.inner_corners_x, board.inner_corners_y}},
      {"squares", {board.inner_corners_x + 1, board.inner_corners_y + 1}},
      {"square_m", board.square},
      {"margin_m", board.margin},
      {"albedo_dark", board.albedo_dark},
      {"albedo_light", board.albedo_light},
      {"origin", "first inner corner"},
      {"frame",
       "OpenCV object points: origin at the inner corner top-left when the board faces the camera upright, x along "
       "the rows (image right), y down the board (image down), z into the board (away from the printed face)"},
      {"order", "row by row, x fastest: corner k = (i * square_m, j * square_m, 0), i = k % cols, j = k / cols"},
      {"object_points_m", object_points},
      {"T_object_board", matrix_json(board_frame_in_object(board))},
      {"square_beyond_origin", square_beyond_origin_is_dark(board) ? "dark" : "light"},
  };
  if (board.is_charuco()) {  // what `sls calibrate` reads (calib/calibrate_capture.cpp)
    json["kind"] = "charuco";
    json["marker_m"] = board.charuco.marker;
    json["dictionary"] = board.charuco.dictionary;
    json["marker_cells"] = board.charuco.cells;
    json["order"] = "ChArUco corner ids: row by row, x fastest, as the chessboard's";
  }
  return json.dump(2);
}

}  // namespace

ChessboardParameters charuco_calibration_board_geometry() {
  ChessboardParameters board;
  board.inner_corners_x = 11;
  board.inner_corners_y = 8;
  board.square = 1.2e-3;
  board.margin = 0.6e-3;
  return board;
}

ChessboardParameters calibration_board() {
  ChessboardParameters board;
  board.inner_corners_x = 9;
  board.inner_corners_y = 7;
  board.square = 0.6e-3;
  board.margin = 0.6e-3;
  return board;
}

Pose board_frame_in_object(const ChessboardParameters& board) {
  // Scene squares span x in [−(cols+1) s / 2, (cols+1) s / 2], y likewise; the board frame's
  // origin is the inner corner of least x and greatest y, its y and z the scene's flipped.
  const double s = board.square;
  const Eigen::Vector3d origin(-0.5 * (board.inner_corners_x + 1) * s + s, 0.5 * (board.inner_corners_y + 1) * s - s,
                               0.0);
  const Eigen::Matrix3d flip = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
  return Pose(flip, origin);
}

std::vector<SimRig> make_calibration_rigs(const SimCalibrationOptions& options) {
  if (options.hand_poses < 0 || options.turntable_poses < 0 || options.hand_poses + options.turntable_poses < 1 ||
      options.hand_poses > 1000 || options.turntable_poses > 1000) {
    throw_error(ErrorCode::kInvalidArgument, "{} hand and {} turntable poses (each 0 .. 1000, at least one view)",
                options.hand_poses, options.turntable_poses);
  }
  if (options.cameras < 1 || options.cameras > kMaxSimCalibrationCameras) {
    throw_error(ErrorCode::kInvalidArgument,
                "{} cameras: the simulated head has places for 1 to {} (round the projector: left, right, above, "
                "below)",
                options.cameras, kMaxSimCalibrationCameras);
  }
  RigOptions rig_options = options.rig;
  rig_options.frames = kCalibrationTurntableSteps;
  rig_options.mount_tilt_deg = 0.0;  // the board's mount is the capture's own
  rig_options.mount_offset_m = 0.0;
  // The head as set up for its object: camera and projector where make_rig puts them to scan
  // it, so the turntable axis calibrated here is the one that object's scans use.
  SimRig rig = make_rig(rig_options, make_scene(options.head_object));

  // Columns and rows: the calibration needs both projector coordinates of every corner. The
  // row period gives the columns' fringe pitch on the object (DLP4500 rows are half a column).
  GrayPhaseOptions patterns;
  patterns.projector_width = rig.projector.width;
  patterns.projector_height = rig.projector.height;
  patterns.rows = true;
  patterns.row_phase_period_px = static_cast<int>(std::lround(
      patterns.phase_period_px * rig.optics.projector.pixel_pitch_x_m / rig.optics.projector.pixel_pitch_y_m));
  rig.patterns = make_gray_phase_pattern_set(patterns);

  const Eigen::Vector3d focus = rig.T_world_camera * Eigen::Vector3d(0.0, 0.0, rig.optics.working_distance_m);
  std::vector<SimRig> rigs = {rig};
  // More cameras stand round the projector, each at the triangulation angle from it (the
  // head's layout, docs/simulator.md): camera 1 mirrors camera 0 across it (twice the angle
  // round the vertical through the focus), cameras 2 and 3 stand above and below it (at the
  // projector's azimuth, the angle up or down about the horizontal through the focus), so a
  // head of four is a cross round the projector. Each has a lens (another distortion) and a
  // sensor of its own. The boards then face the projector, the middle of them.
  double facing_rad = 0.0;
  if (options.cameras >= 2) {
    const double angle = rig.optics.triangulation_angle_rad;
    facing_rad = angle;
    const auto about_focus = [&focus](const Eigen::Matrix3d& turn) { return Pose(turn, focus - turn * focus); };
    const Eigen::Matrix3d to_projector = rotation(angle, Eigen::Vector3d::UnitZ());
    // The horizontal through the focus, square to the projector's line of sight.
    const Eigen::Vector3d across = Eigen::Vector3d::UnitZ().cross(to_projector * Eigen::Vector3d::UnitX());
    const Eigen::Matrix3d turns[kMaxSimCalibrationCameras - 1] = {
        rotation(2.0 * angle, Eigen::Vector3d::UnitZ()),
        rotation(-angle, across) * to_projector,  // above: camera 0's centre is on +x
        rotation(angle, across) * to_projector,   // below
    };
    for (int k = 1; k < options.cameras; ++k) {
      const SimCameraLens& lens = kSimHeadLenses[k - 1];
      SimRig camera = rig;
      camera.T_world_camera = about_focus(turns[k - 1]) * rig.T_world_camera;
      camera.T_camera_projector = camera.T_world_camera.inverse() * rig.T_world_camera * rig.T_camera_projector;
      camera.camera.k1 = lens.k1;
      camera.camera.p1 = lens.p1;
      camera.camera.p2 = lens.p2;
      // A sensor of its own: noise keyed by (seed, frame, pattern, pixel) would otherwise repeat
      // camera 0's, pixel for pixel. The table's jitter (turntable.seed) is one motion for all.
      camera.noise_seed = rig.noise_seed ^ (std::uint64_t{0x9e3779b97f4a7c15} * static_cast<std::uint64_t>(k));
      rigs.push_back(camera);
    }
  }

  const ChessboardParameters& board = options.board;
  const Pose T_object_board = board_frame_in_object(board);
  std::vector<ObjectPlacement> placements;
  for (int i = 0; i < options.hand_poses; ++i) {
    const Pose T_world_board = hand_pose(rigs, board, focus, facing_rad, options.rig.seed, i, options.hand_poses);
    placements.push_back({std::nullopt, T_world_board * T_object_board.inverse()});
  }
  const Pose T_table_object = turntable_mount(board, focus, facing_rad) * T_object_board.inverse();
  // The widest span up to ±40° over which the board stays whole in view and lit: a board
  // standing 16 mm off the axis swings out of the 12 mm field within a few degrees.
  const auto table_views = [&](double half_range_deg) {
    std::vector<ObjectPlacement> views;
    for (int i = 0; i < options.turntable_poses; ++i) {
      views.push_back({turntable_angle_deg(rig, i, options.turntable_poses, half_range_deg), T_table_object});
    }
    return views;
  };
  const auto table_views_fit = [&](double half_range_deg) {
    for (SimRig trial : rigs) {
      trial.placements = table_views(half_range_deg);
      for (int frame = 0; frame < static_cast<int>(trial.placements.size()); ++frame) {
        if (!plate_fits(trial, board, T_camera_board(trial, board, frame), kEdgeMarginFraction * 1.2, nullptr)) {
          return false;
        }
      }
    }
    return true;
  };
  double half_range_deg = kTableHalfRangeDeg;
  if (options.turntable_poses > 1 && !table_views_fit(half_range_deg)) {
    double lo = 0.0, hi = kTableHalfRangeDeg;
    for (int iteration = 0; iteration < 30; ++iteration) {
      const double mid = 0.5 * (lo + hi);
      (table_views_fit(mid) ? lo : hi) = mid;
    }
    half_range_deg = lo;
  }
  for (const ObjectPlacement& view : table_views(half_range_deg)) placements.push_back(view);
  for (SimRig& camera_rig : rigs) {
    camera_rig.placements = placements;
    camera_rig.T_table_object = T_table_object;
  }
  for (int frame = 0; frame < static_cast<int>(placements.size()); ++frame) check_board_in_view(rigs, board, frame);
  return rigs;
}

SimRig make_calibration_rig(const SimCalibrationOptions& options, const Scene& board_scene) {
  (void)board_scene;
  return make_calibration_rigs(options).front();
}

ScannerCalibration head_calibration(const std::vector<SimRig>& rigs) {
  ScannerCalibration calibration = rigs.front().calibration();
  for (std::size_t k = 1; k < rigs.size(); ++k) {
    calibration.additional_cameras.push_back(
        {rigs[k].camera, rigs.front().T_world_camera.inverse() * rigs[k].T_world_camera, 0.0});
  }
  if (rigs.size() > 1) {
    calibration.description = fmt::format("slscan simulator, preset {}, a head of {} cameras (exact calibration of the "
                                          "simulated rig)",
                                          rigs.front().preset, rigs.size());
  }
  return calibration;
}

namespace {

// One camera's capture: its recording in `folder`, its truth (that camera with the projector)
// in the recording's groundtruth/. Progress counts frames from `frames_before` of `frames_all`.
SimRecordingSummary write_camera_capture(const std::string& folder, SimRig rig_built,
                                         const SimCalibrationOptions& options, const Device& device,
                                         const ProgressCallback& progress, int frames_before, int frames_all) {
  Scene board_scene = make_chessboard_scene(options.board);
  const std::string uri = fmt::format("sim://chessboard?preset={}&seed={}&noise={}&projector={}", rig_built.preset,
                                      options.rig.seed, options.rig.noise ? 1 : 0, options.rig.projector);
  const std::shared_ptr<SimScanner> scanner =
      SimScanner::create(std::move(rig_built), std::move(board_scene), device, uri);
  const SimRig& rig = scanner->rig();

  RecordingInfo info;
  info.device = {scanner->uri(), "slscan simulated scanner (calibration capture)", "SIM-0"};
  info.camera = {rig.camera.width, rig.camera.height, rig.optics.camera_sensor.bit_depth};
  info.pattern_set_json = pattern_set_to_json(rig.patterns);
  info.images_per_frame = static_cast<int>(rig.patterns.size());
  info.has_groundtruth = true;
  RecordingWriter writer = RecordingWriter::create(folder, info, std::nullopt);  // made uncalibrated
  const std::string truth_folder = writer.groundtruth_folder();
  write_calibration(truth_folder + "/calibration.yml", rig.calibration());
  write_file_atomic(truth_folder + "/board.json", board_json(options.board));
  write_file_atomic(truth_folder + "/scene.json", scanner->scene().to_json());
  write_file_atomic(truth_folder + "/rig.json", rig_json(rig));

  SimDevices devices = start_sim_devices(*scanner);
  const std::vector<Eigen::Vector3d> corners = inner_corners_board(options.board);
  const int frames = static_cast<int>(rig.placements.size());
  std::vector<StampedPose> board_poses;
  nlohmann::json capture = {{"hand_poses", options.hand_poses},
                            {"turntable_poses", options.turntable_poses},
                            {"turntable_steps_per_revolution", rig.turntable.steps_per_revolution},
                            {"angles", "degrees as the table reports them, in [0, 360); true = commanded + jitter"},
                            {"frames", nlohmann::json::array()}};
  for (int frame = 0; frame < frames; ++frame) {
    const std::optional<double>& angle = rig.placements[static_cast<std::size_t>(frame)].commanded_angle_deg;
    scanner->place_object(frame);
    FrameMetadata metadata;
    if (angle) {
      devices.turntable->move_to_deg(*angle, kSimDeviceTimeout);
      metadata.turntable_angle_deg = devices.turntable->position_deg();
    }
    std::vector<Image16u> images =
        capture_pattern_stack(devices, static_cast<int>(rig.patterns.size()), &metadata.timestamp_ns);

    // Ground truth first: every frame the manifest lists has all of its own.
    const GroundTruthFrame truth = scanner->ground_truth();
    const std::string frame_folder = write_frame_ground_truth(truth, truth_folder);
    const Pose T_camera = T_camera_board(rig, options.board, frame);
    const PlateView view = project_board_points(rig, T_camera, corners);
    const nlohmann::json frame_corners = {{"frame", frame},
                                          {"pixel_convention", "(0, 0) is the centre of the top-left pixel"},
                                          {"camera_px", points_json(view.camera_px)},
                                          {"projector_px", points_json(view.projector_px)}};
    write_file_atomic(frame_folder + "/corners.json", frame_corners.dump(1));
    board_poses.push_back({static_cast<double>(metadata.timestamp_ns) * 1e-9, T_camera});
    write_tum_trajectory(truth_folder + "/board_poses.txt", board_poses);
    capture["frames"].push_back({{"index", frame},
                                 {"kind", angle ? "turntable" : "hand"},
                                 {"timestamp_ns", metadata.timestamp_ns},
                                 {"commanded_angle_deg", angle ? nlohmann::json(*angle) : nlohmann::json()},
                                 {"true_angle_deg", angle ? nlohmann::json(truth.true_angle_deg) : nlohmann::json()}});
    write_file_atomic(truth_folder + "/capture.json", capture.dump(2));

    writer.append_frame(images, metadata);
    report_progress(progress, {"capture", static_cast<std::size_t>(frames_before + frame + 1),
                               static_cast<std::size_t>(frames_all), ""});
  }
  stop_sim_devices(devices);
  writer.close();

  return recording_summary(*scanner, frames, info.images_per_frame, truth_folder);
}

}  // namespace

SimRecordingSummary write_sim_calibration_recording(const std::string& folder, const SimCalibrationOptions& options,
                                                    const Device& device, const ProgressCallback& progress) {
  const std::vector<SimRig> rigs = make_calibration_rigs(options);
  const int frames = static_cast<int>(rigs.front().placements.size());
  if (rigs.size() == 1) return write_camera_capture(folder, rigs.front(), options, device, progress, 0, frames);
  // A head of several cameras: one recording per camera (calib/multi_camera_capture.h reads
  // this layout), the head's exact calibration beside them.
  std::error_code error;
  if (std::filesystem::exists(folder, error) && !std::filesystem::is_empty(folder, error)) {
    throw_error(ErrorCode::kInvalidArgument,
                "{}: the folder exists and is not empty; refusing to write a calibration capture into it", folder);
  }
  create_directories(folder + "/groundtruth");
  write_calibration(folder + "/groundtruth/calibration.yml", head_calibration(rigs));
  SimRecordingSummary summary;
  for (std::size_t k = 0; k < rigs.size(); ++k) {
    const SimRecordingSummary camera =
        write_camera_capture(head_camera_folder(folder, k), rigs[k], options, device, progress,
                             static_cast<int>(k) * frames, static_cast<int>(rigs.size()) * frames);
    if (k == 0) summary = camera;
  }
  summary.groundtruth_folder = folder + "/groundtruth";
  return summary;
}

}  // namespace sls::sim
