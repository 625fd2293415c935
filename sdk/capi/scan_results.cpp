// sls_results.h: the model, trajectory and preview of a scan in memory. The cloud and mesh
// handles share the scan's extracted surface (scan_internal.h), so a snapshot costs one
// extraction and no copy, and stays valid after the scan moves on or is destroyed.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <thread>
#include <vector>

#include "fusion/extract.h"
#include "sdk/capi/capi_guard.h"
#include "sdk/capi/scan_internal.h"
#include "sdk/capi/versioned_struct.h"
#include "sdk/core/error.h"
#include "sdk/core/image.h"
#include "sdk/core/pose.h"
#include "sdk/core/trajectory.h"
#include "sls/sls_results.h"

struct sls_cloud {
  std::shared_ptr<const sls::fusion::ExtractedSurface> surface;
};

struct sls_mesh {
  std::shared_ptr<const sls::fusion::ExtractedSurface> surface;
};

namespace {

constexpr std::size_t kCloudDataFirstVersionSize = offsetof(sls_cloud_data, correction) + sizeof(const float*);
constexpr std::size_t kMeshDataFirstVersionSize = offsetof(sls_mesh_data, indices) + sizeof(const int32_t*);
constexpr int kMinPreviewSide = 16, kMaxPreviewSide = 4096;

// A getter's access to a scan: held for the call, or the frame callback's own thread (the run is
// then between two frames, and waits for the callback).
class ResultsAccess {
 public:
  explicit ResultsAccess(const sls_scan& scan)
      : hold_(scan), in_callback_(!hold_.held() && scan.callback_thread.load() == std::this_thread::get_id()) {}
  bool allowed() const { return hold_.held() || in_callback_; }

 private:
  sls::capi::ScanHold hold_;
  bool in_callback_;
};

sls_status report_busy(const char* function, sls_error** error) {
  return sls::capi::report(SLS_ERROR_BUSY, function,
                           "the scan is in use by another thread (a run, or another call on it); from the frame "
                           "callback the getters are allowed",
                           error);
}

const float* floats_or_null(const std::vector<Eigen::Vector3f>& values) {
  return values.empty() ? nullptr : values.front().data();
}

const float* floats_or_null(const std::vector<float>& values) { return values.empty() ? nullptr : values.data(); }

const float* property_or_null(const sls::PointCloud& cloud, const char* name) {
  const sls::PointProperty* property = cloud.find_property(name);
  return property == nullptr ? nullptr : floats_or_null(property->values);
}

// The caller's 4x4 row-major pose; throws kInvalidArgument unless finite and rigid.
sls::Pose pose_from_c(const double* values) {
  Eigen::Matrix4d matrix;
  for (int row = 0; row < 4; ++row) {
    for (int column = 0; column < 4; ++column) {
      const double value = values[4 * row + column];
      if (!std::isfinite(value)) {
        sls::throw_error(sls::ErrorCode::kInvalidArgument, "T_world_camera[{}][{}] is {}", row, column, value);
      }
      matrix(row, column) = value;
    }
  }
  return sls::Pose::from_matrix(matrix);
}

// The last fused frame's pose (the session's report, as tracked: the volume's frame).
sls::Pose last_fused_pose(const sls::session::ScanSession& session) {
  const std::vector<sls::session::FrameReport>& frames = session.frames();
  for (auto frame = frames.rbegin(); frame != frames.rend(); ++frame) {
    if (frame->status == sls::session::FrameStatus::kFused) return frame->T_world_camera;
  }
  sls::throw_error(sls::ErrorCode::kInvalidArgument, "no frame has been fused: nothing to render");
}

// `source` resampled into width x height bytes: each output pixel the mean of the source pixels
// its footprint covers (at least the one under its centre), so a reduction does not alias.
void resample(const sls::Image8u& source, int width, int height, std::uint8_t* out) {
  const double sx = static_cast<double>(source.width()) / width, sy = static_cast<double>(source.height()) / height;
  for (int y = 0; y < height; ++y) {
    const int y0 = std::min(static_cast<int>(y * sy), source.height() - 1);
    const int y1 = std::max(y0 + 1, std::min(static_cast<int>(std::ceil((y + 1) * sy)), source.height()));
    for (int x = 0; x < width; ++x) {
      const int x0 = std::min(static_cast<int>(x * sx), source.width() - 1);
      const int x1 = std::max(x0 + 1, std::min(static_cast<int>(std::ceil((x + 1) * sx)), source.width()));
      unsigned sum = 0;
      for (int v = y0; v < y1; ++v) {
        for (int u = x0; u < x1; ++u) sum += source(u, v);
      }
      const unsigned count = static_cast<unsigned>((y1 - y0) * (x1 - x0));
      out[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)] =
          static_cast<std::uint8_t>((sum + count / 2) / count);
    }
  }
}

}  // namespace

