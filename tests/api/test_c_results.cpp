// The C API's results in memory (sls_results.h): the cloud and mesh equal to the PLY files
// written for the same scan, the trajectory equal to the TUM file's poses, snapshots that outlive
// their scan, live results from the frame callback (and BUSY from another thread meanwhile), the
// preview, and the mistakes (NULL handles and buffers, short buffers, bad sizes and poses, bad
// struct sizes), each a status, never a crash. Also run under ASan (build/asan).
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "sdk/core/ply.h"
#include "sdk/core/point_cloud.h"
#include "sdk/core/trajectory.h"
#include "tests/api/c_results_fixture.h"

namespace sls::test {
namespace {

class CResults : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    directory_ = new TemporaryDirectory();
    recording_ = new std::string(sim_recording(*directory_, "knob", true, 6));
  }
  static void TearDownTestSuite() {
    delete recording_;
    delete directory_;
  }
  static const std::string& recording() { return *recording_; }
  std::string scratch(const std::string& name) const { return directory_->file(name); }

  static TemporaryDirectory* directory_;
  static std::string* recording_;
  ContextPtr context_ = cpu_context();
};
TemporaryDirectory* CResults::directory_ = nullptr;
std::string* CResults::recording_ = nullptr;

std::vector<float> flatten(const std::vector<Eigen::Vector3f>& values) {
  std::vector<float> out;
  for (const Eigen::Vector3f& value : values) out.insert(out.end(), value.data(), value.data() + 3);
  return out;
}

TEST_F(CResults, CloudMeshAndTrajectoryEqualTheFilesOfTheSameScan) {
  const ScanPtr scan = make_scan(context_.get(), true);
  SLS_OK_CALL(sls_scan_run_recording(scan.get(), recording().c_str(), &error_));
  SLS_OK_CALL(sls_scan_write_cloud(scan.get(), scratch("cloud.ply").c_str(), &error_));
  SLS_OK_CALL(sls_scan_write_mesh(scan.get(), scratch("mesh.ply").c_str(), &error_));
  SLS_OK_CALL(sls_scan_write_trajectory(scan.get(), scratch("trajectory.txt").c_str(), &error_));

  const CloudCopy cloud = scan_cloud(scan.get());
  const PointCloud file = read_ply_cloud(scratch("cloud.ply"));
  ASSERT_GT(file.size(), 1000u);
  EXPECT_EQ(cloud.positions, flatten(file.positions));  // bit for bit: the PLY stores the floats
  EXPECT_EQ(cloud.normals, flatten(file.normals));
  EXPECT_EQ(cloud.confidence, file.confidence);
  const PointProperty* correction = file.find_property("correction");
  ASSERT_NE(correction, nullptr);  // online deformation
  EXPECT_EQ(cloud.correction, correction->values);

  sls_mesh* mesh = nullptr;
  SLS_OK_CALL(sls_scan_get_mesh(scan.get(), &mesh, &error_));
  const MeshPtr mesh_owned(mesh);
  sls_mesh_data data;
  sls_mesh_data_init(&data);
  SLS_OK_CALL(sls_mesh_get_data(mesh, &data, &error_));
  const TriangleMesh mesh_file = read_ply_mesh(scratch("mesh.ply"));
  ASSERT_EQ(data.vertices, mesh_file.vertices.size());
  ASSERT_EQ(data.faces, mesh_file.faces.size());
  ASSERT_GT(data.faces, 1000u);
  EXPECT_EQ(std::vector<float>(data.positions, data.positions + 3 * data.vertices),
            flatten(mesh_file.vertices.positions));
  ASSERT_NE(data.normals, nullptr);
  EXPECT_EQ(std::vector<float>(data.normals, data.normals + 3 * data.vertices), flatten(mesh_file.vertices.normals));
  std::vector<std::int32_t> faces;
  for (const auto& face : mesh_file.faces) faces.insert(faces.end(), face.begin(), face.end());
  EXPECT_EQ(std::vector<std::int32_t>(data.indices, data.indices + 3 * data.faces), faces);

  size_t count = 0;
  SLS_OK_CALL(sls_scan_get_trajectory(scan.get(), nullptr, nullptr, 0, &count, &error_));
  const std::vector<StampedPose> poses = read_tum_trajectory(scratch("trajectory.txt"));
  ASSERT_EQ(count, poses.size());
  ASSERT_EQ(count, 6u);
  std::vector<double> stamps(count), matrices(16 * count);
  SLS_OK_CALL(sls_scan_get_trajectory(scan.get(), stamps.data(), matrices.data(), count, &count, &error_));
  for (std::size_t i = 0; i < count; ++i) {
    EXPECT_NEAR(stamps[i], poses[i].timestamp_s, 1e-9);
    const Eigen::Matrix4d expected = poses[i].T_world_camera.matrix();
    for (int k = 0; k < 16; ++k) EXPECT_NEAR(matrices[16 * i + static_cast<std::size_t>(k)], expected(k / 4, k % 4), 1e-6);
  }
}

