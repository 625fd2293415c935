// sls_scan_config as `sls scan` sets it, and the versioned structs' _init (sls.h):
//  - every _init writes no byte past the caller's struct (an older program's smaller struct, a
//    canary after it), and the exported NAME_init that programs built against the 0.4 headers
//    call writes the 0.4 struct only;
//  - every field reaches the scan's session options (read from the library's own sls_scan, as
//    its only observer for fields whose effect on a model is not a test's business: the
//    session's own tests cover what they do), with `sls scan`'s defaults;
//  - a bad value of each field is refused naming it; a 0.4-size struct gets the defaults of
//    the fields appended since, whatever lies after it;
//  - the fields that change what a run does, through runs: known poses, the loop closure a run
//    tries, and another calibration.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <functional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "sdk/capi/scan_internal.h"
#include "sdk/core/calibration.h"
#include "sdk/core/recording.h"
#include "sdk/core/trajectory.h"
#include "tests/api/c_results_fixture.h"

namespace sls::test {
namespace {

constexpr unsigned char kCanary = 0xA5;

// Stores an int in a C enum field as a C caller may (any int), which C++ cannot assign.
template <typename Enum>
void store_int(Enum& field, int value) {
  static_assert(sizeof(Enum) == sizeof(int), "C enums are ints here");
  std::memcpy(&field, &value, sizeof(value));
}

// T_init_sized(struct, size) for sizes from struct_size's alone to past the library's struct:
// exactly `size` bytes written (the zeros past the library's struct included), struct_size the
// caller's, the canary after them untouched, and the prefix the same as a whole struct's.
template <typename T>
void check_init_sized(void (*init_sized)(T*, size_t), const char* name) {
  SCOPED_TRACE(name);
  T whole;
  init_sized(&whole, sizeof(T));
  EXPECT_EQ(whole.struct_size, sizeof(T));
  for (const std::size_t size : {sizeof(std::size_t), sizeof(std::size_t) + 4, sizeof(T) / 2, sizeof(T) - 1,
                                 sizeof(T), sizeof(T) + 24}) {
    alignas(T) unsigned char buffer[sizeof(T) + 64];
    std::memset(buffer, kCanary, sizeof(buffer));
    init_sized(reinterpret_cast<T*>(buffer), size);
    std::size_t struct_size = 0;
    std::memcpy(&struct_size, buffer, sizeof(struct_size));
    EXPECT_EQ(struct_size, size);
    const std::size_t common = std::min(size, sizeof(T));
    const unsigned char* defaults = reinterpret_cast<const unsigned char*>(&whole);
    const std::size_t skip = sizeof(std::size_t);  // struct_size
    EXPECT_EQ(std::memcmp(buffer + skip, defaults + skip, common - skip), 0) << "size " << size;
    for (std::size_t i = common; i < size; ++i) ASSERT_EQ(buffer[i], 0) << "size " << size << ", byte " << i;
    for (std::size_t i = size; i < sizeof(buffer); ++i) {
      ASSERT_EQ(buffer[i], kCanary) << "size " << size << ", byte " << i;
    }
  }
  // A size no struct has: nothing written.
  unsigned char small[sizeof(std::size_t)];
  std::memset(small, kCanary, sizeof(small));
  init_sized(reinterpret_cast<T*>(small), sizeof(std::size_t) - 1);
  EXPECT_TRUE(std::all_of(small, small + sizeof(small), [](unsigned char b) { return b == kCanary; }));
  init_sized(nullptr, sizeof(T));  // no crash
}

// The exported NAME_init (what the macro hides): the struct as the 0.4 headers had it,
// `size_0_4` bytes, and not one byte more.
template <typename T>
void check_init_0_4(void (*init)(T*), std::size_t size_0_4, const char* name) {
  SCOPED_TRACE(name);
  alignas(T) unsigned char buffer[sizeof(T) + 64];
  std::memset(buffer, kCanary, sizeof(buffer));
  init(reinterpret_cast<T*>(buffer));
  std::size_t struct_size = 0;
  std::memcpy(&struct_size, buffer, sizeof(struct_size));
  EXPECT_EQ(struct_size, size_0_4);
  for (std::size_t i = size_0_4; i < sizeof(buffer); ++i) ASSERT_EQ(buffer[i], kCanary) << "byte " << i;
  init(nullptr);
}

// The sizeof a 0.4 struct had: its last field's end, rounded up to the alignment.
template <typename T>
constexpr std::size_t size_0_4(std::size_t end) {
  return (end + alignof(T) - 1) / alignof(T) * alignof(T);
}

#define SLS_CHECK_INIT(T)                 \
  check_init_sized<T>(T##_init_sized, #T); \
  check_init_0_4<T>(T##_init, sizeof(T), #T)

TEST(CStructVersions, InitWritesNothingPastTheCallersStruct) {
  // The structs that did not grow since 0.4: their 0.4 size is today's.
  SLS_CHECK_INIT(sls_context_config);
  SLS_CHECK_INIT(sls_device_info);
  SLS_CHECK_INIT(sls_camera_info);
  SLS_CHECK_INIT(sls_frame_info);
  SLS_CHECK_INIT(sls_projector_info);
  SLS_CHECK_INIT(sls_frame_report);
  SLS_CHECK_INIT(sls_capture_config);
  SLS_CHECK_INIT(sls_scan_summary);
  SLS_CHECK_INIT(sls_loop_closure);
  SLS_CHECK_INIT(sls_cloud_data);
  SLS_CHECK_INIT(sls_mesh_data);
  SLS_CHECK_INIT(sls_feed_config);
  SLS_CHECK_INIT(sls_depth_frame);
  SLS_CHECK_INIT(sls_stack_frame);
  SLS_CHECK_INIT(sls_intrinsics);
  SLS_CHECK_INIT(sls_calibration_view);
  // New in 0.6: the exported plain _init writes today's struct.
  SLS_CHECK_INIT(sls_eval_config);
  SLS_CHECK_INIT(sls_evaluation_summary);
  SLS_CHECK_INIT(sls_report_config);
  // New in 0.7, grown in 0.9 (a head's other cameras; the cameras of the result): the plain
  // exported _init writes the 0.7 struct, which a 0.7 program without the macro has.
  check_init_sized<sls_calibration_capture_config>(sls_calibration_capture_config_init_sized,
                                                   "sls_calibration_capture_config");
  check_init_0_4<sls_calibration_capture_config>(
      sls_calibration_capture_config_init,
      size_0_4<sls_calibration_capture_config>(offsetof(sls_calibration_capture_config, max_retries) + sizeof(int)),
      "sls_calibration_capture_config");
  check_init_sized<sls_calibration_capture_result>(sls_calibration_capture_result_init_sized,
                                                   "sls_calibration_capture_result");
  check_init_0_4<sls_calibration_capture_result>(
      sls_calibration_capture_result_init,
      size_0_4<sls_calibration_capture_result>(offsetof(sls_calibration_capture_result, capture_seconds) +
                                               sizeof(double)),
      "sls_calibration_capture_result");
  // New in 0.8.
  SLS_CHECK_INIT(sls_calibration_camera);
  // New in 0.3, grown in 0.10 (the board's kind, marker and dictionary): the plain exported
  // _init writes the first struct, which a program of 0.3 .. 0.9 without the macro has.
  check_init_sized<sls_calibration_config>(sls_calibration_config_init_sized, "sls_calibration_config");
  check_init_0_4<sls_calibration_config>(
      sls_calibration_config_init,
      size_0_4<sls_calibration_config>(offsetof(sls_calibration_config, max_rms_px) + sizeof(double)),
      "sls_calibration_config");
  check_init_sized<sls_calibration_summary>(sls_calibration_summary_init_sized, "sls_calibration_summary");
  check_init_0_4<sls_calibration_summary>(
      sls_calibration_summary_init,
      size_0_4<sls_calibration_summary>(offsetof(sls_calibration_summary, axis_point_err_um) + sizeof(double)),
      "sls_calibration_summary");
  // sls_scan_config grew in 0.5: a 0.4 program's struct ended with online_deformation, and the
  // library's 0.4 entry point must not write the fields appended since (it did: an overrun).
  check_init_sized<sls_scan_config>(sls_scan_config_init_sized, "sls_scan_config");
  check_init_0_4<sls_scan_config>(
      sls_scan_config_init,
      size_0_4<sls_scan_config>(offsetof(sls_scan_config, online_deformation) + sizeof(int)), "sls_scan_config");
  // It grew again in 0.7 (no_record, after 0.6's revisits): a 0.6 program's struct, as its
  // sls_scan_config_init macro sizes it, gets the defaults and not one byte past its end.
  {
    const std::size_t size_0_6 =
        size_0_4<sls_scan_config>(offsetof(sls_scan_config, revisits) + sizeof(sls_revisit_policy));
    ASSERT_LT(size_0_6, sizeof(sls_scan_config));
    alignas(sls_scan_config) unsigned char buffer[sizeof(sls_scan_config) + 64];
    std::memset(buffer, kCanary, sizeof(buffer));
    sls_scan_config_init_sized(reinterpret_cast<sls_scan_config*>(buffer), size_0_6);
    for (std::size_t i = size_0_6; i < sizeof(buffer); ++i) ASSERT_EQ(buffer[i], kCanary) << "byte " << i;
    sls_scan_config whole;
    sls_scan_config_init(&whole);
    EXPECT_EQ(whole.no_record, 0);
    EXPECT_GE(offsetof(sls_scan_config, no_record), size_0_6);
  }
}

class CScanConfig : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { directory_ = new TemporaryDirectory(); }
  static void TearDownTestSuite() {
    delete recording_;
    recording_ = nullptr;
    delete directory_;
  }
  // Made by the first test that runs one (ctest runs each test in its own process).
  static const std::string& recording() {
    if (recording_ == nullptr) recording_ = new std::string(sim_recording(*directory_, "knob", true, 3));
    return *recording_;
  }
  std::string scratch(const std::string& name) const { return directory_->file(name); }

  // The scan a config makes (it must be accepted).
  ScanPtr create(const sls_scan_config& config) {
    sls_scan* scan = nullptr;
    SLS_OK_CALL(sls_scan_create(context_.get(), &config, &scan, &error_));
    return ScanPtr(scan);
  }

  static TemporaryDirectory* directory_;
  static std::string* recording_;
  ContextPtr context_ = cpu_context();
};
TemporaryDirectory* CScanConfig::directory_ = nullptr;
std::string* CScanConfig::recording_ = nullptr;

TEST_F(CScanConfig, DefaultsAreSlsScans) {
  sls_scan_config config;
  sls_scan_config_init(&config);
  EXPECT_EQ(config.struct_size, sizeof(config));
  EXPECT_EQ(config.fusion, SLS_FUSION_GTSDF);
  EXPECT_EQ(config.calibration_path, nullptr);
  EXPECT_EQ(config.gtsdf_lambda, 0.0);
  EXPECT_EQ(config.gtsdf_kappa, 0.0);
  EXPECT_EQ(config.gtsdf_penalty, SLS_GTSDF_PENALTY_DEFAULT);
  EXPECT_EQ(config.gtsdf_iterations, 0);
  EXPECT_EQ(config.poses, SLS_POSES_TRACK);
  EXPECT_EQ(config.loop_frames, 2);
  EXPECT_EQ(config.photometric_weight, 0.0);
  EXPECT_EQ(config.icp_crease_deg, 15.0);
  EXPECT_EQ(config.icp_weights, SLS_ICP_WEIGHTS_CONFIDENCE);
  EXPECT_EQ(config.loop_closure, SLS_LOOP_CLOSURE_CALLER);
  EXPECT_EQ(config.revisits, SLS_REVISITS_AUTO);
  EXPECT_EQ(config.no_record, 0);

  // What samples/sls/cmd_scan.cpp sets for `sls scan` without options.
  const ScanPtr scan = create(config);
  const session::ScanSessionOptions& options = scan->options;
  const fusion::IntegrationOptions gtsdf = fusion::IntegrationOptions::gtsdf();
  EXPECT_EQ(options.integration.lambda, gtsdf.lambda);
  EXPECT_EQ(options.integration.kappa, gtsdf.kappa);
  EXPECT_EQ(options.integration.penalty, gtsdf.penalty);
  EXPECT_EQ(options.integration.iterations, gtsdf.iterations);
  EXPECT_FALSE(options.turntable_prior);
  EXPECT_EQ(options.voxel_size_m, 0.0);
  EXPECT_EQ(options.max_voxels, 48e6);  // a CPU context
  EXPECT_EQ(options.max_gpu_bytes, 0.0);  // no budget
  EXPECT_TRUE(options.deformation.enabled);
  EXPECT_EQ(options.deformation.loop_frames, session::DeformationOptions().loop_frames);
  EXPECT_EQ(options.tracking.photometric_weight, 0.0);
  EXPECT_TRUE(options.tracking.weight_by_confidence);
  EXPECT_EQ(options.tracking.crease_angle_deg, fusion::TrackingOptions().crease_angle_deg);
  EXPECT_FALSE(scan->groundtruth);
  EXPECT_EQ(scan->loop_closure, SLS_LOOP_CLOSURE_CALLER);
  EXPECT_FALSE(scan->calibration.has_value());
  EXPECT_EQ(options.revisits, session::RevisitPolicy::kAfterFirstRevolution);
}

TEST_F(CScanConfig, EveryFieldReachesTheSession) {
  // calibration_path: RunsDecodeWithTheGivenCalibration.
  sls_scan_config config;
  sls_scan_config_init(&config);
  config.use_turntable_prior = 1;
  config.voxel_size_m = 150e-6;
  config.volume_size_m[0] = 0.03;
  config.volume_size_m[1] = 0.04;
  config.volume_size_m[2] = 0.05;
  config.max_voxels = 20e6;
  config.online_deformation = 0;
  config.gtsdf_lambda = 2.5;
  config.gtsdf_kappa = 0.07;
  config.gtsdf_penalty = SLS_GTSDF_PENALTY_CHARBONNIER;
  config.gtsdf_iterations = 5;
  config.loop_frames = 4;
  config.photometric_weight = 0.25;
  config.icp_crease_deg = 30.0;
  config.icp_weights = SLS_ICP_WEIGHTS_EQUAL;
  config.loop_closure = SLS_LOOP_CLOSURE_AUTO;
  config.max_gpu_bytes = 6e9;
  config.revisits = SLS_REVISITS_MERGE;
  const ScanPtr scan = create(config);
  const session::ScanSessionOptions& options = scan->options;
  EXPECT_EQ(options.max_gpu_bytes, 6e9);
  EXPECT_EQ(options.revisits, session::RevisitPolicy::kMerge);
  config.revisits = SLS_REVISITS_KEEP;
  EXPECT_EQ(create(config)->options.revisits, session::RevisitPolicy::kKeep);
  EXPECT_EQ(options.integration.lambda, 2.5);
  EXPECT_EQ(options.integration.kappa, 0.07);
  EXPECT_EQ(options.integration.penalty, fusion::Penalty::kCharbonnier);
  EXPECT_EQ(options.integration.iterations, 5);
  EXPECT_TRUE(options.turntable_prior);
  EXPECT_EQ(options.voxel_size_m, 150e-6);
  EXPECT_EQ(options.volume_size_m, Eigen::Vector3d(0.03, 0.04, 0.05));
  EXPECT_EQ(options.max_voxels, 20e6);
  EXPECT_FALSE(options.deformation.enabled);
  EXPECT_EQ(options.deformation.loop_frames, 4);
  EXPECT_EQ(options.tracking.photometric_weight, 0.25);
  EXPECT_EQ(options.tracking.crease_angle_deg, 30.0);
  EXPECT_FALSE(options.tracking.weight_by_confidence);
  EXPECT_EQ(scan->loop_closure, SLS_LOOP_CLOSURE_AUTO);

  sls_scan_config tsdf;
  sls_scan_config_init(&tsdf);
  tsdf.fusion = SLS_FUSION_TSDF;
  tsdf.poses = SLS_POSES_GROUNDTRUTH;
  const ScanPtr known = create(tsdf);
  EXPECT_FALSE(known->options.integration.is_gtsdf());
  EXPECT_TRUE(known->groundtruth);
  EXPECT_FALSE(known->options.deformation.enabled);  // known poses: no drift, as the tool
}

TEST_F(CScanConfig, BadValuesAreRefusedNamingTheField) {
  struct Bad {
    const char* field;
    std::function<void(sls_scan_config&)> set;
    sls_status status = SLS_ERROR_INVALID_ARGUMENT;
  };
  const std::vector<Bad> bad = {
      {"config.fusion", [](sls_scan_config& c) { store_int(c.fusion, 7); }},
      {"config.voxel_size_m", [](sls_scan_config& c) { c.voxel_size_m = -1e-4; }},
      {"config.volume_size_m", [](sls_scan_config& c) { c.volume_size_m[1] = 0.1; }},
      {"config.max_voxels", [](sls_scan_config& c) { c.max_voxels = NAN; }},
      {"config.gtsdf_lambda", [](sls_scan_config& c) { c.gtsdf_lambda = 1e4; }},
      {"config.gtsdf_kappa", [](sls_scan_config& c) { c.gtsdf_kappa = -0.1; }},
      {"config.gtsdf_penalty", [](sls_scan_config& c) { store_int(c.gtsdf_penalty, 9); }},
      {"config.gtsdf_iterations", [](sls_scan_config& c) { c.gtsdf_iterations = 101; }},
      {"config.gtsdf_lambda/_kappa/_penalty/_iterations",
       [](sls_scan_config& c) {
         c.fusion = SLS_FUSION_TSDF;
         c.gtsdf_iterations = 4;
       }},
      {"config.poses", [](sls_scan_config& c) { store_int(c.poses, -1); }},
      {"config.loop_frames", [](sls_scan_config& c) { c.loop_frames = 0; }},
      {"config.loop_frames", [](sls_scan_config& c) { c.loop_frames = 65; }},
      {"config.photometric_weight", [](sls_scan_config& c) { c.photometric_weight = -1.0; }},
      {"config.icp_crease_deg", [](sls_scan_config& c) { c.icp_crease_deg = 180.0; }},
      {"config.icp_weights", [](sls_scan_config& c) { store_int(c.icp_weights, 2); }},
      {"config.loop_closure", [](sls_scan_config& c) { store_int(c.loop_closure, 3); }},
      {"config.max_gpu_bytes", [](sls_scan_config& c) { c.max_gpu_bytes = -1.0; }},
      {"config.max_gpu_bytes", [](sls_scan_config& c) { c.max_gpu_bytes = INFINITY; }},
      {"config.revisits", [](sls_scan_config& c) { store_int(c.revisits, 3); }},
      {"no-such-calibration.yml",
       [](sls_scan_config& c) { c.calibration_path = "no-such-calibration.yml"; }, SLS_ERROR_NOT_FOUND},
  };
  for (const Bad& b : bad) {
    SCOPED_TRACE(b.field);
    sls_scan_config config;
    sls_scan_config_init(&config);
    b.set(config);
    sls_scan* scan = nullptr;
    SLS_FAILS(sls_scan_create(context_.get(), &config, &scan, &error_), b.status, b.field);
    EXPECT_EQ(scan, nullptr);
  }
}

TEST_F(CScanConfig, AnOlderStructGetsTheDefaultsOfTheFieldsItLacks) {
  // A program built against the 0.4 headers: its struct ends with online_deformation, and what
  // lies after it in memory (here values every new field refuses) is none of the library's.
  sls_scan_config config;
  std::memset(&config, 0xFF, sizeof(config));
  sls_scan_config_init(&config);
  config.struct_size = offsetof(sls_scan_config, online_deformation) + sizeof(int);
  config.online_deformation = 0;
  config.gtsdf_iterations = 1000;
  config.loop_frames = -3;
  config.icp_crease_deg = -1.0;
  store_int(config.poses, 5);
  config.calibration_path = "no-such-calibration.yml";
  const ScanPtr scan = create(config);
  EXPECT_FALSE(scan->options.deformation.enabled);  // its own field
  EXPECT_EQ(scan->options.integration.iterations, fusion::IntegrationOptions::gtsdf().iterations);
  EXPECT_EQ(scan->options.deformation.loop_frames, 2);
  EXPECT_EQ(scan->options.tracking.crease_angle_deg, 15.0);
  EXPECT_FALSE(scan->groundtruth);
  EXPECT_FALSE(scan->calibration.has_value());

  // A 0.5 program's struct ends with max_gpu_bytes: revisits, beyond it, keeps its default.
  sls_scan_config v05;
  sls_scan_config_init(&v05);
  store_int(v05.revisits, 7);
  v05.struct_size = offsetof(sls_scan_config, max_gpu_bytes) + sizeof(double);
  EXPECT_EQ(create(v05)->options.revisits, session::RevisitPolicy::kAfterFirstRevolution);
}

TEST_F(CScanConfig, KnownPosesAreTheRecordingsGroundTruth) {
  sls_scan_config config;
  sls_scan_config_init(&config);
  config.poses = SLS_POSES_GROUNDTRUTH;
  config.max_voxels = 2e6;  // the automatic voxel grown to fit: a small volume, a quick test
  const ScanPtr scan = create(config);
  SLS_OK_CALL(sls_scan_run_recording(scan.get(), recording().c_str(), &error_));
  sls_scan_summary summary;
  sls_scan_summary_init(&summary);
  SLS_OK_CALL(sls_scan_get_summary(scan.get(), &summary, &error_));
  EXPECT_EQ(summary.fused, 3u);
  EXPECT_EQ(summary.volume_moves, 0u);  // one fixed volume around the object
  EXPECT_EQ(summary.deformation_nodes, 0u);
  // The trajectory is the ground truth's.
  SLS_OK_CALL(sls_scan_write_trajectory(scan.get(), scratch("known.txt").c_str(), &error_));
  const std::vector<StampedPose> written = read_tum_trajectory(scratch("known.txt"));
  const std::vector<StampedPose> truth =
      read_tum_trajectory(RecordingReader::open(recording()).groundtruth_folder() + "/trajectory.txt");
  ASSERT_EQ(written.size(), truth.size());
  for (std::size_t i = 0; i < truth.size(); ++i) {
    EXPECT_LT((written[i].T_world_camera.matrix() - truth[i].T_world_camera.matrix()).norm(), 1e-5) << i;
  }
  // Fed frames have no ground truth.
  sls_feed_config feed;
  sls_feed_config_init(&feed);
  const std::string calibration = recording() + "/calibration.yml";
  feed.calibration_path = calibration.c_str();
  SLS_FAILS(sls_scan_start_feed(scan.get(), &feed, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT,
            "SLS_POSES_GROUNDTRUTH");
}

// The library's warnings, collected (sls_log.h).
void collect_log(sls_log_level level, const char* message, void* user) {
  if (level >= SLS_LOG_WARNING) static_cast<std::vector<std::string>*>(user)->emplace_back(message);
}

bool any_contains(const std::vector<std::string>& lines, const std::string& part) {
  return std::any_of(lines.begin(), lines.end(),
                     [&](const std::string& line) { return line.find(part) != std::string::npos; });
}

TEST_F(CScanConfig, ARunClosesTheLoopAsConfigured) {
  // The recording's three frames are a full revolution (120 degree steps), too coarse for the
  // closure to register (closures that close: test_c_scan.c), so a run's closure is seen by the
  // warning it leaves (the default, SLS_LOOP_CLOSURE_CALLER, tries none: the other tests' runs).
  sls_scan_config config;
  sls_scan_config_init(&config);
  config.use_turntable_prior = 1;
  config.max_voxels = 2e6;  // quick
  const struct {
    sls_loop_closure_mode mode;
    const char* why;  // in the warning of the closure tried
  } cases[] = {{SLS_LOOP_CLOSURE_ON, "config.loop_closure SLS_LOOP_CLOSURE_ON"},
               {SLS_LOOP_CLOSURE_AUTO, "a full turntable revolution"}};
  for (const auto& c : cases) {
    SCOPED_TRACE(static_cast<int>(c.mode));
    config.loop_closure = c.mode;
    const ScanPtr scan = create(config);
    std::vector<std::string> warnings;
    SLS_OK_CALL(sls_set_log_callback(collect_log, &warnings, &error_));
    SLS_OK_CALL(sls_scan_run_recording(scan.get(), recording().c_str(), &error_));  // still OK
    SLS_OK_CALL(sls_set_log_callback(nullptr, nullptr, &error_));
    EXPECT_TRUE(any_contains(warnings, "was not closed"));
    EXPECT_TRUE(any_contains(warnings, c.why));
    sls_scan_summary summary;
    sls_scan_summary_init(&summary);
    SLS_OK_CALL(sls_scan_get_summary(scan.get(), &summary, &error_));
    EXPECT_EQ(summary.loop_closed, 0);
  }
}

TEST_F(CScanConfig, RunsDecodeWithTheGivenCalibration) {
  // A calibration whose camera sees 2 % wider: the depth maps back-project elsewhere.
  ScannerCalibration other = read_calibration(recording() + "/calibration.yml");
  other.camera.fx *= 0.98;
  other.camera.fy *= 0.98;
  write_calibration(scratch("wider.yml"), other);
  sls_scan_config config;
  sls_scan_config_init(&config);
  config.use_turntable_prior = 1;
  config.online_deformation = 0;
  config.max_voxels = 2e6;  // quick
  const ScanPtr own = create(config);
  SLS_OK_CALL(sls_scan_run_recording(own.get(), recording().c_str(), &error_));
  const std::string wider = scratch("wider.yml");
  config.calibration_path = wider.c_str();
  const ScanPtr given = create(config);
  ASSERT_TRUE(given->calibration.has_value());  // read by sls_scan_create
  EXPECT_EQ(given->calibration->camera.fx, other.camera.fx);
  SLS_OK_CALL(sls_scan_run_recording(given.get(), recording().c_str(), &error_));
  EXPECT_NE(scan_cloud(given.get()).positions, scan_cloud(own.get()).positions);

  // One of another camera size is refused by the run, naming both sizes.
  other.camera.width /= 2;
  other.camera.height /= 2;
  write_calibration(scratch("half.yml"), other);
  const std::string half = scratch("half.yml");
  config.calibration_path = half.c_str();
  const ScanPtr mismatched = create(config);
  SLS_FAILS(sls_scan_run_recording(mismatched.get(), recording().c_str(), &error_), SLS_ERROR_INVALID_ARGUMENT,
            "was recorded at 400x300");
}

}  // namespace
}  // namespace sls::test