extern "C" {

SLS_API sls_status sls_scan_get_cloud(const sls_scan* scan, sls_cloud** cloud, sls_error** error) {
  SLS_CAPI_REQUIRE(cloud != nullptr, error, "cloud (the output pointer) is NULL");
  *cloud = nullptr;
  SLS_CAPI_REQUIRE(scan != nullptr, error, "scan is NULL");
  const ResultsAccess access(*scan);
  if (!access.allowed()) return report_busy(__func__, error);
  return sls::capi::guarded(__func__, error, [&] { *cloud = new sls_cloud{sls::capi::model_surface(*scan)}; });
}

SLS_API void sls_cloud_destroy(sls_cloud* cloud) { delete cloud; }

SLS_CAPI_DEFINE_INIT(sls_cloud_data, correction, sls::capi::zeroed<sls_cloud_data>())

SLS_API sls_status sls_cloud_get_data(const sls_cloud* cloud, sls_cloud_data* data, sls_error** error) {
  SLS_CAPI_REQUIRE(cloud != nullptr, error, "cloud is NULL");
  SLS_CAPI_REQUIRE(data != nullptr, error, "data (the output pointer) is NULL");
  return sls::capi::guarded(__func__, error, [&] {
    const sls::PointCloud& points = cloud->surface->cloud;
    sls_cloud_data filled;
    sls_cloud_data_init(&filled);
    filled.points = points.size();
    filled.positions = floats_or_null(points.positions);
    filled.normals = floats_or_null(points.normals);
    filled.confidence = floats_or_null(points.confidence);
    filled.correction = property_or_null(points, "correction");
    sls::capi::write_versioned(filled, data, kCloudDataFirstVersionSize, "sls_cloud_data");
  });
}

SLS_API sls_status sls_scan_get_mesh(const sls_scan* scan, sls_mesh** mesh, sls_error** error) {
  SLS_CAPI_REQUIRE(mesh != nullptr, error, "mesh (the output pointer) is NULL");
  *mesh = nullptr;
  SLS_CAPI_REQUIRE(scan != nullptr, error, "scan is NULL");
  const ResultsAccess access(*scan);
  if (!access.allowed()) return report_busy(__func__, error);
  return sls::capi::guarded(__func__, error, [&] { *mesh = new sls_mesh{sls::capi::model_surface(*scan)}; });
}

SLS_API void sls_mesh_destroy(sls_mesh* mesh) { delete mesh; }

SLS_CAPI_DEFINE_INIT(sls_mesh_data, indices, sls::capi::zeroed<sls_mesh_data>())

SLS_API sls_status sls_mesh_get_data(const sls_mesh* mesh, sls_mesh_data* data, sls_error** error) {
  SLS_CAPI_REQUIRE(mesh != nullptr, error, "mesh is NULL");
  SLS_CAPI_REQUIRE(data != nullptr, error, "data (the output pointer) is NULL");
  return sls::capi::guarded(__func__, error, [&] {
    const sls::TriangleMesh& triangles = mesh->surface->mesh;
    sls_mesh_data filled;
    sls_mesh_data_init(&filled);
    filled.vertices = triangles.vertices.size();
    filled.faces = triangles.faces.size();
    filled.positions = floats_or_null(triangles.vertices.positions);
    filled.normals = floats_or_null(triangles.vertices.normals);
    filled.confidence = floats_or_null(triangles.vertices.confidence);
    filled.indices = triangles.faces.empty() ? nullptr : triangles.faces.front().data();
    sls::capi::write_versioned(filled, data, kMeshDataFirstVersionSize, "sls_mesh_data");
  });
}

SLS_API sls_status sls_scan_get_trajectory(const sls_scan* scan, double* timestamps_s, double* T_world_camera,
                                           size_t capacity, size_t* count, sls_error** error) {
  SLS_CAPI_REQUIRE(scan != nullptr, error, "scan is NULL");
  SLS_CAPI_REQUIRE(count != nullptr, error, "count (the output pointer) is NULL");
  const ResultsAccess access(*scan);
  if (!access.allowed()) return report_busy(__func__, error);
  return sls::capi::guarded(__func__, error, [&] {
    const std::vector<sls::StampedPose> poses = sls::capi::fused_session(*scan).trajectory();
    *count = poses.size();
    if (capacity == 0 && timestamps_s == nullptr && T_world_camera == nullptr) return;  // the size query
    if (capacity < poses.size()) {
      sls::throw_error(sls::ErrorCode::kInvalidArgument, "capacity {} < {} poses (nothing copied)", capacity,
                       poses.size());
    }
    for (std::size_t i = 0; i < poses.size(); ++i) {
      if (timestamps_s != nullptr) timestamps_s[i] = poses[i].timestamp_s;
      if (T_world_camera != nullptr) {
        const Eigen::Matrix4d matrix = poses[i].T_world_camera.matrix();
        for (int row = 0; row < 4; ++row) {
          for (int column = 0; column < 4; ++column) T_world_camera[16 * i + static_cast<std::size_t>(4 * row + column)] = matrix(row, column);
        }
      }
    }
  });
}

SLS_API sls_status sls_scan_render_preview(const sls_scan* scan, const double* T_world_camera, int width, int height,
                                           uint8_t* pixels, size_t pixel_count, sls_error** error) {
  SLS_CAPI_REQUIRE(scan != nullptr, error, "scan is NULL");
  SLS_CAPI_REQUIRE(pixels != nullptr, error, "pixels is NULL");
  SLS_CAPI_REQUIRE(width >= kMinPreviewSide && width <= kMaxPreviewSide && height >= kMinPreviewSide &&
                       height <= kMaxPreviewSide,
                   error, "width and height must be 16 .. 4096");
  SLS_CAPI_REQUIRE(pixel_count >= static_cast<size_t>(width) * static_cast<size_t>(height), error,
                   "pixel_count is less than width x height");
  const ResultsAccess access(*scan);
  if (!access.allowed()) return report_busy(__func__, error);
  return sls::capi::guarded(__func__, error, [&] {
    const sls::session::ScanSession& session = sls::capi::fused_session(*scan);
    const sls::Pose pose = T_world_camera != nullptr ? pose_from_c(T_world_camera) : last_fused_pose(session);
    const sls::Image8u rendered = session.render(pose);
    resample(rendered, width, height, pixels);
  });
}

}  // extern "C"
