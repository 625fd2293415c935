// libFuzzer target: TUM trajectories. Whatever is accepted has finite values, unit quaternions
// and timestamps that never go backwards, and survives a write/read round trip (timestamps
// and translations exactly, quaternions to rounding).
#include <cmath>
#include <string>
#include <vector>

#include "sdk/core/error.h"
#include "sdk/core/trajectory.h"
#include "tests/fuzz/fuzz_support.h"

using sls::fuzz::check;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::vector<sls::StampedPose> poses;
  try {
    poses = sls::parse_tum_trajectory(sls::fuzz::as_text(data, size), "fuzz.txt");
  } catch (const sls::Error&) {
    return 0;
  }
  for (std::size_t i = 0; i < poses.size(); ++i) {
    check(std::isfinite(poses[i].timestamp_s) && poses[i].T_world_camera.translation().allFinite());
    check(std::fabs(poses[i].T_world_camera.quaternion().norm() - 1.0) < 1e-12);
    check(i == 0 || poses[i].timestamp_s >= poses[i - 1].timestamp_s);
  }
  const std::vector<sls::StampedPose> again =
      sls::parse_tum_trajectory(sls::format_tum_trajectory(poses), "again.txt");
  check(again.size() == poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    check(again[i].timestamp_s == poses[i].timestamp_s);
    check(again[i].T_world_camera.translation() == poses[i].T_world_camera.translation());
    check(again[i].T_world_camera.quaternion().angularDistance(poses[i].T_world_camera.quaternion()) < 1e-6);
  }
  return 0;
}