TEST_F(CResults, SnapshotsOutliveTheScanAndDoNotChange) {
  ScanPtr scan = make_scan(context_.get(), false);
  SLS_OK_CALL(sls_scan_run_recording(scan.get(), recording().c_str(), &error_));
  sls_cloud* cloud = nullptr;
  SLS_OK_CALL(sls_scan_get_cloud(scan.get(), &cloud, &error_));
  const CloudPtr owned(cloud);
  const CloudCopy before = copy_cloud(cloud);
  EXPECT_TRUE(before.correction.empty());  // online deformation off: no correction property
  EXPECT_EQ(before.normals.size(), before.positions.size());
  // A new run replaces the scan's model, and the scan goes: the snapshot stays as it was.
  SLS_OK_CALL(sls_scan_run_recording(scan.get(), recording().c_str(), &error_));
  scan.reset();
  const CloudCopy after = copy_cloud(cloud);
  EXPECT_EQ(after.positions, before.positions);
  EXPECT_EQ(after.confidence, before.confidence);
}

// What the frame callback saw of the model as it grew.
struct Live {
  sls_scan* scan = nullptr;
  int frames = 0;
  std::vector<std::size_t> points;       // the cloud's size after each frame
  std::vector<std::size_t> poses;        // the trajectory's length after each frame
  std::vector<std::size_t> lit_pixels;   // non-zero preview pixels after each frame
  sls_status other_thread = SLS_OK;      // a getter from another thread during the run
  sls_status write_from_callback = SLS_OK;
  sls_status feed_from_callback = SLS_OK;
};

void on_frame_live(const sls_frame_report* report, void* user) {
  Live& live = *static_cast<Live*>(user);
  ++live.frames;
  sls_cloud* cloud = nullptr;
  sls_cloud_data data;
  sls_cloud_data_init(&data);
  live.points.push_back(sls_scan_get_cloud(live.scan, &cloud, nullptr) == SLS_OK &&
                                sls_cloud_get_data(cloud, &data, nullptr) == SLS_OK
                            ? data.points
                            : 0);
  sls_cloud_destroy(cloud);
  size_t count = 0;
  live.poses.push_back(sls_scan_get_trajectory(live.scan, nullptr, nullptr, 0, &count, nullptr) == SLS_OK ? count : 0);
  std::vector<std::uint8_t> preview(80 * 60);
  live.lit_pixels.push_back(
      sls_scan_render_preview(live.scan, nullptr, 80, 60, preview.data(), preview.size(), nullptr) == SLS_OK
          ? static_cast<std::size_t>(std::count_if(preview.begin(), preview.end(), [](std::uint8_t v) { return v > 0; }))
          : 0);
  if (report->index == 2) {
    // The run is in progress for as long as this callback runs: another thread is refused.
    std::thread other([&live] {
      sls_cloud* refused = nullptr;
      live.other_thread = sls_scan_get_cloud(live.scan, &refused, nullptr);
      sls_cloud_destroy(refused);
    });
    other.join();
    live.write_from_callback = sls_scan_write_cloud(live.scan, "never-written.ply", nullptr);
    sls_depth_frame frame;
    sls_depth_frame_init(&frame);
    live.feed_from_callback = sls_scan_add_depth(live.scan, &frame, nullptr, nullptr);
  }
}

TEST_F(CResults, LiveFromTheFrameCallbackAndBusyElsewhere) {
  const ScanPtr scan = make_scan(context_.get(), true);
  Live live;
  live.scan = scan.get();
  SLS_OK_CALL(sls_scan_set_frame_callback(scan.get(), on_frame_live, &live, &error_));
  SLS_OK_CALL(sls_scan_run_recording(scan.get(), recording().c_str(), &error_));
  ASSERT_EQ(live.frames, 6);
  for (int i = 0; i < 6; ++i) {
    EXPECT_GT(live.points[static_cast<std::size_t>(i)], 1000u) << "frame " << i;
    EXPECT_EQ(live.poses[static_cast<std::size_t>(i)], static_cast<std::size_t>(i + 1)) << "frame " << i;
    EXPECT_GT(live.lit_pixels[static_cast<std::size_t>(i)], 80u * 60u / 10u) << "frame " << i;
  }
  EXPECT_GT(live.points.back(), live.points.front());  // the model grew round the knob
  EXPECT_EQ(live.other_thread, SLS_ERROR_BUSY);
  EXPECT_EQ(live.write_from_callback, SLS_ERROR_BUSY);
  EXPECT_EQ(live.feed_from_callback, SLS_ERROR_BUSY);
  // After the run, the last live cloud is the final one (no frame came after it).
  EXPECT_EQ(scan_cloud(scan.get()).positions.size(), 3 * live.points.back());
}

