// Frames the caller feeds (sls_feed.h): a recording's depth maps fed one by one (with a padded
// row stride) give the model a run of the recording gives, bit for bit, and the frame callback
// hands back each frame's depth map; the same for pattern stacks (16 and 8 bit); the mistakes
// (NULL frames and arrays, wrong sizes, strides, stack lengths, pixel sizes, a feed not started,
// a cancelled scan, a call from another thread or from the callback during a run) are statuses
// that change nothing. And the log callback (sls_log.h): a skipped frame's warning delivered on
// the scan's thread, the level, and a callback that tries to replace itself.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "sdk/core/recording.h"
#include "tests/api/c_results_fixture.h"

namespace sls::test {
namespace {

class CFeed : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    directory_ = new TemporaryDirectory();
    depth_recording_ = new std::string(sim_recording(*directory_, "depth", true, 6));
    stack_recording_ = new std::string(sim_recording(*directory_, "stacks", false, 3));
  }
  static void TearDownTestSuite() {
    delete depth_recording_;
    delete stack_recording_;
    delete directory_;
  }
  static const std::string& depth_recording() { return *depth_recording_; }
  static const std::string& stack_recording() { return *stack_recording_; }

  static TemporaryDirectory* directory_;
  static std::string* depth_recording_;
  static std::string* stack_recording_;
  ContextPtr context_ = cpu_context();
};
TemporaryDirectory* CFeed::directory_ = nullptr;
std::string* CFeed::depth_recording_ = nullptr;
std::string* CFeed::stack_recording_ = nullptr;

// What the frame callback got: reports and each depth map, copied.
struct Seen {
  std::vector<int> index;
  std::vector<sls_frame_status> status;
  std::vector<std::vector<float>> depth;
  std::vector<std::thread::id> thread;
};

void on_frame_seen(const sls_frame_report* report, void* user) {
  Seen& seen = *static_cast<Seen*>(user);
  seen.index.push_back(report->index);
  seen.status.push_back(report->status);
  seen.thread.push_back(std::this_thread::get_id());
  std::vector<float> depth;
  if (report->depth_m != nullptr) {
    EXPECT_EQ(report->depth_stride_bytes, sizeof(float) * static_cast<std::size_t>(report->depth_width));
    depth.assign(report->depth_m, report->depth_m + report->depth_width * report->depth_height);
  }
  EXPECT_EQ(report->depth_device, nullptr);  // a CPU context
  seen.depth.push_back(std::move(depth));
}

sls_feed_config feed_config(const std::string& recording) {
  static std::string calibration;  // read during the call only
  calibration = recording + "/calibration.yml";
  sls_feed_config config;
  sls_feed_config_init(&config);
  config.calibration_path = calibration.c_str();
  return config;
}

