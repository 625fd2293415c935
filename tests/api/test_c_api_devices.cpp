// sls_camera against the driver it wraps: the pixels a C caller gets are exactly the image the
// C++ simulated camera renders for the same URI, row by row, and the frame metadata matches.
#include <sls/sls.h>

#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "drivers/device_registry.h"

namespace {

struct ContextDeleter {
  void operator()(sls_context* context) const { sls_context_destroy(context); }
};
struct CameraDeleter {
  void operator()(sls_camera* camera) const { sls_camera_close(camera); }
};

std::unique_ptr<sls_context, ContextDeleter> cpu_context() {
  sls_context_config config;
  sls_context_config_init(&config);
  config.device = SLS_DEVICE_CPU;
  sls_context* context = nullptr;
  EXPECT_EQ(sls_context_create(SLS_API_VERSION, &config, &context, nullptr), SLS_OK);
  return std::unique_ptr<sls_context, ContextDeleter>(context);
}

TEST(CApiCamera, GrabsExactlyWhatTheDriverRenders) {
  // Noise on: the renders of two fresh scanners agree only if the C API hands out the very
  // image of the first trigger, untouched.
  const std::string uri = "sim://knurled-knob?preset=ci&seed=7";
  auto context = cpu_context();
  sls_camera* raw = nullptr;
  ASSERT_EQ(sls_camera_open(context.get(), uri.c_str(), &raw, nullptr), SLS_OK);
  std::unique_ptr<sls_camera, CameraDeleter> camera(raw);
  sls_camera_info info;
  sls_camera_info_init(&info);
  ASSERT_EQ(sls_camera_get_info(camera.get(), &info, nullptr), SLS_OK);
  EXPECT_EQ(std::string(info.uri).rfind("sim://knurled-knob?preset=ci", 0), 0u) << info.uri;
  EXPECT_STREQ(info.serial, "SIM-CAM-0");

  std::vector<std::uint16_t> pixels(static_cast<std::size_t>(info.width) * static_cast<std::size_t>(info.height));
  sls_frame_info frame;
  sls_frame_info_init(&frame);
  ASSERT_EQ(sls_camera_grab(camera.get(), 1000, pixels.data(), pixels.size(), &frame, nullptr), SLS_OK);

  sls::drivers::OpenOptions on_cpu;
  on_cpu.sim_device = sls::Device::cpu();
  auto direct = sls::drivers::open_camera(uri, on_cpu);
  direct->start();
  direct->software_trigger();
  const sls::drivers::CapturedImage expected = direct->wait_image(std::chrono::milliseconds(1000));
  ASSERT_EQ(expected.image.width(), info.width);
  ASSERT_EQ(expected.image.height(), info.height);
  EXPECT_EQ(frame.width, info.width);
  EXPECT_EQ(frame.bit_depth, direct->info().bit_depth);
  EXPECT_EQ(frame.frame_id, expected.frame_id);
  EXPECT_EQ(frame.timestamp_ns, expected.timestamp_ns);
  std::size_t differing = 0;
  for (int y = 0; y < info.height; ++y) {
    for (int x = 0; x < info.width; ++x) {
      differing += pixels[static_cast<std::size_t>(y) * static_cast<std::size_t>(info.width) +
                          static_cast<std::size_t>(x)] != expected.image(x, y);
    }
  }
  EXPECT_EQ(differing, 0u);
}

// A context's device choice reaches the simulated camera: with SLS_DEVICE_AUTO on a machine
// with a GPU the image is rendered by CUDA, and it must still be a proper image.
TEST(CApiCamera, RendersOnTheContextsDevice) {
  sls_context* raw_context = nullptr;
  ASSERT_EQ(sls_context_create(SLS_API_VERSION, nullptr, &raw_context, nullptr), SLS_OK);
  std::unique_ptr<sls_context, ContextDeleter> context(raw_context);
  sls_camera* raw = nullptr;
  sls_error* error = nullptr;
  ASSERT_EQ(sls_camera_open(context.get(), "sim://sphere?preset=ci", &raw, &error), SLS_OK)
      << sls_error_message(error);
  std::unique_ptr<sls_camera, CameraDeleter> camera(raw);
  sls_camera_info info;
  sls_camera_info_init(&info);
  ASSERT_EQ(sls_camera_get_info(camera.get(), &info, nullptr), SLS_OK);
  std::vector<std::uint16_t> pixels(static_cast<std::size_t>(info.width) * static_cast<std::size_t>(info.height),
                                    std::uint16_t{0xFFFF});
  ASSERT_EQ(sls_camera_grab(camera.get(), 1000, pixels.data(), pixels.size(), nullptr, &error), SLS_OK)
      << sls_error_message(error);
  const std::uint16_t max_value = static_cast<std::uint16_t>((1u << info.bit_depth) - 1u);
  std::size_t above = 0, nonzero = 0;
  for (const std::uint16_t value : pixels) {
    above += value > max_value;
    nonzero += value != 0;
  }
  EXPECT_EQ(above, 0u);
  EXPECT_GT(nonzero, pixels.size() / 2);
}

TEST(CApiCamera, ErrorsNameTheUri) {
  auto context = cpu_context();
  sls_camera* camera = nullptr;
  sls_error* error = nullptr;
  EXPECT_EQ(sls_camera_open(context.get(), "headctl://1:3", &camera, &error), SLS_ERROR_INVALID_ARGUMENT);
  ASSERT_NE(error, nullptr);
  EXPECT_STREQ(sls_error_function(error), "sls_camera_open");
  EXPECT_NE(std::string(sls_error_message(error)).find("headctl://1:3"), std::string::npos)
      << sls_error_message(error);
  sls_error_free(error);
  EXPECT_EQ(camera, nullptr);
}

TEST(CApiDeviceList, MatchesTheRegistry) {
  auto context = cpu_context();
  sls_device_list* list = nullptr;
  ASSERT_EQ(sls_device_list_create(context.get(), &list, nullptr), SLS_OK);
  const sls::drivers::DeviceEnumeration found = sls::drivers::enumerate_devices();
  std::size_t count = 0;
  ASSERT_EQ(sls_device_list_count(list, &count, nullptr), SLS_OK);
  ASSERT_EQ(count, found.devices.size());
  for (std::size_t i = 0; i < count; ++i) {
    sls_device_info info;
    sls_device_info_init(&info);
    ASSERT_EQ(sls_device_list_get_info(list, i, &info, nullptr), SLS_OK);
    EXPECT_EQ(info.uri, found.devices[i].uri);
    EXPECT_EQ(info.model, found.devices[i].model);
    EXPECT_EQ(info.serial, found.devices[i].serial);
    EXPECT_EQ(info.details, found.devices[i].details);
    EXPECT_EQ(info.roles, found.devices[i].roles);
    EXPECT_EQ(static_cast<int>(info.kind), static_cast<int>(found.devices[i].kind));
  }
  const char* problems = nullptr;
  ASSERT_EQ(sls_device_list_problems(list, &problems, nullptr), SLS_OK);
  std::string expected_problems;
  for (const auto& transport : found.transports) {
    if (!transport.searched) expected_problems += transport.name + ": " + transport.problem + "\n";
  }
  EXPECT_EQ(problems, expected_problems);
  sls_device_list_destroy(list);
}

}  // namespace
