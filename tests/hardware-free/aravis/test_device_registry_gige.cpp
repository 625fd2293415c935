// The device registry and the C API over real GigE Vision: fake cameras on loopback addresses
// of a private network namespace (run_in_netns.sh) are listed by enumerate_devices() and by
// sls_device_list with their gige:// URIs, and the URI as listed opens a camera whose images
// are exactly what the fake's fill callback wrote. Skips without a private network namespace.
#include <sls/sls.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "drivers/device_registry.h"
#include "sdk/core/error.h"
#include "tests/hardware-free/aravis/fake_gige_camera.h"

namespace sls::drivers {
namespace {

using std::chrono::milliseconds;
using test::FakeGigeCamera;
using test::FakeGigeCameraOptions;

#define SLS_REQUIRE_NETNS()                                                                         \
  do {                                                                                              \
    if (std::getenv("SLS_TEST_NETNS") == nullptr) {                                                 \
      GTEST_SKIP() << "needs a private network namespace: run through run_in_netns.sh (unshare -rn)"; \
    }                                                                                               \
  } while (0)

const milliseconds kFrameTimeout(2000);

// A fill callback that writes a different image for every frame and camera and keeps a copy
// of each, so a test compares what arrived with what was sent.
class RecordingImageSource {
 public:
  explicit RecordingImageSource(std::uint16_t camera_salt) : salt_(camera_salt) {}

  test::FakeImageSource source() {
    return [this](const test::FakeFrameRequest& request, ImageView<std::uint16_t> pixels) {
      const std::uint32_t mask = (1u << request.bit_depth) - 1u;
      Image16u copy(pixels.width, pixels.height);
      for (int y = 0; y < pixels.height; ++y) {
        for (int x = 0; x < pixels.width; ++x) {
          const std::uint32_t value = static_cast<std::uint32_t>(request.frame_id) * 40503u +
                                      static_cast<std::uint32_t>(x) * 3u + static_cast<std::uint32_t>(y) * 977u + salt_;
          pixels(x, y) = static_cast<std::uint16_t>(value & mask);
          copy(x, y) = pixels(x, y);
        }
      }
      std::lock_guard<std::mutex> lock(mutex_);
      sent_[request.frame_id] = std::move(copy);
    };
  }

  // The image sent as `frame_id`; empty when none was.
  Image16u sent(std::uint64_t frame_id) const {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto found = sent_.find(frame_id);
    return found == sent_.end() ? Image16u() : found->second;
  }

