#include "sdk/core/trajectory.h"

#include <array>
#include <charconv>
#include <cmath>
#include <iterator>
#include <system_error>

#include <fmt/format.h>

#include "sdk/core/error.h"
#include "sdk/core/file_util.h"

namespace sls {
namespace {

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

// Splits a line (comment already removed) into whitespace-separated fields.
std::vector<std::string_view> split_fields(std::string_view line) {
  std::vector<std::string_view> fields;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_space(line[i])) ++i;
    const std::size_t start = i;
    while (i < line.size() && !is_space(line[i])) ++i;
    if (i > start) fields.push_back(line.substr(start, i - start));
  }
  return fields;
}

constexpr std::array<const char*, 8> kFieldNames = {"timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"};

}  // namespace

std::string format_tum_trajectory(const std::vector<StampedPose>& poses) {
  std::string text = "# timestamp tx ty tz qx qy qz qw\n";
  auto out = std::back_inserter(text);
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const StampedPose& pose = poses[i];
    const Eigen::Vector3d& t = pose.T_world_camera.translation();
    const Eigen::Quaterniond& q = pose.T_world_camera.quaternion();
    const std::array<double, 8> values = {pose.timestamp_s, t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()};
    for (std::size_t k = 0; k < values.size(); ++k) {
      if (!std::isfinite(values[k])) {
        throw_error(ErrorCode::kInvalidArgument, "trajectory pose {}: {} is not finite ({})", i, kFieldNames[k],
                    values[k]);
      }
    }
    // "{}" is the shortest representation that reads back to the same double.
    fmt::format_to(out, "{} {} {} {} {} {} {} {}\n", values[0], values[1], values[2], values[3], values[4],
                   values[5], values[6], values[7]);
  }
  return text;
}

std::vector<StampedPose> parse_tum_trajectory(std::string_view text, const std::string& source) {
  std::vector<StampedPose> poses;
  std::size_t line_start = 0;
  int line_number = 0;
  int previous_line_number = 0;
  while (line_start < text.size()) {
    std::size_t line_end = text.find('\n', line_start);
    if (line_end == std::string_view::npos) line_end = text.size();
    std::string_view line = text.substr(line_start, line_end - line_start);
    line_start = line_end + 1;
    ++line_number;

    const std::size_t comment = line.find('#');
    if (comment != std::string_view::npos) line = line.substr(0, comment);
    const std::vector<std::string_view> fields = split_fields(line);
    if (fields.empty()) continue;
    if (fields.size() != kFieldNames.size()) {
      throw_error(ErrorCode::kFormat, "{}:{}: expected 8 fields (timestamp tx ty tz qx qy qz qw), found {}",
                  source, line_number, fields.size());
    }
    std::array<double, 8> values{};
    for (std::size_t k = 0; k < fields.size(); ++k) {
      const std::string_view field = fields[k];
      // from_chars is locale-independent, unlike strtod; it also rejects a leading '+'.
      const char* begin = field.data();
      const char* end = field.data() + field.size();
      if (end - begin >= 2 && *begin == '+' && *(begin + 1) != '-') ++begin;
      const std::from_chars_result result = std::from_chars(begin, end, values[k]);
      if (result.ec == std::errc::result_out_of_range && result.ptr == end) {
        throw_error(ErrorCode::kFormat, "{}:{}: {} '{}' is out of range", source, line_number, kFieldNames[k],
                    field);
      }
      if (result.ec != std::errc() || result.ptr != end) {
        throw_error(ErrorCode::kFormat, "{}:{}: {} '{}' is not a number", source, line_number, kFieldNames[k],
                    field);
      }
      if (!std::isfinite(values[k])) {
        throw_error(ErrorCode::kFormat, "{}:{}: {} '{}' is not finite", source, line_number, kFieldNames[k], field);
      }
    }
    const Eigen::Quaterniond q(values[7], values[4], values[5], values[6]);  // (w, x, y, z)
    const double norm = q.norm();
    if (!(std::fabs(norm - 1.0) <= kTumQuaternionNormTolerance)) {
      throw_error(ErrorCode::kFormat, "{}:{}: quaternion (qx qy qz qw) has norm {}, expected 1 (tolerance {})",
                  source, line_number, norm, kTumQuaternionNormTolerance);
    }
    // Poses are associated by time (evaluation, interpolation): a clock that goes backwards
    // means lines out of order or a corrupt value. Equal timestamps are left to the reader.
    if (!poses.empty() && values[0] < poses.back().timestamp_s) {
      throw_error(ErrorCode::kFormat,
                  "{}:{}: timestamp {} is earlier than {} on line {}: timestamps must not go backwards", source,
                  line_number, fields[0], poses.back().timestamp_s, previous_line_number);
    }
    poses.push_back({values[0], Pose(q, Eigen::Vector3d(values[1], values[2], values[3]))});
    previous_line_number = line_number;
  }
  return poses;
}

void write_tum_trajectory(const std::string& path, const std::vector<StampedPose>& poses) {
  write_file_atomic(path, format_tum_trajectory(poses));
}

std::vector<StampedPose> read_tum_trajectory(const std::string& path) {
  return parse_tum_trajectory(read_file_text(path), path);
}

}  // namespace sls
