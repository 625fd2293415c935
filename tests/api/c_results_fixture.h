// Shared by the C API's in-memory results and feed tests (test_c_results.cpp, test_c_feed.cpp):
// simulated recordings made once per test program, scans through the public C API, and the C
// structs read back as C++ values.
#pragma once

#include <sls/sls.h>

#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "drivers/sim/sim_recording.h"
#include "sdk/core/device.h"
#include "tests/support/test_support.h"

namespace sls::test {

// A call that must succeed: its message when it does not.
inline ::testing::AssertionResult ok(sls_status status, sls_error* error) {
  if (status == SLS_OK) return ::testing::AssertionSuccess();
  ::testing::AssertionResult failure = ::testing::AssertionFailure()
                                       << sls_status_str(status) << ": " << sls_error_message(error);
  sls_error_free(error);
  return failure;
}
#define SLS_OK_CALL(call)                \
  do {                                   \
    sls_error* error_ = nullptr;         \
    const sls_status status_ = (call);   \
    EXPECT_TRUE(ok(status_, error_));    \
  } while (0)

// The status of a call that must fail, and whether its message contains `part`.
inline ::testing::AssertionResult fails(sls_status status, sls_error* error, sls_status expected, const char* part) {
  const std::string message = sls_error_message(error);
  const sls_status recorded = sls_error_status(error);
  sls_error_free(error);
  if (status != expected || recorded != expected) {
    return ::testing::AssertionFailure() << "status " << sls_status_str(status) << ", expected "
                                         << sls_status_str(expected) << ": " << message;
  }
  if (part != nullptr && message.find(part) == std::string::npos) {
    return ::testing::AssertionFailure() << "message \"" << message << "\" lacks \"" << part << "\"";
  }
  return ::testing::AssertionSuccess();
}
#define SLS_FAILS(call, expected, part)                        \
  do {                                                         \
    sls_error* error_ = nullptr;                               \
    const sls_status status_ = (call);                         \
    EXPECT_TRUE(fails(status_, error_, (expected), (part)));   \
  } while (0)

struct ContextDeleter {
  void operator()(sls_context* context) const { sls_context_destroy(context); }
};
struct ScanDeleter {
  void operator()(sls_scan* scan) const { sls_scan_destroy(scan); }
};
struct CloudDeleter {
  void operator()(sls_cloud* cloud) const { sls_cloud_destroy(cloud); }
};
struct MeshDeleter {
  void operator()(sls_mesh* mesh) const { sls_mesh_destroy(mesh); }
};
using ContextPtr = std::unique_ptr<sls_context, ContextDeleter>;
using ScanPtr = std::unique_ptr<sls_scan, ScanDeleter>;
using CloudPtr = std::unique_ptr<sls_cloud, CloudDeleter>;
using MeshPtr = std::unique_ptr<sls_mesh, MeshDeleter>;

inline ContextPtr cpu_context() {
  sls_context_config config;
  sls_context_config_init(&config);
  config.device = SLS_DEVICE_CPU;
  sls_context* context = nullptr;
  EXPECT_EQ(sls_context_create(SLS_API_VERSION, &config, &context, nullptr), SLS_OK);
  return ContextPtr(context);
}

inline ScanPtr make_scan(sls_context* context, bool online_deformation) {
  sls_scan_config config;
  sls_scan_config_init(&config);
  config.use_turntable_prior = 1;
  config.online_deformation = online_deformation ? 1 : 0;
  sls_scan* scan = nullptr;
  EXPECT_EQ(sls_scan_create(context, &config, &scan, nullptr), SLS_OK);
  return ScanPtr(scan);
}

// The simulated knurled knob (ci preset: 400 x 300) in `frames` turntable steps, written once.
inline std::string sim_recording(const TemporaryDirectory& directory, const std::string& name, bool depth_mode,
                                 int frames) {
  const std::string folder = directory.file(name);
  sim::SimRecordingOptions options;
  options.object = "knurled-knob";
  options.depth_mode = depth_mode;
  options.rig.preset = "ci";
  options.rig.frames = frames;
  options.reference_spacing_m = 1e-3;
  sim::write_sim_recording(folder, options, Device::cpu(), {});
  return folder;
}

// A cloud's arrays as vectors (empty for a NULL array).
struct CloudCopy {
  std::vector<float> positions, normals, confidence, correction;
};

inline CloudCopy copy_cloud(const sls_cloud* cloud) {
  sls_cloud_data data;
  sls_cloud_data_init(&data);
  CloudCopy copy;
  if (sls_cloud_get_data(cloud, &data, nullptr) != SLS_OK) {
    ADD_FAILURE() << "sls_cloud_get_data failed";
    return copy;
  }
  const auto take = [](const float* values, std::size_t count) {
    return values == nullptr ? std::vector<float>() : std::vector<float>(values, values + count);
  };
  copy.positions = take(data.positions, 3 * data.points);
  copy.normals = take(data.normals, 3 * data.points);
  copy.confidence = take(data.confidence, data.points);
  copy.correction = take(data.correction, data.points);
  return copy;
}

inline CloudCopy scan_cloud(const sls_scan* scan) {
  sls_cloud* cloud = nullptr;
  SLS_OK_CALL(sls_scan_get_cloud(scan, &cloud, &error_));
  const CloudPtr owned(cloud);
  return cloud == nullptr ? CloudCopy() : copy_cloud(cloud);
}

}  // namespace sls::test