 private:
  const std::uint32_t salt_;
  mutable std::mutex mutex_;
  std::map<std::uint64_t, Image16u> sent_;
};

FakeGigeCameraOptions fake_options(const std::string& address, const std::string& serial,
                                   RecordingImageSource& images) {
  FakeGigeCameraOptions options;
  options.address = address;
  options.serial = serial;
  options.image_source = images.source();
  return options;
}

const DeviceDescription* find_uri(const DeviceEnumeration& found, const std::string& uri) {
  const auto it = std::find_if(found.devices.begin(), found.devices.end(),
                               [&](const DeviceDescription& device) { return device.uri == uri; });
  return it == found.devices.end() ? nullptr : &*it;
}

TEST(DeviceRegistryGige, ListedFakeCamerasOpenByTheirUriAndDeliverWhatWasSent) {
  SLS_REQUIRE_NETNS();
  RecordingImageSource left_images(11), right_images(12345);
  FakeGigeCamera left_fake(fake_options("127.0.0.1", "REG-L", left_images));
  FakeGigeCamera right_fake(fake_options("127.0.0.2", "REG-R", right_images));

  const DeviceEnumeration found = enumerate_devices();
  EXPECT_TRUE(found.hardware_found());
  EXPECT_EQ(found.devices.front().kind, DeviceKind::kScanner);  // the simulator is still listed, first
  ASSERT_GE(found.transports.size(), 2u);
  EXPECT_TRUE(found.transports[1].searched) << found.transports[1].problem;

  for (auto [fake, images] : {std::make_pair(&left_fake, &left_images), std::make_pair(&right_fake, &right_images)}) {
    SCOPED_TRACE(fake->uri());
    const DeviceDescription* device = find_uri(found, fake->uri());
    ASSERT_NE(device, nullptr) << "the fake's URI is not listed";
    EXPECT_EQ(device->uri, "gige://" + fake->address());
    EXPECT_EQ(device->kind, DeviceKind::kCamera);
    EXPECT_EQ(device->roles, unsigned{kRoleCamera});
    EXPECT_EQ(device->model, "Aravis Fake");
    EXPECT_EQ(device->serial, fake->serial());
    EXPECT_NE(device->details.find("GigE Vision at " + fake->address()), std::string::npos) << device->details;

    // The URI exactly as listed.
    const std::unique_ptr<Camera> camera = open_camera(device->uri);
    const CameraInfo info = camera->info();
    EXPECT_EQ(info.uri, device->uri);
    EXPECT_EQ(info.serial, fake->serial());
    camera->start();
    for (int i = 0; i < 3; ++i) {
      camera->software_trigger();
      const CapturedImage captured = camera->wait_image(kFrameTimeout);
      ASSERT_TRUE(captured.complete) << captured.problem;
      const Image16u sent = images->sent(captured.frame_id);
      ASSERT_FALSE(sent.empty()) << "frame " << captured.frame_id << " was never sent";
      EXPECT_EQ(sent.width(), info.width);
      EXPECT_TRUE(captured.image == sent) << "frame " << captured.frame_id << " is not what the fake sent";
    }
    EXPECT_EQ(fake->source_error(), "");
  }
  // The registry's other factories refuse a camera URI without touching the network.
  EXPECT_THROW(open_projector(left_fake.uri()), Error);
}

TEST(DeviceRegistryGige, AVanishedCameraIsNotFound) {
  SLS_REQUIRE_NETNS();
  std::string uri;
  {
    RecordingImageSource images(1);
    FakeGigeCamera fake(fake_options("127.0.0.2", "REG-GONE", images));
    uri = fake.uri();
    ASSERT_NE(find_uri(enumerate_devices(), uri), nullptr);
  }
  EXPECT_EQ(find_uri(enumerate_devices(), uri), nullptr);
  try {
    open_camera(uri);
    ADD_FAILURE() << "opened a camera that is gone";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kNotFound) << error.what();
    EXPECT_NE(std::string(error.what()).find("127.0.0.2"), std::string::npos) << error.what();
  }
}

// The same through the C API: sls_device_list shows the fake, sls_camera_open takes the listed
// URI, and sls_camera_grab fills the caller's buffer with the pixels that were sent.
TEST(DeviceRegistryGige, CApiListsOpensAndGrabsTheFake) {
  SLS_REQUIRE_NETNS();
  RecordingImageSource images(77);
  FakeGigeCamera fake(fake_options("127.0.0.1", "REG-C", images));

  sls_context* context = nullptr;
  ASSERT_EQ(sls_context_create(SLS_API_VERSION, nullptr, &context, nullptr), SLS_OK);
  sls_device_list* list = nullptr;
  ASSERT_EQ(sls_device_list_create(context, &list, nullptr), SLS_OK);
  std::size_t count = 0;
  ASSERT_EQ(sls_device_list_count(list, &count, nullptr), SLS_OK);
  std::string listed_uri;
  for (std::size_t i = 0; i < count; ++i) {
    sls_device_info info;
    sls_device_info_init(&info);
    ASSERT_EQ(sls_device_list_get_info(list, i, &info, nullptr), SLS_OK);
    if (std::string(info.uri) == fake.uri()) {
      listed_uri = info.uri;
      EXPECT_EQ(info.kind, SLS_DEVICE_KIND_CAMERA);
      EXPECT_EQ(info.roles, static_cast<unsigned>(SLS_DEVICE_ROLE_CAMERA));
      EXPECT_STREQ(info.serial, "REG-C");
    }
  }
  int has_hardware = 0;
  EXPECT_EQ(sls_device_list_has_hardware(list, &has_hardware, nullptr), SLS_OK);
  EXPECT_EQ(has_hardware, 1);
  sls_device_list_destroy(list);
  ASSERT_EQ(listed_uri, fake.uri()) << "sls_device_list does not list the fake";

  sls_camera* camera = nullptr;
  sls_error* error = nullptr;
  ASSERT_EQ(sls_camera_open(context, listed_uri.c_str(), &camera, &error), SLS_OK) << sls_error_message(error);
  sls_camera_info info;
  sls_camera_info_init(&info);
  ASSERT_EQ(sls_camera_get_info(camera, &info, nullptr), SLS_OK);
  EXPECT_EQ(info.bit_depth, 16);  // the driver's default format, Mono16
  std::vector<std::uint16_t> pixels(static_cast<std::size_t>(info.width) * static_cast<std::size_t>(info.height));
  for (int i = 0; i < 3; ++i) {
    sls_frame_info frame;
    sls_frame_info_init(&frame);
    ASSERT_EQ(sls_camera_grab(camera, 2000, pixels.data(), pixels.size(), &frame, &error), SLS_OK)
        << sls_error_message(error);
    const Image16u sent = images.sent(frame.frame_id);
    ASSERT_EQ(sent.width(), info.width);
    ASSERT_EQ(sent.height(), info.height);
    std::size_t differing = 0;
    for (int y = 0; y < info.height; ++y) {
      for (int x = 0; x < info.width; ++x) {
        differing += pixels[static_cast<std::size_t>(y) * static_cast<std::size_t>(info.width) +
                            static_cast<std::size_t>(x)] != sent(x, y);
      }
    }
    EXPECT_EQ(differing, 0u) << "frame " << frame.frame_id;
  }
  sls_camera_close(camera);
  sls_context_destroy(context);
}

// With packets lost (and never resent) a grab either returns exactly the image that was sent
// or fails with SLS_ERROR_DEVICE / SLS_ERROR_TIMEOUT: never a silently wrong image.
TEST(DeviceRegistryGige, CApiGrabNeverHandsOutAnIncompleteFrame) {
  SLS_REQUIRE_NETNS();
  RecordingImageSource images(5);
  FakeGigeCameraOptions options = fake_options("127.0.0.1", "REG-LOSSY", images);
  options.packet_loss_ratio = 0.002;
  FakeGigeCamera fake(options);
  sls_context* context = nullptr;
  ASSERT_EQ(sls_context_create(SLS_API_VERSION, nullptr, &context, nullptr), SLS_OK);
  sls_camera* camera = nullptr;
  // About 100 packets per frame: roughly one frame in five loses one.
  const std::string uri = fake.uri() + "?width=256&height=256&packet_size=1400";
  ASSERT_EQ(sls_camera_open(context, uri.c_str(), &camera, nullptr), SLS_OK);
  std::vector<std::uint16_t> pixels(256 * 256);
  int whole = 0, incomplete = 0;
  for (int i = 0; i < 50; ++i) {
    std::fill(pixels.begin(), pixels.end(), std::uint16_t{0xBEEF});
    sls_frame_info frame;
    sls_frame_info_init(&frame);
    sls_error* error = nullptr;
    const sls_status status = sls_camera_grab(camera, 2000, pixels.data(), pixels.size(), &frame, &error);
    if (status == SLS_OK) {
      ++whole;
      const Image16u sent = images.sent(frame.frame_id);
      ASSERT_EQ(sent.width(), 256);
      bool equal = true;
      for (int y = 0; y < 256 && equal; ++y) {
        for (int x = 0; x < 256 && equal; ++x) equal = pixels[static_cast<std::size_t>(y * 256 + x)] == sent(x, y);
      }
      EXPECT_TRUE(equal) << "frame " << frame.frame_id << " was returned but is not what was sent";
    } else {
      ASSERT_TRUE(status == SLS_ERROR_DEVICE || status == SLS_ERROR_TIMEOUT) << sls_error_message(error);
      if (status == SLS_ERROR_DEVICE) {
        ++incomplete;
        EXPECT_NE(std::string(sls_error_message(error)).find("incomplete"), std::string::npos)
            << sls_error_message(error);
      }
      EXPECT_TRUE(std::all_of(pixels.begin(), pixels.end(), [](std::uint16_t v) { return v == 0xBEEF; }))
          << "a failed grab wrote into the buffer";
    }
    sls_error_free(error);
  }
  EXPECT_GT(whole, 20);
  EXPECT_GT(incomplete, 0) << "no loss seen: the test exercised nothing";
  sls_camera_close(camera);
  sls_context_destroy(context);
}

}  // namespace
}  // namespace sls::drivers