TEST_F(CFeed, FedDepthMapsGiveTheRunsModel) {
  const ScanPtr run = make_scan(context_.get(), false);
  Seen run_seen;
  SLS_OK_CALL(sls_scan_set_frame_callback(run.get(), on_frame_seen, &run_seen, &error_));
  SLS_OK_CALL(sls_scan_run_recording(run.get(), depth_recording().c_str(), &error_));
  const CloudCopy expected = scan_cloud(run.get());
  ASSERT_GT(expected.positions.size(), 3000u);

  const ScanPtr fed = make_scan(context_.get(), false);
  Seen seen;
  SLS_OK_CALL(sls_scan_set_frame_callback(fed.get(), on_frame_seen, &seen, &error_));
  const sls_feed_config config = feed_config(depth_recording());
  int patterns = 0;
  SLS_OK_CALL(sls_scan_start_feed(fed.get(), &config, &patterns, &error_));
  EXPECT_GT(patterns, 8);
  const RecordingReader recording = RecordingReader::open(depth_recording());
  std::vector<std::vector<float>> given;
  for (std::size_t i = 0; i < recording.frame_count(); ++i) {
    const Image32f depth = *recording.load_depth_m(i);
    const int width = depth.width(), height = depth.height(), stride = width + 7;
    // Rows 7 floats apart more than their width, the padding NaN: only the rows are read.
    std::vector<float> padded(static_cast<std::size_t>(stride * height), std::numeric_limits<float>::quiet_NaN());
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) padded[static_cast<std::size_t>(y * stride + x)] = depth(x, y);
    }
    given.emplace_back(depth.data(), depth.data() + depth.pixel_count());
    sls_depth_frame frame;
    sls_depth_frame_init(&frame);
    frame.depth_m = padded.data();
    frame.width = width;
    frame.height = height;
    frame.stride_bytes = sizeof(float) * static_cast<std::size_t>(stride);
    frame.timestamp_ns = recording.frame(i).timestamp_ns;
    frame.has_turntable_angle = 1;
    frame.turntable_angle_deg = *recording.frame(i).turntable_angle_deg;
    sls_frame_report report;
    sls_frame_report_init(&report);
    SLS_OK_CALL(sls_scan_add_depth(fed.get(), &frame, &report, &error_));
    EXPECT_EQ(report.index, static_cast<int>(i));
    EXPECT_EQ(report.status, SLS_FRAME_FUSED) << report.reason;
    EXPECT_EQ(report.recording_frames, 0u);
    EXPECT_EQ(report.depth_m, nullptr);  // the depth is the callback's only
  }
  EXPECT_EQ(scan_cloud(fed.get()).positions, expected.positions);
  EXPECT_EQ(scan_cloud(fed.get()).normals, expected.normals);
  ASSERT_EQ(seen.index.size(), recording.frame_count());
  for (std::size_t i = 0; i < seen.index.size(); ++i) {
    EXPECT_EQ(seen.index[i], static_cast<int>(i));
    EXPECT_EQ(seen.thread[i], std::this_thread::get_id());
    // The depth as fused: the caller's values (NaN-free here), unpadded; the run's the same.
    EXPECT_EQ(seen.depth[i], given[i]) << "frame " << i;
    EXPECT_EQ(run_seen.depth[i], given[i]) << "frame " << i;
  }
  sls_scan_summary summary;
  sls_scan_summary_init(&summary);
  SLS_OK_CALL(sls_scan_get_summary(fed.get(), &summary, &error_));
  EXPECT_EQ(summary.frames, 6u);
  EXPECT_EQ(summary.fused, 6u);
}

// Feeds the stack recording's frames as `bytes` per pixel images (8-bit: values shifted down).
void feed_stacks(sls_scan* scan, const std::string& folder, int bytes, Seen* seen) {
  const RecordingReader recording = RecordingReader::open(folder);
  for (std::size_t i = 0; i < recording.frame_count(); ++i) {
    const std::vector<Image16u> images = recording.load_images(i);
    std::vector<std::vector<std::uint8_t>> eight(images.size());
    std::vector<const void*> pointers;
    for (std::size_t k = 0; k < images.size(); ++k) {
      if (bytes == 2) {
        pointers.push_back(images[k].data());
      } else {
        for (std::size_t p = 0; p < images[k].pixel_count(); ++p) {
          eight[k].push_back(static_cast<std::uint8_t>(images[k].data()[p] >> 4));
        }
        pointers.push_back(eight[k].data());
      }
    }
    sls_stack_frame frame;
    sls_stack_frame_init(&frame);
    frame.images = pointers.data();
    frame.image_count = pointers.size();
    frame.width = images.front().width();
    frame.height = images.front().height();
    frame.bytes_per_pixel = bytes;
    frame.timestamp_ns = recording.frame(i).timestamp_ns;
    frame.has_turntable_angle = 1;
    frame.turntable_angle_deg = *recording.frame(i).turntable_angle_deg;
    SLS_OK_CALL(sls_scan_add_stack(scan, &frame, nullptr, &error_));
  }
  if (seen != nullptr) {
    ASSERT_EQ(seen->index.size(), recording.frame_count());
  }
}