TEST_F(CResults, Preview) {
  const ScanPtr scan = make_scan(context_.get(), false);
  std::vector<std::uint8_t> pixels(160 * 120, 0xAB);
  SLS_FAILS(sls_scan_render_preview(scan.get(), nullptr, 160, 120, pixels.data(), pixels.size(), &error_),
            SLS_ERROR_INVALID_ARGUMENT, "no frame");
  SLS_OK_CALL(sls_scan_run_recording(scan.get(), recording().c_str(), &error_));
  EXPECT_EQ(std::count(pixels.begin(), pixels.end(), 0xAB), static_cast<long>(pixels.size()));  // untouched
  SLS_OK_CALL(sls_scan_render_preview(scan.get(), nullptr, 160, 120, pixels.data(), pixels.size(), &error_));
  const auto lit = std::count_if(pixels.begin(), pixels.end(), [](std::uint8_t v) { return v > 0; });
  EXPECT_GT(lit, 160 * 120 / 10);
  // The last fused frame's pose given explicitly draws the same picture.
  std::vector<double> stamps(6), poses(6 * 16);
  size_t count = 0;
  SLS_OK_CALL(sls_scan_get_trajectory(scan.get(), stamps.data(), poses.data(), 6, &count, &error_));
  std::vector<std::uint8_t> again(160 * 120);
  SLS_OK_CALL(sls_scan_render_preview(scan.get(), &poses[16 * (count - 1)], 160, 120, again.data(), again.size(),
                                      &error_));
  EXPECT_EQ(again, pixels);
  // Mistakes: the buffer untouched.
  std::fill(again.begin(), again.end(), 0xCD);
  SLS_FAILS(sls_scan_render_preview(scan.get(), nullptr, 160, 120, again.data(), again.size() - 1, &error_),
            SLS_ERROR_INVALID_ARGUMENT, "pixel_count");
  SLS_FAILS(sls_scan_render_preview(scan.get(), nullptr, 15, 120, again.data(), again.size(), &error_),
            SLS_ERROR_INVALID_ARGUMENT, "16 .. 4096");
  SLS_FAILS(sls_scan_render_preview(scan.get(), nullptr, 160, 5000, again.data(), again.size(), &error_),
            SLS_ERROR_INVALID_ARGUMENT, "16 .. 4096");
  SLS_FAILS(sls_scan_render_preview(scan.get(), nullptr, 160, 120, nullptr, again.size(), &error_),
            SLS_ERROR_INVALID_ARGUMENT, "pixels");
  double scaled[16] = {2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 1};
  SLS_FAILS(sls_scan_render_preview(scan.get(), scaled, 160, 120, again.data(), again.size(), &error_),
            SLS_ERROR_INVALID_ARGUMENT, "rigid");
  double not_finite[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  not_finite[3] = std::numeric_limits<double>::quiet_NaN();
  SLS_FAILS(sls_scan_render_preview(scan.get(), not_finite, 160, 120, again.data(), again.size(), &error_),
            SLS_ERROR_INVALID_ARGUMENT, "T_world_camera[0][3]");
  EXPECT_EQ(std::count(again.begin(), again.end(), 0xCD), static_cast<long>(again.size()));
}

TEST_F(CResults, MistakesAreStatusesNeverCrashes) {
  const ScanPtr scan = make_scan(context_.get(), false);
  sls_cloud* cloud = reinterpret_cast<sls_cloud*>(0x1);  // set to NULL by a failing getter
  sls_mesh* mesh = reinterpret_cast<sls_mesh*>(0x1);
  size_t count = 99;
  // Before any run: nothing fused.
  SLS_FAILS(sls_scan_get_cloud(scan.get(), &cloud, &error_), SLS_ERROR_INVALID_ARGUMENT, "no frame");
  EXPECT_EQ(cloud, nullptr);
  SLS_FAILS(sls_scan_get_mesh(scan.get(), &mesh, &error_), SLS_ERROR_INVALID_ARGUMENT, "no frame");
  EXPECT_EQ(mesh, nullptr);
  SLS_FAILS(sls_scan_get_trajectory(scan.get(), nullptr, nullptr, 0, &count, &error_), SLS_ERROR_INVALID_ARGUMENT,
            "no frame");
  // NULL handles and outputs.
  SLS_FAILS(sls_scan_get_cloud(nullptr, &cloud, &error_), SLS_ERROR_INVALID_ARGUMENT, "scan is NULL");
  SLS_FAILS(sls_scan_get_cloud(scan.get(), nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "cloud");
  SLS_FAILS(sls_scan_get_mesh(nullptr, &mesh, &error_), SLS_ERROR_INVALID_ARGUMENT, "scan is NULL");
  SLS_FAILS(sls_scan_get_mesh(scan.get(), nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "mesh");
  SLS_FAILS(sls_scan_get_trajectory(nullptr, nullptr, nullptr, 0, &count, &error_), SLS_ERROR_INVALID_ARGUMENT,
            "scan is NULL");
  SLS_FAILS(sls_scan_get_trajectory(scan.get(), nullptr, nullptr, 0, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT,
            "count");
  SLS_FAILS(sls_scan_render_preview(nullptr, nullptr, 64, 64, nullptr, 0, &error_), SLS_ERROR_INVALID_ARGUMENT,
            "scan is NULL");
  sls_cloud_data cloud_data;
  sls_cloud_data_init(&cloud_data);
  SLS_FAILS(sls_cloud_get_data(nullptr, &cloud_data, &error_), SLS_ERROR_INVALID_ARGUMENT, "cloud is NULL");
  sls_mesh_data mesh_data;
  sls_mesh_data_init(&mesh_data);
  SLS_FAILS(sls_mesh_get_data(nullptr, &mesh_data, &error_), SLS_ERROR_INVALID_ARGUMENT, "mesh is NULL");
  sls_cloud_destroy(nullptr);
  sls_mesh_destroy(nullptr);
  // The _init macros need a struct (sizeof *s); the functions behind them take NULL.
  sls_cloud_data_init_sized(nullptr, sizeof(sls_cloud_data));
  sls_mesh_data_init_sized(nullptr, sizeof(sls_mesh_data));

  SLS_OK_CALL(sls_scan_run_recording(scan.get(), recording().c_str(), &error_));
  SLS_OK_CALL(sls_scan_get_cloud(scan.get(), &cloud, &error_));
  const CloudPtr cloud_owned(cloud);
  SLS_FAILS(sls_cloud_get_data(cloud, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "data");
  // An uninitialised struct is refused; a caller of the first version gets its fields and no more.
  cloud_data.struct_size = 0;
  SLS_FAILS(sls_cloud_get_data(cloud, &cloud_data, &error_), SLS_ERROR_INVALID_ARGUMENT, "struct_size");
  struct {
    sls_cloud_data data;
    unsigned char canary[64];
  } padded;
  std::memset(&padded, 0x5A, sizeof(padded));
  padded.data.struct_size = offsetof(sls_cloud_data, confidence);  // an older, smaller struct: refused
  SLS_FAILS(sls_cloud_get_data(cloud, &padded.data, &error_), SLS_ERROR_INVALID_ARGUMENT, "struct_size");
  padded.data.struct_size = sizeof(sls_cloud_data);
  SLS_OK_CALL(sls_cloud_get_data(cloud, &padded.data, &error_));
  EXPECT_GT(padded.data.points, 1000u);
  EXPECT_TRUE(std::all_of(padded.canary, padded.canary + sizeof(padded.canary),
                          [](unsigned char byte) { return byte == 0x5A; }));

  // The trajectory: a short buffer is refused and left as it was, the count given.
  std::vector<double> stamps(3, -1.0), poses(3 * 16, -1.0);
  SLS_FAILS(sls_scan_get_trajectory(scan.get(), stamps.data(), poses.data(), 3, &count, &error_),
            SLS_ERROR_INVALID_ARGUMENT, "capacity 3 < 6");
  EXPECT_EQ(count, 6u);
  EXPECT_TRUE(std::all_of(stamps.begin(), stamps.end(), [](double v) { return v == -1.0; }));
  EXPECT_TRUE(std::all_of(poses.begin(), poses.end(), [](double v) { return v == -1.0; }));
  // Only the stamps (NULL poses): fine.
  stamps.resize(6);
  SLS_OK_CALL(sls_scan_get_trajectory(scan.get(), stamps.data(), nullptr, 6, &count, &error_));
  EXPECT_TRUE(std::is_sorted(stamps.begin(), stamps.end()));
}

}  // namespace
}  // namespace sls::test
