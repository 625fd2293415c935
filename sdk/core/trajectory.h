// Camera trajectories in the TUM RGB-D format, which evo and most SLAM tools read:
// one pose per line, "timestamp tx ty tz qx qy qz qw", whitespace separated, '#' starts a
// comment. Timestamps in seconds, translations in metres, the pose is T_world_camera
// (camera frame -> world frame), the quaternion is Hamilton with w last.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "sdk/core/pose.h"

namespace sls {

struct StampedPose {
  double timestamp_s = 0.0;
  Pose T_world_camera;
};

// Quaternions whose norm differs from 1 by more than this are rejected when reading; closer
// ones are normalized. Loose enough for files printed with 4 decimals (the TUM benchmark's
// own ground truth), tight enough to catch a wrong column order or a corrupt value.
constexpr double kTumQuaternionNormTolerance = 1e-3;

// The file text: a header comment, then one line per pose with every number in its
// shortest exact form (reads back bit-for-bit). Throws sls::Error (invalid argument) for a
// non-finite value.
std::string format_tum_trajectory(const std::vector<StampedPose>& poses);

// Parses TUM text; `source` (a path) only names the input in errors. Blank lines and
// comments are skipped. Throws sls::Error (format) naming the source and line: wrong number
// of fields, a field that is not a number, a non-finite value, a quaternion that is not unit
// within kTumQuaternionNormTolerance, a timestamp earlier than the previous pose's (equal
// ones are accepted).
std::vector<StampedPose> parse_tum_trajectory(std::string_view text, const std::string& source);

// Writes atomically (temporary file + rename); throws sls::Error (I/O) naming the path.
void write_tum_trajectory(const std::string& path, const std::vector<StampedPose>& poses);

// Reads a trajectory (a regular file of at most kMaxMetadataFileBytes); throws sls::Error
// (not found / I/O / format) naming the path.
std::vector<StampedPose> read_tum_trajectory(const std::string& path);

}  // namespace sls