TEST_F(CFeed, FedPatternStacksGiveTheRunsModel) {
  const ScanPtr run = make_scan(context_.get(), false);
  Seen run_seen;
  SLS_OK_CALL(sls_scan_set_frame_callback(run.get(), on_frame_seen, &run_seen, &error_));
  SLS_OK_CALL(sls_scan_run_recording(run.get(), stack_recording().c_str(), &error_));
  const CloudCopy expected = scan_cloud(run.get());
  ASSERT_GT(expected.positions.size(), 3000u);

  const ScanPtr fed = make_scan(context_.get(), false);
  Seen seen;
  SLS_OK_CALL(sls_scan_set_frame_callback(fed.get(), on_frame_seen, &seen, &error_));
  const sls_feed_config config = feed_config(stack_recording());
  int patterns = 0;
  SLS_OK_CALL(sls_scan_start_feed(fed.get(), &config, &patterns, &error_));
  EXPECT_EQ(static_cast<std::size_t>(patterns), RecordingReader::open(stack_recording()).info().images_per_frame);
  feed_stacks(fed.get(), stack_recording(), 2, &seen);
  EXPECT_EQ(scan_cloud(fed.get()).positions, expected.positions);
  for (sls_frame_status status : seen.status) EXPECT_EQ(status, SLS_FRAME_FUSED);
  // Each stack's decoded depth map reaches the callback, the run's and the feed's the same.
  ASSERT_EQ(run_seen.depth.size(), seen.depth.size());
  for (std::size_t i = 0; i < seen.depth.size(); ++i) {
    EXPECT_EQ(seen.depth[i].size(), 400u * 300u);
    EXPECT_EQ(seen.depth[i], run_seen.depth[i]) << "frame " << i;
  }

  // 8-bit images of the same stacks (bit_depth 8): decoded and fused too.
  const ScanPtr eight = make_scan(context_.get(), false);
  sls_feed_config config8 = feed_config(stack_recording());
  config8.bit_depth = 8;
  SLS_OK_CALL(sls_scan_start_feed(eight.get(), &config8, nullptr, &error_));
  feed_stacks(eight.get(), stack_recording(), 1, nullptr);
  sls_scan_summary summary;
  sls_scan_summary_init(&summary);
  SLS_OK_CALL(sls_scan_get_summary(eight.get(), &summary, &error_));
  EXPECT_EQ(summary.fused, 3u);
}

