// The simulator's calibration capture (drivers/sim/sim_calibration_capture.h): the board in
// view and lit at every pose and preset, the recording's files, the exact corners where the
// images show them, the poses' tilts, and turntable views related by the exact axis.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "drivers/sim/sim_calibration_capture.h"
#include "drivers/sim/sim_capture.h"
#include "sdk/core/calibration.h"
#include "sdk/core/camera_model_shared.h"
#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/recording.h"
#include "sdk/core/trajectory.h"
#include "tests/support/test_support.h"
#include "tests/unit/sim/sim_test_rig.h"

namespace sls::sim {
namespace {

constexpr double kDegree = M_PI / 180.0;

nlohmann::json read_json(const std::string& path) { return nlohmann::json::parse(read_file_text(path)); }

std::vector<Eigen::Vector2d> points(const nlohmann::json& list) {
  std::vector<Eigen::Vector2d> out;
  for (const nlohmann::json& p : list) out.emplace_back(p[0].get<double>(), p[1].get<double>());
  return out;
}

// The smallest distance between neighbouring corners: one square in pixels.
double square_px(const std::vector<Eigen::Vector2d>& corners, int cols, int rows) {
  double smallest = HUGE_VAL;
  for (int j = 0; j < rows; ++j) {
    for (int i = 0; i < cols; ++i) {
      const Eigen::Vector2d& p = corners[static_cast<std::size_t>(j * cols + i)];
      if (i + 1 < cols) smallest = std::min(smallest, (corners[static_cast<std::size_t>(j * cols + i + 1)] - p).norm());
      if (j + 1 < rows) smallest = std::min(smallest, (corners[static_cast<std::size_t>((j + 1) * cols + i)] - p).norm());
    }
  }
  return smallest;
}

// Every corner at least one square (in that view's pixels) inside a width x height image.
void expect_inside_with_a_square_of_margin(const std::vector<Eigen::Vector2d>& corners, int cols, int rows,
                                           int width, int height, const std::string& what) {
  const double margin = square_px(corners, cols, rows);
  EXPECT_GT(margin, 3.0) << what;
  for (std::size_t k = 0; k < corners.size(); ++k) {
    const Eigen::Vector2d& p = corners[k];
    ASSERT_TRUE(p.x() >= margin && p.y() >= margin && p.x() <= width - 1 - margin && p.y() <= height - 1 - margin)
        << what << ": corner " << k << " at (" << p.x() << ", " << p.y() << "), margin " << margin;
  }
}

double bilinear(const Image16u& image, const Eigen::Vector2d& p) {
  const int x = static_cast<int>(std::floor(p.x())), y = static_cast<int>(std::floor(p.y()));
  const double fx = p.x() - x, fy = p.y() - y;
  return (1 - fx) * (1 - fy) * image(x, y) + fx * (1 - fy) * image(x + 1, y) + (1 - fx) * fy * image(x, y + 1) +
         fx * fy * image(x + 1, y + 1);
}

TEST(SimCalibrationCapture, EveryPoseKeepsTheWholeBoardInViewAndLitAtEveryPresetAndProjector) {
  const Scene board = make_chessboard_scene(calibration_board());
  const ChessboardParameters parameters = calibration_board();
  const std::pair<std::string, std::string> rigs[] = {
      {"ci", "dlpc350"}, {"demo", "dlpc350"}, {"paper", "dlpc350"}, {"ci", "1080p"}};
  for (const auto& [preset, projector_kind] : rigs) {
    for (std::uint64_t seed = 1; seed <= 100; ++seed) {
      SimCalibrationOptions options;
      options.rig.preset = preset;
      options.rig.projector = projector_kind;
      options.rig.seed = seed;
      options.hand_poses = 16;
      options.turntable_poses = 9;
      const SimRig rig = make_calibration_rig(options, board);
      ASSERT_EQ(rig.placements.size(), 25u);
      for (int frame = 0; frame < 25; ++frame) {
        // Corners from the exact poses, independently of the capture's own projection.
        const Pose T_camera_board =
            rig.T_world_camera.inverse() * rig.T_world_object(frame) * board_frame_in_object(parameters);
        const Pose T_projector_board = rig.T_camera_projector.inverse() * T_camera_board;
        std::vector<Eigen::Vector2d> camera, projector;
        for (const Eigen::Vector3d& corner_object : board.chessboard_corners()) {
          const Eigen::Vector3d corner = board_frame_in_object(parameters).inverse() * corner_object;
          const Eigen::Vector3d c = T_camera_board * corner, q = T_projector_board * corner;
          Vec2d uv, st;
          ASSERT_TRUE(project(rig.camera, Vec3d{c.x(), c.y(), c.z()}, &uv));
          ASSERT_TRUE(project(rig.projector, Vec3d{q.x(), q.y(), q.z()}, &st));
          camera.emplace_back(uv.x, uv.y);
          projector.emplace_back(st.x, st.y);
        }
        const std::string what = fmt::format("{} {} seed {} frame {}", preset, projector_kind, seed, frame);
        expect_inside_with_a_square_of_margin(camera, 9, 7, rig.camera.width, rig.camera.height, what + " camera");
        expect_inside_with_a_square_of_margin(projector, 9, 7, rig.projector.width, rig.projector.height,
                                              what + " projector");
      }
    }
  }
  // The scans' 1.2 mm board does not fit: refused, not captured half out of view.
  SimCalibrationOptions too_big;
  too_big.rig.preset = "ci";
  too_big.board = ChessboardParameters{};
  EXPECT_THROW(make_calibration_rig(too_big, make_chessboard_scene(too_big.board)), Error);
  SimCalibrationOptions none;
  none.hand_poses = 0;
  none.turntable_poses = 0;
  EXPECT_THROW(make_calibration_rig(none, board), Error);
}

// A head of two cameras: the second mirrors the first across the projector (twice the 25°
// triangulation angle round the focus), the same placements for both, every pose in view and
// lit for both (make_calibration_rigs checks each camera), the exact head calibration with
// both; one camera is the one-camera capture unchanged; five cameras are refused.
TEST(SimCalibrationCapture, ASecondCameraMirrorsTheFirstAcrossTheProjector) {
  for (const char* preset : {"ci", "demo", "paper"}) {
    SimCalibrationOptions options;
    options.rig.preset = preset;
    options.cameras = 2;
    const std::vector<SimRig> rigs = make_calibration_rigs(options);
    ASSERT_EQ(rigs.size(), 2u);
    ASSERT_EQ(rigs[1].placements.size(), 19u);
    for (std::size_t i = 0; i < rigs[0].placements.size(); ++i) {
      EXPECT_EQ(rigs[0].placements[i].mount.matrix(), rigs[1].placements[i].mount.matrix());
      EXPECT_EQ(rigs[0].placements[i].commanded_angle_deg, rigs[1].placements[i].commanded_angle_deg);
    }
    const ScannerCalibration head = head_calibration(rigs);
    ASSERT_EQ(head.camera_count(), 2);
    const Pose& T_camera0_camera1 = head.additional_cameras[0].T_camera0_camera;
    EXPECT_NEAR(T_camera0_camera1.angle_rad() / kDegree, 50.0, 1e-9) << preset;
    const double working_distance = rigs[0].optics.working_distance_m;
    EXPECT_NEAR(T_camera0_camera1.translation().norm(), 2.0 * working_distance * std::sin(25.0 * kDegree), 1e-12);
    // The projector halfway: the same distance from both cameras, each pair 25° apart.
    EXPECT_NEAR(rigs[1].T_camera_projector.translation().norm(), rigs[0].T_camera_projector.translation().norm(),
                1e-12);
    EXPECT_NEAR(rigs[1].T_camera_projector.angle_rad() / kDegree, 25.0, 1e-9);
    EXPECT_NE(head.additional_cameras[0].intrinsics.k1, head.camera.k1);  // a lens of its own
    EXPECT_NE(rigs[1].noise_seed, rigs[0].noise_seed);                     // and a sensor
    EXPECT_EQ(rigs[1].turntable.seed, rigs[0].turntable.seed);             // the same table
    EXPECT_NO_THROW(head.validate());
  }
  SimCalibrationOptions one;
  one.rig.preset = "ci";
  const SimRig alone = make_calibration_rig(one, make_chessboard_scene(one.board));
  const std::vector<SimRig> head_of_one = make_calibration_rigs(one);
  ASSERT_EQ(head_of_one.size(), 1u);
  for (std::size_t i = 0; i < alone.placements.size(); ++i) {
    EXPECT_EQ(alone.placements[i].mount.matrix(), head_of_one[0].placements[i].mount.matrix());
  }
  SimCalibrationOptions five = one;
  five.cameras = 5;
  EXPECT_THROW(make_calibration_rigs(five), Error);
}

// Heads of three and four cameras: cameras 0 and 1 are the two-camera head's (place, lens,
// sensor), camera 2 stands above the projector and camera 3 below it, each the 25°
// triangulation angle from it (their axes acos(cos² 25°) = 34.8° from camera 0's), each with a lens and
// a sensor of its own, the table one motion for all; every pose in view of every camera (the
// rigs are refused otherwise) at every preset.
TEST(SimCalibrationCapture, ThirdAndFourthCamerasStandAboveAndBelowTheProjector) {
  for (const char* preset : {"ci", "demo", "paper"}) {
    SimCalibrationOptions two;
    two.rig.preset = preset;
    two.cameras = 2;
    const std::vector<SimRig> pair = make_calibration_rigs(two);
    for (const int count : {3, 4}) {
      SimCalibrationOptions options = two;
      options.cameras = count;
      const std::vector<SimRig> rigs = make_calibration_rigs(options);
      ASSERT_EQ(rigs.size(), static_cast<std::size_t>(count));
      const std::string what = fmt::format("{} {} cameras", preset, count);
      for (std::size_t k = 0; k < 2; ++k) {
        EXPECT_EQ(rigs[k].T_world_camera.matrix(), pair[k].T_world_camera.matrix()) << what;
        EXPECT_EQ(rigs[k].camera.k1, pair[k].camera.k1) << what;
        EXPECT_EQ(rigs[k].noise_seed, pair[k].noise_seed) << what;
      }
      const Eigen::Vector3d focus =
          rigs[0].T_world_camera * Eigen::Vector3d(0.0, 0.0, rigs[0].optics.working_distance_m);
      const ScannerCalibration head = head_calibration(rigs);
      EXPECT_EQ(head.camera_count(), count);
      EXPECT_NO_THROW(head.validate());
      for (std::size_t k = 2; k < rigs.size(); ++k) {
        EXPECT_NEAR(rigs[k].T_camera_projector.angle_rad() / kDegree, 25.0, 1e-9) << what;
        // Its optical axis acos(cos² 25°) from camera 0's (25° round, then 25° up or down);
        // the rotation between them turns by acos((2 cos 25° + cos² 25° − 1) / 2) = 35.2°, its
        // image upright (no roll about its own axis: image x stays horizontal).
        const Eigen::Matrix3d R = head.additional_cameras[k - 1].T_camera0_camera.rotation();
        EXPECT_NEAR(R.col(2).z(), std::pow(std::cos(25.0 * kDegree), 2), 1e-12) << what;
        const double c = std::cos(25.0 * kDegree);
        EXPECT_NEAR(head.additional_cameras[k - 1].T_camera0_camera.angle_rad(),
                    std::acos((2.0 * c + c * c - 1.0) / 2.0), 1e-9)
            << what;
        EXPECT_NEAR((rigs[k].T_world_camera.rotation() * Eigen::Vector3d::UnitX()).z(), 0.0, 1e-12) << what;
        // At the working distance from the focus, above (camera 2) or below (camera 3) it.
        const Eigen::Vector3d centre = rigs[k].T_world_camera.translation();
        EXPECT_NEAR((centre - focus).norm(), rigs[0].optics.working_distance_m, 1e-12) << what;
        EXPECT_NEAR(centre.z() - focus.z(), (k == 2 ? 1.0 : -1.0) * rigs[0].optics.working_distance_m *
                                                std::sin(25.0 * kDegree),
                    1e-12)
            << what;
        EXPECT_EQ(rigs[k].turntable.seed, rigs[0].turntable.seed);
      }
      for (std::size_t a = 0; a < rigs.size(); ++a) {
        for (std::size_t b = a + 1; b < rigs.size(); ++b) {
          EXPECT_NE(rigs[a].camera.k1, rigs[b].camera.k1) << what << " lenses " << a << " " << b;
          EXPECT_NE(rigs[a].noise_seed, rigs[b].noise_seed) << what << " sensors " << a << " " << b;
        }
        for (std::size_t i = 0; i < rigs[0].placements.size(); ++i) {
          EXPECT_EQ(rigs[a].placements[i].mount.matrix(), rigs[0].placements[i].mount.matrix()) << what;
        }
      }
    }
  }
}

// Over the default 12 hand poses the corners reach out over the whole image, as calibration
// wants (distortion and the principal point are constrained by corners near the image's
// edges): every image quadrant holds corners of several views, the corners' bounding box spans
// most of the image, and each image corner has board corners near it. How near is bounded by
// the plate's light border, which must stay in view (the detector's quiet zone, checked by
// make_calibration_rig): an inner corner lies two squares (0.6 mm square + 0.6 mm border)
// inside the plate's edge, 10 % of the 12 mm width and 13 % of the 9 mm height (less the
// foreshortening of a tilt), so the bounding box cannot pass ~80 % x 74 %. Measured: 78 % x
// 71 %; the nearest board corner 14 % from an image corner's edges, up to 21 % where the
// ±8° in-plane turn of the corner views takes their outermost corner inwards.
TEST(SimCalibrationCapture, HandPosesCoverTheWholeImage) {
  const Scene board = make_chessboard_scene(calibration_board());
  const ChessboardParameters parameters = calibration_board();
  const std::pair<std::string, std::string> rigs[] = {
      {"ci", "dlpc350"}, {"demo", "dlpc350"}, {"paper", "dlpc350"}, {"ci", "1080p"}};
  for (const auto& [preset, projector_kind] : rigs) {
    double least_width = 1.0, least_height = 1.0, farthest_corner = 0.0;
    int fewest_views_per_quadrant = 1000;
    for (std::uint64_t seed = 1; seed <= 20; ++seed) {
      SimCalibrationOptions options;
      options.rig.preset = preset;
      options.rig.projector = projector_kind;
      options.rig.seed = seed;
      const SimRig rig = make_calibration_rig(options, board);
      ASSERT_EQ(options.hand_poses, 12);
      const double width = rig.camera.width, height = rig.camera.height;
      Eigen::Vector2d low(HUGE_VAL, HUGE_VAL), high(-HUGE_VAL, -HUGE_VAL);
      int views_in_quadrant[4] = {};
      double nearest[4] = {HUGE_VAL, HUGE_VAL, HUGE_VAL, HUGE_VAL};  // per image corner, as a share of the image
      for (int frame = 0; frame < options.hand_poses; ++frame) {
        const Pose T_camera_board =
            rig.T_world_camera.inverse() * rig.T_world_object(frame) * board_frame_in_object(parameters);
        bool in_quadrant[4] = {};
        for (const Eigen::Vector3d& corner_object : board.chessboard_corners()) {
          const Eigen::Vector3d c = T_camera_board * (board_frame_in_object(parameters).inverse() * corner_object);
          Vec2d uv{0.0, 0.0};
          ASSERT_TRUE(project(rig.camera, Vec3d{c.x(), c.y(), c.z()}, &uv));
          const Eigen::Vector2d p(uv.x, uv.y);
          low = low.cwiseMin(p);
          high = high.cwiseMax(p);
          const bool right = p.x() > 0.5 * (width - 1), below = p.y() > 0.5 * (height - 1);
          in_quadrant[(below ? 2 : 0) + (right ? 1 : 0)] = true;
          // Distance to image corner q (0 top-left, 1 top-right, 2 bottom-left, 3 bottom-right),
          // the larger of the two edge distances, as shares of the width and height.
          const double dx[2] = {(p.x() + 0.5) / width, (width - 0.5 - p.x()) / width};
          const double dy[2] = {(p.y() + 0.5) / height, (height - 0.5 - p.y()) / height};
          for (int q = 0; q < 4; ++q) nearest[q] = std::min(nearest[q], std::max(dx[q % 2], dy[q / 2]));
        }
        for (int q = 0; q < 4; ++q) views_in_quadrant[q] += in_quadrant[q] ? 1 : 0;
      }
      least_width = std::min(least_width, (high.x() - low.x()) / width);
      least_height = std::min(least_height, (high.y() - low.y()) / height);
      for (int q = 0; q < 4; ++q) {
        farthest_corner = std::max(farthest_corner, nearest[q]);
        fewest_views_per_quadrant = std::min(fewest_views_per_quadrant, views_in_quadrant[q]);
      }
    }
    std::printf("%s %s: corners' bounding box at least %.1f %% of the width, %.1f %% of the height; every image "
                "corner has a board corner within %.1f %% of both its edges; every quadrant corners of %d views\n",
                preset.c_str(), projector_kind.c_str(), 100 * least_width, 100 * least_height,
                100 * farthest_corner, fewest_views_per_quadrant);
    EXPECT_GE(least_width, 0.77) << preset << " " << projector_kind;
    EXPECT_GE(least_height, 0.70) << preset << " " << projector_kind;
    EXPECT_LE(farthest_corner, 0.23) << preset << " " << projector_kind;
    EXPECT_GE(fewest_views_per_quadrant, 6) << preset << " " << projector_kind;
  }
}

// A head set up for the knurled screw focuses on its surface, 16.1 mm in front of the axis:
// the capture calibrates that rig (the axis its scans use), with the table views' board at
// the focus and their span cut to what keeps it in the 12 mm field.
TEST(SimCalibrationCapture, TheHeadIsTheOneSetUpForItsObject) {
  SimCalibrationOptions options;
  options.rig.preset = "demo";
  ASSERT_EQ(options.head_object, "knurled-screw");
  const SimRig rig = make_calibration_rig(options, make_chessboard_scene(options.board));
  RigOptions scan_options;
  scan_options.preset = "demo";
  const SimRig scan = make_rig(scan_options, make_scene("knurled-screw"));
  const ScannerCalibration exact = rig.calibration(), scanned = scan.calibration();
  ASSERT_TRUE(exact.turntable && scanned.turntable);
  EXPECT_LT((exact.turntable->point_camera - scanned.turntable->point_camera).norm(), 1e-12);
  EXPECT_LT((exact.turntable->direction_camera - scanned.turntable->direction_camera).norm(), 1e-12);
  EXPECT_LT((exact.T_camera_projector.translation() - scanned.T_camera_projector.translation()).norm(), 1e-12);
  double lo = 360.0, hi = -360.0;
  for (const ObjectPlacement& placement : rig.placements) {
    if (!placement.commanded_angle_deg) continue;
    const double angle = std::remainder(*placement.commanded_angle_deg, 360.0);
    lo = std::min(lo, angle);
    hi = std::max(hi, angle);
  }
  std::printf("table views over %.2f .. %.2f deg\n", lo, hi);
  EXPECT_GT(hi - lo, 10.0);
  EXPECT_LT(hi - lo, 80.0);
}

TEST(SimCalibrationCapture, TheTurntableMustBeAtAPlacementsAngle) {
  SimCalibrationOptions options;
  options.rig.preset = "ci";
  options.rig.camera_width = 64;
  options.hand_poses = 1;
  options.turntable_poses = 2;
  const std::shared_ptr<SimScanner> scanner = calibration_scanner(options);
  SimDevices devices = start_sim_devices(*scanner);
  std::int64_t timestamp = 0;
  EXPECT_THROW(capture_pattern_stack(devices, 1, &timestamp), Error);  // nothing placed yet
  scanner->place_object(0);
  EXPECT_NO_THROW(capture_pattern_stack(devices, 1, &timestamp));  // by hand: any table angle
  scanner->place_object(1);
  EXPECT_THROW(capture_pattern_stack(devices, 1, &timestamp), Error);  // the table still at 0°
  devices.turntable->move_to_deg(*scanner->rig().placements[1].commanded_angle_deg, kSimDeviceTimeout);
  EXPECT_NO_THROW(capture_pattern_stack(devices, 1, &timestamp));
  EXPECT_THROW(scanner->place_object(3), Error);
}

TEST(SimCalibrationCapture, WritesAnUncalibratedRecordingWithTheExactCalibrationAsTruth) {
  test::TemporaryDirectory dir;
  SimCalibrationOptions options;
  options.rig.preset = "ci";
  options.hand_poses = 4;
  options.turntable_poses = 3;
  options.head_object = "chessboard";  // focused on the axis: table views over ±40°
  const SimRecordingSummary summary =
      write_sim_calibration_recording(dir.file("rec"), options, Device::cpu(), {});
  EXPECT_EQ(summary.frames, 7);
  EXPECT_EQ(summary.images_per_frame, 42);  // white, black, columns and rows: Gray 6 + 6 inverses, 8 phase each

  const RecordingReader reader = RecordingReader::open(dir.file("rec"));
  ASSERT_EQ(reader.frame_count(), 7u);
  EXPECT_FALSE(reader.has_calibration());
  EXPECT_FALSE(std::filesystem::exists(dir.file("rec/calibration.yml")));
  const std::string truth = reader.groundtruth_folder();
  for (const char* name : {"calibration.yml", "board.json", "board_poses.txt", "capture.json", "rig.json", "scene.json"}) {
    EXPECT_TRUE(std::filesystem::exists(truth + "/" + name)) << name;
  }
  const PatternSet patterns = pattern_set_from_json(reader.info().pattern_set_json);
  EXPECT_EQ(patterns.patterns[0].kind, PatternKind::kWhite);
  EXPECT_EQ(patterns.patterns[1].kind, PatternKind::kBlack);
  EXPECT_TRUE(std::any_of(patterns.patterns.begin(), patterns.patterns.end(),
                          [](const PatternDesc& p) { return p.axis == PatternAxis::kRows; }));

  const ScannerCalibration calibration = read_calibration(truth + "/calibration.yml");
  ASSERT_TRUE(calibration.turntable.has_value());
  const nlohmann::json board = read_json(truth + "/board.json");
  const int cols = board["inner_corners"][0], rows = board["inner_corners"][1];
  const double square = board["square_m"];
  EXPECT_EQ(cols, 9);
  EXPECT_EQ(rows, 7);
  EXPECT_EQ(board["object_points_m"].size(), 63u);
  const nlohmann::json capture = read_json(truth + "/capture.json");
  const std::vector<StampedPose> poses = read_tum_trajectory(truth + "/board_poses.txt");
  ASSERT_EQ(poses.size(), 7u);
  ASSERT_EQ(capture["frames"].size(), 7u);

  bool jittered = false;
  for (std::size_t frame = 0; frame < 7; ++frame) {
    SCOPED_TRACE("frame " + std::to_string(frame));
    const nlohmann::json& entry = capture["frames"][frame];
    const bool hand = frame < 4;
    EXPECT_EQ(entry["kind"], hand ? "hand" : "turntable");
    EXPECT_EQ(reader.frame(frame).turntable_angle_deg.has_value(), !hand);
    EXPECT_EQ(entry["commanded_angle_deg"].is_null(), hand);
    if (!hand) {
      EXPECT_EQ(*reader.frame(frame).turntable_angle_deg, entry["commanded_angle_deg"].get<double>());
      const double jitter = entry["true_angle_deg"].get<double>() - entry["commanded_angle_deg"].get<double>();
      EXPECT_LT(std::fabs(jitter), 5 * options.rig.angle_jitter_deg);
      jittered = jittered || jitter != 0.0;
    }

    // corners.json: the board's corners projected with the exact calibration.
    const nlohmann::json corners = read_json(fmt::format("{}/frames/{:06d}/corners.json", truth, frame));
    const std::vector<Eigen::Vector2d> camera = points(corners["camera_px"]);
    const std::vector<Eigen::Vector2d> projector = points(corners["projector_px"]);
    ASSERT_EQ(camera.size(), 63u);
    ASSERT_EQ(projector.size(), 63u);
    const Pose T_projector_camera = calibration.T_camera_projector.inverse();
    for (std::size_t k = 0; k < 63; ++k) {
      const Eigen::Vector3d corner(static_cast<double>(k % 9) * square, static_cast<double>(k / 9) * square, 0.0);
      const Eigen::Vector3d c = poses[frame].T_world_camera * corner, q = T_projector_camera * c;
      Vec2d uv, st;
      ASSERT_TRUE(project(calibration.camera, Vec3d{c.x(), c.y(), c.z()}, &uv));
      ASSERT_TRUE(project(calibration.projector, Vec3d{q.x(), q.y(), q.z()}, &st));
      EXPECT_NEAR(uv.x, camera[k].x(), 1e-6);
      EXPECT_NEAR(uv.y, camera[k].y(), 1e-6);
      EXPECT_NEAR(st.x, projector[k].x(), 1e-6);
      EXPECT_NEAR(st.y, projector[k].y(), 1e-6);
    }
    expect_inside_with_a_square_of_margin(camera, cols, rows, calibration.camera.width, calibration.camera.height,
                                          "camera");
    // Corner 0 is the board's corner nearest the image's top-left, as detectors order them.
    for (const std::size_t other : {8u, 54u, 62u}) EXPECT_LT(camera[0].norm(), camera[other].norm());
    expect_inside_with_a_square_of_margin(projector, cols, rows, calibration.projector.width,
                                          calibration.projector.height, "projector");

    // The white image shows a chessboard corner at every exact corner: around corner (i, j)
    // the squares towards (+x, +y) and (−x, −y) share a colour, the other two the other,
    // which alternates with i + j; board.json says which the first is.
    const Image16u white = reader.load_image(frame, 0);
    const double light_first = board["square_beyond_origin"] == "light" ? 1.0 : -1.0;
    for (int j = 0; j < rows; ++j) {
      for (int i = 0; i < cols; ++i) {
        const std::size_t k = static_cast<std::size_t>(j * cols + i);
        const Eigen::Vector2d p = camera[k];
        // Along the board's axes in the image, from the neighbouring corners.
        const Eigen::Vector2d along_x = (i + 1 < cols ? camera[k + 1] - p : p - camera[k - 1]) * 0.35;
        const Eigen::Vector2d along_y = (j + 1 < rows ? camera[k + 9] - p : p - camera[k - 9]) * 0.35;
        const double same = bilinear(white, p + along_x + along_y) + bilinear(white, p - along_x - along_y);
        const double other = bilinear(white, p + along_x - along_y) + bilinear(white, p - along_x + along_y);
        const double parity = (i + j) % 2 == 0 ? 1.0 : -1.0;
        // Dark squares reflect 0.1, light 0.9: the difference is most of the light level.
        EXPECT_GT(light_first * parity * (same - other), 0.5 * std::max(same, other)) << "corner " << k;
      }
    }
  }
  EXPECT_TRUE(jittered);

  // Hand poses tilt the board about two axes, by more than 20° between some views.
  double max_tilt_deg = 0.0;
  Eigen::Vector3d low = Eigen::Vector3d::Constant(1.0), high = Eigen::Vector3d::Constant(-1.0);
  for (std::size_t a = 0; a < 4; ++a) {
    const Eigen::Vector3d normal = poses[a].T_world_camera.rotation().col(2);
    low = low.cwiseMin(normal);
    high = high.cwiseMax(normal);
    for (std::size_t b = 0; b < a; ++b) {
      const Eigen::Vector3d other = poses[b].T_world_camera.rotation().col(2);
      max_tilt_deg = std::max(max_tilt_deg, std::acos(std::clamp(normal.dot(other), -1.0, 1.0)) / kDegree);
    }
  }
  EXPECT_GT(max_tilt_deg, 20.0);
  EXPECT_GT(high.x() - low.x(), std::sin(10.0 * kDegree));  // about the image's vertical axis
  EXPECT_GT(high.y() - low.y(), std::sin(10.0 * kDegree));  // and its horizontal one

  // Turntable views: each consecutive pair differs by a rotation about the exact axis, by the
  // true angle between them (the jitter included).
  const TurntableAxis& axis = *calibration.turntable;
  for (std::size_t frame = 5; frame < 7; ++frame) {
    const Pose motion = poses[frame].T_world_camera * poses[frame - 1].T_world_camera.inverse();
    const Eigen::AngleAxisd rotation(motion.rotation());
    double turned_deg = capture["frames"][frame]["true_angle_deg"].get<double>() -
                        capture["frames"][frame - 1]["true_angle_deg"].get<double>();
    turned_deg -= 360.0 * std::round(turned_deg / 360.0);
    const double sign = rotation.axis().dot(axis.direction_camera) > 0.0 ? 1.0 : -1.0;
    EXPECT_NEAR(sign * rotation.angle() / kDegree, turned_deg, 1e-6);
    EXPECT_GT(std::fabs(turned_deg), 20.0);
    EXPECT_NEAR(std::fabs(rotation.axis().dot(axis.direction_camera)), 1.0, 1e-9);
    for (const double along : {-0.01, 0.0, 0.01}) {
      const Eigen::Vector3d on_axis = axis.point_camera + along * axis.direction_camera;
      EXPECT_LT((motion * on_axis - on_axis).norm(), 1e-9);
    }
  }
}

TEST(SimCalibrationCapture, AnInterruptedCaptureKeepsItsFramesAndTheirTruth) {
  test::TemporaryDirectory dir;
  SimCalibrationOptions options;
  options.rig.preset = "ci";
  options.rig.camera_width = 160;
  options.hand_poses = 2;
  options.turntable_poses = 2;
  options.head_object = "chessboard";  // focused on the axis: table views over ±40°
  const ProgressCallback stop_after_three = [](const ProgressUpdate& update) { return update.done < 3; };
  try {
    write_sim_calibration_recording(dir.file("rec"), options, Device::cpu(), stop_after_three);
    FAIL() << "expected a cancellation";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kCancelled);
  }
  const RecordingReader reader = RecordingReader::open(dir.file("rec"));
  ASSERT_EQ(reader.frame_count(), 3u);
  // The first table view, at −40° in whole steps of the 6400-step table: −711 steps.
  EXPECT_DOUBLE_EQ(*reader.frame(2).turntable_angle_deg, 360.0 * (6400 - 711) / 6400);
  EXPECT_EQ(read_tum_trajectory(reader.groundtruth_folder() + "/board_poses.txt").size(), 3u);
  EXPECT_EQ(read_json(reader.groundtruth_folder() + "/capture.json")["frames"].size(), 3u);
  EXPECT_TRUE(std::filesystem::exists(reader.groundtruth_folder() + "/frames/000002/corners.json"));
}

// sim://chessboard?calibration=1: the calibration target opened by URI, whose simulated operator
// places the board at the next pose by hand at every acquisition until the table is homed,
// then leaves it on the table's mount at whatever angle the table is at.
TEST(SimCalibrationCapture, ACalibrationTargetByUriHasAnOperatorWhoPlacesTheBoard) {
  const std::shared_ptr<SimScanner> scanner =
      SimScanner::open("sim://chessboard?calibration=1&preset=ci&width=64&hand_poses=2&head=chessboard&device=cpu");
  ASSERT_TRUE(scanner->simulated_operator());
  EXPECT_EQ(scanner->rig().placements.size(), 2u);
  EXPECT_TRUE(std::any_of(scanner->rig().patterns.patterns.begin(), scanner->rig().patterns.patterns.end(),
                          [](const PatternDesc& p) { return p.axis == PatternAxis::kRows; }));
  const std::unique_ptr<drivers::Camera> camera = scanner->camera();
  const std::unique_ptr<drivers::Projector> projector = scanner->projector();
  const std::unique_ptr<drivers::Turntable> turntable = scanner->turntable();
  projector->load_patterns(scanner->rig().patterns);
  const auto white = [&] {  // one acquisition: what the camera sees under white light
    camera->start();
    projector->show_pattern(0);
    camera->software_trigger();
    Image16u image = camera->wait_image(kSimDeviceTimeout).image;
    camera->stop();
    return image;
  };
  const Image16u first = white();
  EXPECT_EQ(scanner->ground_truth().frame, 0);
  const Image16u second = white();
  EXPECT_EQ(scanner->ground_truth().frame, 1);
  EXPECT_TRUE(first != second);
  EXPECT_THROW(camera->start(), Error);  // both poses by hand placed
  // The table homed: the board is on it, at the table's angle, a placement per angle.
  turntable->home(kSimDeviceTimeout);
  turntable->move_to_deg(10.0, kSimDeviceTimeout);
  white();
  GroundTruthFrame truth = scanner->ground_truth();
  EXPECT_EQ(truth.frame, 2);
  EXPECT_NEAR(truth.commanded_angle_deg, 10.0, 360.0 / kCalibrationTurntableSteps);
  turntable->move_to_deg(350.0, kSimDeviceTimeout);
  white();
  EXPECT_EQ(scanner->ground_truth().frame, 3);
  turntable->move_to_deg(10.0, kSimDeviceTimeout);
  white();
  EXPECT_EQ(scanner->ground_truth().frame, 2);
  EXPECT_EQ(scanner->rig().placements.size(), 4u);

  for (const char* bad : {"sim://chessboard?hand_poses=3", "sim://chessboard?head=chessboard",
                          "sim://knurled-screw?calibration=1", "sim://chessboard?calibration=1&frames=4",
                          "sim://chessboard?calibration=1&hand_poses=0", "sim://chessboard?calibration=1&head=teapot"}) {
    EXPECT_THROW(SimScanner::open(bad), Error) << bad;
  }
}

// board=charuco: the target's board is made by the maker its opener hands in (its markers come
// from calib, which the drivers do not link), on the ChArUco geometry, in the poses `sls sim
// --calibration --board charuco` gives it; without a maker, or a board the target cannot be,
// refused naming the URI.
TEST(SimCalibrationCapture, AChArUcoTargetByUriHasTheBoardItsOpenerMakes) {
  const std::string uri =
      "sim://chessboard?calibration=1&preset=ci&width=64&hand_poses=2&head=chessboard&device=cpu&board=charuco:12x9";
  std::string asked;
  const CharucoBoardMaker maker = [&](const std::string& spec, const ChessboardParameters& geometry) {
    asked = spec;
    return synthetic_charuco(7, geometry);
  };
  const std::shared_ptr<SimScanner> scanner = SimScanner::open(uri, maker);
  EXPECT_EQ(asked, "charuco:12x9");
  EXPECT_EQ(scanner->scene().name(), "charuco");
  SimCalibrationOptions options;
  options.rig.preset = "ci";
  options.rig.camera_width = 64;
  options.hand_poses = 2;
  options.turntable_poses = 0;
  options.head_object = "chessboard";
  options.board = synthetic_charuco(7, charuco_calibration_board_geometry());
  const SimRig rig = make_calibration_rigs(options).front();
  ASSERT_EQ(scanner->rig().placements.size(), 2u);
  for (std::size_t k = 0; k < 2; ++k) {
    EXPECT_EQ(scanner->rig().placements[k].mount.matrix(), rig.placements[k].mount.matrix()) << k;
  }

  const auto refusal = [&](const std::string& text, const CharucoBoardMaker& with) -> Error {
    try {
      SimScanner::open(text, with);
    } catch (const Error& error) {
      return error;
    }
    ADD_FAILURE() << text << " opened";
    return Error(ErrorCode::kInternal, "");
  };
  const Error no_maker = refusal(uri, {});
  EXPECT_EQ(no_maker.code(), ErrorCode::kUnsupported);
  EXPECT_NE(std::string(no_maker.what()).find("board=charuco:12x9 needs the ChArUco markers of calib"),
            std::string::npos)
      << no_maker.what();
  const Error hexagon = refusal("sim://chessboard?calibration=1&preset=ci&board=hexagon", maker);
  EXPECT_EQ(hexagon.code(), ErrorCode::kInvalidArgument);
  EXPECT_NE(std::string(hexagon.what()).find("board=hexagon (chessboard, charuco or charuco:COLSxROWS)"),
            std::string::npos);
  EXPECT_EQ(refusal("sim://chessboard?preset=ci&board=charuco", maker).code(), ErrorCode::kInvalidArgument);
  const CharucoBoardMaker failing = [](const std::string&, const ChessboardParameters&) -> ChessboardParameters {
    throw Error(ErrorCode::kInvalidArgument, "marker too large");
  };
  const Error failed = refusal(uri, failing);
  EXPECT_EQ(failed.code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(std::string(failed.what()), uri + ": board=charuco:12x9: marker too large");
}

// The devices of one head by URI (cameras=2&camera=K): camera K is rigs[K] of that head; what
// the projector opened from any of its URIs shows, every camera sees; the operator places the
// board once per acquisition of the head (both cameras started for one pose), not per camera.
TEST(SimCalibrationCapture, TheCamerasOfAHeadShareItsProjectorAndItsOperator) {
  const std::string uri = "sim://chessboard?calibration=1&preset=ci&width=64&hand_poses=2&head=chessboard&device=cpu"
                          "&cameras=2";
  const std::shared_ptr<SimScanner> first = SimScanner::open(uri + "&camera=0");
  const std::shared_ptr<SimScanner> second = SimScanner::open(uri + "&camera=1");
  SimCalibrationOptions options;
  options.rig.preset = "ci";
  options.rig.camera_width = 64;
  options.hand_poses = 2;
  options.turntable_poses = 0;
  options.head_object = "chessboard";
  options.cameras = 2;
  const std::vector<SimRig> rigs = make_calibration_rigs(options);
  EXPECT_EQ(first->rig().T_world_camera.matrix(), rigs[0].T_world_camera.matrix());
  EXPECT_EQ(second->rig().T_world_camera.matrix(), rigs[1].T_world_camera.matrix());
  EXPECT_EQ(second->rig().camera.k1, rigs[1].camera.k1);
  EXPECT_EQ(second->rig().noise_seed, rigs[1].noise_seed);
  const std::unique_ptr<drivers::Projector> projector = second->projector();  // any of the head's
  const std::unique_ptr<drivers::Camera> camera0 = first->camera();
  const std::unique_ptr<drivers::Camera> camera1 = second->camera();
  EXPECT_EQ(camera0->info().serial, "SIM-CAM-0");
  EXPECT_EQ(camera1->info().serial, "SIM-CAM-1");
  projector->load_patterns(first->rig().patterns);
  const auto mean = [](const Image16u& image) {
    double sum = 0.0;
    for (int y = 0; y < image.height(); ++y) {
      for (int x = 0; x < image.width(); ++x) sum += image(x, y);
    }
    return sum / (static_cast<double>(image.width()) * image.height());
  };
  // One acquisition of the head: both cameras started, the pattern shown once, both triggered.
  const auto acquire = [&](int pattern) {
    camera0->start();
    camera1->start();
    if (pattern < 0) {
      projector->go_dark();
    } else {
      projector->show_pattern(pattern);
    }
    camera0->software_trigger();
    camera1->software_trigger();
    std::pair<Image16u, Image16u> images{camera0->wait_image(kSimDeviceTimeout).image,
                                         camera1->wait_image(kSimDeviceTimeout).image};
    camera1->stop();
    camera0->stop();
    return images;
  };
  const auto [white0, white1] = acquire(0);
  EXPECT_EQ(first->ground_truth().frame, 0);
  EXPECT_EQ(second->ground_truth().frame, 0);
  const auto [dark0, dark1] = acquire(-1);
  EXPECT_EQ(first->ground_truth().frame, 1);  // one pose further for both, not two
  EXPECT_EQ(second->ground_truth().frame, 1);
  EXPECT_GT(mean(white1), 2.0 * mean(dark1));  // camera 1 sees the head's projector
  EXPECT_GT(mean(white0), 2.0 * mean(dark0));
  EXPECT_TRUE(white0 != white1);
  EXPECT_THROW(camera0->start(), Error);  // both poses by hand placed

  for (const std::string& bad : std::vector<std::string>{uri + "&camera=2", "sim://chessboard?calibration=1&camera=1",
                                "sim://chessboard?calibration=1&cameras=5", "sim://chessboard?cameras=2",
                                "sim://chessboard?calibration=1&cameras=2&camera=-1"}) {
    EXPECT_THROW(SimScanner::open(bad), Error) << bad;
  }
  try {
    SimScanner::open(uri + "&camera=2");
  } catch (const Error& error) {
    EXPECT_NE(std::string(error.what()).find("camera=2 is not a camera of a head of 2 (0 .. 1)"), std::string::npos)
        << error.what();
  }
}

}  // namespace
}  // namespace sls::sim
