// TUM trajectories: exact round trips, comments and blank lines, and errors that name the
// file and the line.
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/trajectory.h"
#include "tests/support/test_support.h"

namespace sls {
namespace {

std::vector<StampedPose> random_trajectory(int count) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<StampedPose> poses;
  double t = 1305031102.175304;  // a TUM-like Unix timestamp: needs all 17 digits
  for (int i = 0; i < count; ++i) {
    Eigen::Vector3d axis(u(rng), u(rng), u(rng));
    axis.normalize();
    const Eigen::Quaterniond q(Eigen::AngleAxisd(3.1 * u(rng), axis));
    poses.push_back({t, Pose(q, Eigen::Vector3d(u(rng), u(rng), 1e-6 * u(rng)))});
    t += 0.0333 + 1e-7 * u(rng);
  }
  return poses;
}

// Message checks: the error names the file, the line and what is wrong.
void expect_format_error(const std::string& path, const std::string& text, const std::string& location,
                         const std::string& detail) {
  write_file_atomic(path, text);
  try {
    read_tum_trajectory(path);
    FAIL() << "expected an error for:\n" << text;
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kFormat);
    const std::string message = error.what();
    EXPECT_NE(message.find(path + ":" + location), std::string::npos) << message;
    EXPECT_NE(message.find(detail), std::string::npos) << message;
  }
}

TEST(Trajectory, RoundTripIsExact) {
  test::TemporaryDirectory directory;
  const std::string path = directory.file("trajectory.txt");
  const std::vector<StampedPose> poses = random_trajectory(200);
  write_tum_trajectory(path, poses);
  const std::vector<StampedPose> read = read_tum_trajectory(path);
  ASSERT_EQ(read.size(), poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    EXPECT_EQ(read[i].timestamp_s, poses[i].timestamp_s) << i;  // bit-exact
    EXPECT_EQ(read[i].T_world_camera.translation(), poses[i].T_world_camera.translation()) << i;
    // The quaternion is re-normalized on reading, which may move its last bit.
    EXPECT_LE((read[i].T_world_camera.quaternion().coeffs() - poses[i].T_world_camera.quaternion().coeffs())
                  .cwiseAbs()
                  .maxCoeff(),
              1e-15)
        << i;
    EXPECT_TRUE(read[i].T_world_camera.is_approx(poses[i].T_world_camera, 1e-12)) << i;
  }
}

TEST(Trajectory, WritesTheTumLayout) {
  const std::vector<StampedPose> poses = {
      {1.5, Pose(Eigen::Quaterniond(0.5, 0.5, -0.5, 0.5), Eigen::Vector3d(0.25, -2.0, 3.0))}};
  const std::string text = format_tum_trajectory(poses);
  EXPECT_EQ(text, "# timestamp tx ty tz qx qy qz qw\n1.5 0.25 -2 3 0.5 -0.5 0.5 0.5\n");
}

TEST(Trajectory, EmptyTrajectoryRoundTrips) {
  test::TemporaryDirectory directory;
  const std::string path = directory.file("empty.txt");
  write_tum_trajectory(path, {});
  EXPECT_TRUE(read_tum_trajectory(path).empty());
}

TEST(Trajectory, SkipsCommentsAndBlankLines) {
  const std::string text =
      "# written by some tool\n"
      "\n"
      "   # indented comment\n"
      "1.0 0 0 0 0 0 0 1\n"
      "\t\n"
      "2.0\t0.1  0.2 0.3 0 0 0.7071067811865476 0.7071067811865476   # trailing comment\r\n"
      "3.0 1e-3 -1E+1 .5 0 0 0 -1";  // no final newline, w < 0
  const std::vector<StampedPose> poses = parse_tum_trajectory(text, "inline");
  ASSERT_EQ(poses.size(), 3u);
  EXPECT_EQ(poses[0].timestamp_s, 1.0);
  EXPECT_TRUE(poses[0].T_world_camera.is_approx(Pose::identity()));
  EXPECT_EQ(poses[1].timestamp_s, 2.0);
  EXPECT_EQ(poses[1].T_world_camera.translation(), Eigen::Vector3d(0.1, 0.2, 0.3));
  EXPECT_NEAR(poses[1].T_world_camera.angle_rad(), M_PI / 2, 1e-12);
  EXPECT_EQ(poses[2].T_world_camera.translation(), Eigen::Vector3d(1e-3, -10.0, 0.5));
  EXPECT_NEAR(poses[2].T_world_camera.angle_rad(), 0.0, 1e-12);
}