TEST_F(CFeed, MistakesChangeNothing) {
  const ScanPtr scan = make_scan(context_.get(), false);
  std::vector<float> depth(400 * 300, 0.1f);
  sls_depth_frame frame;
  sls_depth_frame_init(&frame);
  frame.depth_m = depth.data();
  frame.width = 400;
  frame.height = 300;
  SLS_FAILS(sls_scan_add_depth(scan.get(), &frame, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT,
            "sls_scan_start_feed");
  sls_feed_config config = feed_config(depth_recording());
  SLS_FAILS(sls_scan_start_feed(nullptr, &config, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "scan is NULL");
  SLS_FAILS(sls_scan_start_feed(scan.get(), nullptr, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "config");
  config.calibration_path = nullptr;
  SLS_FAILS(sls_scan_start_feed(scan.get(), &config, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT,
            "calibration_path");
  config.calibration_path = "/nonexistent/calibration.yml";
  sls_error* error = nullptr;
  EXPECT_NE(sls_scan_start_feed(scan.get(), &config, nullptr, &error), SLS_OK);
  EXPECT_NE(std::string(sls_error_message(error)).find("/nonexistent/calibration.yml"), std::string::npos);
  sls_error_free(error);
  config = feed_config(depth_recording());
  config.bit_depth = 17;
  SLS_FAILS(sls_scan_start_feed(scan.get(), &config, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "bit_depth");
  config.bit_depth = 12;
  config.struct_size = 3;
  SLS_FAILS(sls_scan_start_feed(scan.get(), &config, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "struct_size");
  config = feed_config(depth_recording());
  SLS_OK_CALL(sls_scan_start_feed(scan.get(), &config, nullptr, &error_));

  // Depth maps.
  SLS_FAILS(sls_scan_add_depth(nullptr, &frame, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "scan is NULL");
  SLS_FAILS(sls_scan_add_depth(scan.get(), nullptr, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "frame is NULL");
  sls_depth_frame bad = frame;
  bad.depth_m = nullptr;
  SLS_FAILS(sls_scan_add_depth(scan.get(), &bad, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "depth_m is NULL");
  bad = frame;
  bad.width = 401;
  SLS_FAILS(sls_scan_add_depth(scan.get(), &bad, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "400x300");
  bad = frame;
  bad.stride_bytes = 399 * sizeof(float);
  SLS_FAILS(sls_scan_add_depth(scan.get(), &bad, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "stride_bytes");
  bad = frame;
  bad.struct_size = 0;
  SLS_FAILS(sls_scan_add_depth(scan.get(), &bad, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "struct_size");
  bad = frame;
  bad.has_turntable_angle = 1;
  bad.turntable_angle_deg = std::numeric_limits<double>::infinity();
  SLS_FAILS(sls_scan_add_depth(scan.get(), &bad, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "turntable_angle_deg");
  sls_frame_report report;
  sls_frame_report_init(&report);
  report.struct_size = 8;
  SLS_FAILS(sls_scan_add_depth(scan.get(), &frame, &report, &error_), SLS_ERROR_INVALID_ARGUMENT, "struct_size");

  // Pattern stacks.
  std::vector<std::uint16_t> image(400 * 300, 100);
  std::vector<const void*> images(static_cast<std::size_t>(4), image.data());
  sls_stack_frame stack;
  sls_stack_frame_init(&stack);
  stack.images = images.data();
  stack.image_count = images.size();
  stack.width = 400;
  stack.height = 300;
  stack.bytes_per_pixel = 2;
  SLS_FAILS(sls_scan_add_stack(scan.get(), &stack, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "4 images");
  SLS_FAILS(sls_scan_add_stack(scan.get(), nullptr, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "frame is NULL");
  int patterns = 0;
  SLS_OK_CALL(sls_scan_start_feed(scan.get(), &config, &patterns, &error_));
  images.assign(static_cast<std::size_t>(patterns), image.data());
  stack.images = images.data();
  stack.image_count = images.size();
  stack.bytes_per_pixel = 3;
  SLS_FAILS(sls_scan_add_stack(scan.get(), &stack, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "bytes_per_pixel");
  stack.bytes_per_pixel = 2;
  images[1] = nullptr;
  SLS_FAILS(sls_scan_add_stack(scan.get(), &stack, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "images[1]");
  images[1] = image.data();
  stack.images = nullptr;
  SLS_FAILS(sls_scan_add_stack(scan.get(), &stack, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "images is NULL");
  stack.images = images.data();
  stack.height = 299;
  SLS_FAILS(sls_scan_add_stack(scan.get(), &stack, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "400x299");
  stack.height = 300;
  // A flat grey stack is a frame the decoder cannot use: skipped, reported, the scan goes on.
  sls_frame_report_init(&report);
  SLS_OK_CALL(sls_scan_add_stack(scan.get(), &stack, &report, &error_));
  EXPECT_EQ(report.index, 0);  // none of the refused calls took a frame number
  EXPECT_EQ(report.status, SLS_FRAME_SKIPPED);
  EXPECT_STRNE(report.reason, "");

  // A cancelled scan refuses frames.
  SLS_OK_CALL(sls_scan_cancel(scan.get(), &error_));
  SLS_FAILS(sls_scan_add_depth(scan.get(), &frame, nullptr, &error_), SLS_ERROR_CANCELLED, "cancelled");
  SLS_FAILS(sls_scan_start_feed(scan.get(), &config, nullptr, &error_), SLS_ERROR_CANCELLED, "cancelled");
}

// A depth frame fed from another thread, and from the callback, while a run is in progress.
struct Contended {
  sls_scan* scan = nullptr;
  sls_depth_frame frame{};
  sls_status from_thread = SLS_OK, from_callback = SLS_OK, start_from_callback = SLS_OK;
};

void on_frame_contended(const sls_frame_report* report, void* user) {
  Contended& contended = *static_cast<Contended*>(user);
  if (report->index != 1) return;
  std::thread other([&contended] {
    contended.from_thread = sls_scan_add_depth(contended.scan, &contended.frame, nullptr, nullptr);
  });
  other.join();
  contended.from_callback = sls_scan_add_depth(contended.scan, &contended.frame, nullptr, nullptr);
  const sls_feed_config config = feed_config("/unused");
  contended.start_from_callback = sls_scan_start_feed(contended.scan, &config, nullptr, nullptr);
}

TEST_F(CFeed, BusyDuringARun) {
  const ScanPtr scan = make_scan(context_.get(), false);
  std::vector<float> depth(400 * 300, 0.1f);
  Contended contended;
  contended.scan = scan.get();
  sls_depth_frame_init(&contended.frame);
  contended.frame.depth_m = depth.data();
  contended.frame.width = 400;
  contended.frame.height = 300;
  SLS_OK_CALL(sls_scan_set_frame_callback(scan.get(), on_frame_contended, &contended, &error_));
  SLS_OK_CALL(sls_scan_run_recording(scan.get(), depth_recording().c_str(), &error_));
  EXPECT_EQ(contended.from_thread, SLS_ERROR_BUSY);
  EXPECT_EQ(contended.from_callback, SLS_ERROR_BUSY);
  EXPECT_EQ(contended.start_from_callback, SLS_ERROR_BUSY);
  // The run replaced no feed, and started none: frames are refused until a feed starts.
  SLS_FAILS(sls_scan_add_depth(scan.get(), &contended.frame, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT,
            "sls_scan_start_feed");
}

// The log callback's record.
struct Messages {
  std::vector<std::pair<sls_log_level, std::string>> received;
  std::vector<std::thread::id> threads;
  sls_status replace_from_inside = SLS_OK;
};

void on_log(sls_log_level level, const char* message, void* user) {
  Messages& messages = *static_cast<Messages*>(user);
  messages.received.emplace_back(level, message);
  messages.threads.push_back(std::this_thread::get_id());
  messages.replace_from_inside = sls_set_log_callback(nullptr, nullptr, nullptr);
}

TEST_F(CFeed, LogCallbackReceivesTheScansWarnings) {
  Messages messages;
  SLS_OK_CALL(sls_set_log_callback(on_log, &messages, &error_));
  sls_log_level level = SLS_LOG_OFF;
  SLS_OK_CALL(sls_get_log_level(&level, &error_));
  EXPECT_EQ(level, SLS_LOG_WARNING);  // the default
  const ScanPtr scan = make_scan(context_.get(), false);
  const sls_feed_config config = feed_config(depth_recording());
  SLS_OK_CALL(sls_scan_start_feed(scan.get(), &config, nullptr, &error_));
  std::vector<float> nothing(400 * 300, 0.0f);  // no valid depth: skipped, with a warning
  sls_depth_frame frame;
  sls_depth_frame_init(&frame);
  frame.depth_m = nothing.data();
  frame.width = 400;
  frame.height = 300;
  SLS_OK_CALL(sls_scan_add_depth(scan.get(), &frame, nullptr, &error_));
  ASSERT_EQ(messages.received.size(), 1u);
  EXPECT_EQ(messages.received[0].first, SLS_LOG_WARNING);
  EXPECT_NE(messages.received[0].second.find("frame 0 skipped: no valid depth"), std::string::npos)
      << messages.received[0].second;
  EXPECT_EQ(messages.threads[0], std::this_thread::get_id());
  EXPECT_EQ(messages.replace_from_inside, SLS_ERROR_BUSY);  // and the callback stayed

  // Below the level: not delivered. Then back to stderr: the callback is not called again.
  SLS_OK_CALL(sls_set_log_level(SLS_LOG_ERROR, &error_));
  SLS_OK_CALL(sls_scan_add_depth(scan.get(), &frame, nullptr, &error_));
  EXPECT_EQ(messages.received.size(), 1u);
  SLS_OK_CALL(sls_set_log_level(SLS_LOG_WARNING, &error_));
  SLS_OK_CALL(sls_set_log_callback(nullptr, nullptr, &error_));
  SLS_OK_CALL(sls_scan_add_depth(scan.get(), &frame, nullptr, &error_));
  EXPECT_EQ(messages.received.size(), 1u);

  sls_log_level not_a_level;  // what a C caller may pass: any int
  const int value = 42;
  std::memcpy(&not_a_level, &value, sizeof(value));
  SLS_FAILS(sls_set_log_level(not_a_level, &error_), SLS_ERROR_INVALID_ARGUMENT, "42");
  SLS_FAILS(sls_get_log_level(nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "level");
  // A context's log_level is the same process-wide setting.
  sls_context_config context_config;
  sls_context_config_init(&context_config);
  context_config.device = SLS_DEVICE_CPU;
  context_config.log_level = SLS_LOG_DEBUG;
  sls_context* context = nullptr;
  SLS_OK_CALL(sls_context_create(SLS_API_VERSION, &context_config, &context, &error_));
  sls_context_destroy(context);
  SLS_OK_CALL(sls_get_log_level(&level, &error_));
  EXPECT_EQ(level, SLS_LOG_DEBUG);
}

}  // namespace
}  // namespace sls::test
