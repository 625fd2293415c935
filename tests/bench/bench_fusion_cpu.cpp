// CPU fusion speed on a recording's depth maps, for the side-by-side run with Open3D's CPU
// TSDF integration (tests/bench/fusion_vs_open3d.py sets the environment): a cube volume of
// SLS_BENCH_VOXELS³ voxels of SLS_BENCH_VOXEL_M metres with its corner at SLS_BENCH_ORIGIN
// ("x,y,z", object frame), every depth map of SLS_BENCH_RECORDING integrated with its
// ground-truth pose. Truncation SLS_BENCH_TRUNCATION_M (metres) like Open3D's sdf_trunc.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

#include "fusion/integrator.h"
#include "sdk/core/recording.h"
#include "sdk/core/trajectory.h"

namespace sls {
namespace {

std::string env(const char* name) {
  const char* value = std::getenv(name);
  return value != nullptr ? value : "";
}

struct Input {
  CameraIntrinsics camera;
  std::vector<Image32f> depth;
  std::vector<Pose> T_object_camera;
};

const Input& input() {
  static const Input loaded = [] {
    Input in;
    const RecordingReader recording = RecordingReader::open(env("SLS_BENCH_RECORDING"));
    in.camera = recording.calibration().camera;
    const std::vector<StampedPose> poses = read_tum_trajectory(recording.groundtruth_folder() + "/trajectory.txt");
    for (std::size_t i = 0; i < recording.frame_count(); ++i) {
      in.depth.push_back(*recording.load_depth_m(i));
      in.T_object_camera.push_back(poses[i].T_world_camera);
    }
    return in;
  }();
  return loaded;
}

void BM_IntegrateCpu(benchmark::State& state, const fusion::IntegrationOptions& base) {
  if (env("SLS_BENCH_RECORDING").empty()) {
    state.SkipWithError("set SLS_BENCH_RECORDING (see tests/bench/fusion_vs_open3d.py)");
    return;
  }
  const Input& in = input();
  const int voxels = std::stoi(env("SLS_BENCH_VOXELS"));
  const double voxel_m = std::stod(env("SLS_BENCH_VOXEL_M"));
  std::stringstream origin_text(env("SLS_BENCH_ORIGIN"));
  Eigen::Vector3d origin;
  char comma;
  origin_text >> origin.x() >> comma >> origin.y() >> comma >> origin.z();
  fusion::VolumeGeometry geometry;
  geometry.nx = geometry.ny = geometry.nz = voxels;
  geometry.voxel_size_m = voxel_m;
  geometry.T_world_volume = Pose(Eigen::Matrix3d::Identity(), origin);
  fusion::IntegrationOptions options = base;
  options.truncation_voxels = std::stod(env("SLS_BENCH_TRUNCATION_M")) / voxel_m;
  options.eta_voxels = options.truncation_voxels * 1.5;
  fusion::Volume volume(geometry, fusion::VoxelFormat::kFloat32, Device::cpu(), options.average_storage());
  fusion::Integrator integrator(Device::cpu(), options);
  for (auto _ : state) {
    volume.clear();
    for (std::size_t n = 0; n < in.depth.size(); ++n) integrator.integrate(volume, in.depth[n], in.camera, in.T_object_camera[n]);
  }
  state.counters["ms_per_frame"] = benchmark::Counter(static_cast<double>(state.iterations()) * static_cast<double>(in.depth.size()) * 1e-3,
                                                      benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters["frames"] = static_cast<double>(in.depth.size());
  state.counters["voxels_M"] = static_cast<double>(geometry.voxel_count()) / 1e6;
}

BENCHMARK_CAPTURE(BM_IntegrateCpu, tsdf, fusion::IntegrationOptions::tsdf())->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);
BENCHMARK_CAPTURE(BM_IntegrateCpu, gtsdf, fusion::IntegrationOptions::gtsdf())->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);

}  // namespace
}  // namespace sls

BENCHMARK_MAIN();