TEST(Trajectory, SlightlyNonUnitQuaternionsAreNormalized) {
  // Four decimals, as in the TUM benchmark's ground truth: norm 1 − 4e-5.
  const std::vector<StampedPose> poses = parse_tum_trajectory("0 0 0 0 0.6124 0.3536 0.3536 0.6124\n", "inline");
  ASSERT_EQ(poses.size(), 1u);
  EXPECT_NEAR(poses[0].T_world_camera.quaternion().norm(), 1.0, 1e-15);
}

TEST(Trajectory, MalformedLinesNameFileAndLine) {
  test::TemporaryDirectory directory;
  const std::string path = directory.file("bad.txt");
  const std::string good = "# header\n1 0 0 0 0 0 0 1\n";
  expect_format_error(path, good + "2 0 0 0 0 0 1\n", "3:", "expected 8 fields");
  expect_format_error(path, good + "2 0 0 0 0 0 0 1 9\n", "3:", "found 9");
  expect_format_error(path, good + "\n2 0 0 abc 0 0 0 1\n", "4:", "tz 'abc' is not a number");
  expect_format_error(path, good + "2 0 0 0.5x 0 0 0 1\n", "3:", "tz '0.5x' is not a number");
  expect_format_error(path, good + "2,0,0,0,0,0,0,1\n", "3:", "expected 8 fields");
  expect_format_error(path, good + "2 0 nan 0 0 0 0 1\n", "3:", "ty 'nan' is not finite");
  expect_format_error(path, good + "2 0 0 0 0 0 0 inf\n", "3:", "qw 'inf' is not finite");
  expect_format_error(path, good + "2 0 0 0 1e999 0 0 1\n", "3:", "qx '1e999' is out of range");
  expect_format_error(path, good + "2 0 0 0 0 0 0 0\n", "3:", "quaternion (qx qy qz qw) has norm 0");
  expect_format_error(path, good + "2 0 0 0 0 0 0.1 1\n", "3:", "has norm 1.00498");
  expect_format_error(path, good + "2 0 0 0 0 0 0 +-1\n", "3:", "qw '+-1' is not a number");
}

TEST(Trajectory, MissingFileIsNotFound) {
  test::TemporaryDirectory directory;
  try {
    read_tum_trajectory(directory.file("nope.txt"));
    FAIL() << "expected an error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kNotFound);
    EXPECT_NE(std::string(error.what()).find("nope.txt"), std::string::npos);
  }
}

TEST(Trajectory, NonFinitePosesAreNotWritten) {
  test::TemporaryDirectory directory;
  std::vector<StampedPose> poses = random_trajectory(3);
  poses[1].timestamp_s = std::nan("");
  EXPECT_THROW(write_tum_trajectory(directory.file("t.txt"), poses), Error);
}

TEST(Trajectory, TimestampsGoingBackwardsAreRefused) {
  test::TemporaryDirectory directory;
  const std::string path = directory.file("backwards.txt");
  const std::string good = "# header\n1 0 0 0 0 0 0 1\n\n2.5 0 0 0 0 0 0 1\n";
  expect_format_error(path, good + "2.25 0 0 0 0 0 0 1\n", "5:",
                      "timestamp 2.25 is earlier than 2.5 on line 4: timestamps must not go backwards");
  expect_format_error(path, good + "-1 0 0 0 0 0 0 1\n", "5:", "timestamp -1 is earlier than 2.5 on line 4");
  // Equal timestamps are not backwards.
  EXPECT_EQ(parse_tum_trajectory(good + "2.5 1 0 0 0 0 0 1\n", "inline").size(), 3u);
}

}  // namespace
}  // namespace sls
