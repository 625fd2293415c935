// The Aravis camera driver against fake GigE Vision cameras over real UDP (GVCP + GVSP) on
// loopback. Runs inside a private network namespace (run_in_netns.sh); skips without one.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <optional>
#include <ostream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "drivers/aravis/aravis_camera.h"
#include "drivers/interfaces/device_uri.h"
#include "sdk/core/device.h"
#include "sdk/core/error.h"
#include "tests/hardware-free/aravis/fake_gige_camera.h"
#include "tests/support/test_support.h"

namespace sls::drivers {
namespace {

using std::chrono::milliseconds;
using Clock = std::chrono::steady_clock;
using test::FakeGigeCamera;
using test::FakeGigeCameraOptions;

#define SLS_REQUIRE_NETNS()                                                                         \
  do {                                                                                              \
    if (std::getenv("SLS_TEST_NETNS") == nullptr) {                                                 \
      GTEST_SKIP() << "needs a private network namespace: run through run_in_netns.sh (unshare -rn)"; \
    }                                                                                               \
  } while (0)

const milliseconds kFrameTimeout(2000);

std::string sfnc_xml() { return std::string(SLS_ARAVIS_TEST_DIR) + "/fake-sfnc.xml"; }

FakeGigeCameraOptions fake_options(const std::string& address = "127.0.0.1", const std::string& serial = "SLS-FAKE-01",
                                   const std::string& xml = "") {
  FakeGigeCameraOptions options;
  options.address = address;
  options.serial = serial;
  options.genicam_xml = xml;
  return options;
}

AravisCameraOptions camera_options(const std::string& format, int width, int height) {
  AravisCameraOptions options;
  options.pixel_format = format;
  options.width = width;
  options.height = height;
  return options;
}

CapturedImage grab(AravisCamera& camera) {
  camera.software_trigger();
  return camera.wait_image(kFrameTimeout);
}

// Runs `call`, expects sls::Error with one of `codes`, returns its message.
template <typename Call>
std::string expect_error(Call&& call, std::initializer_list<ErrorCode> codes) {
  try {
    call();
  } catch (const Error& error) {
    EXPECT_NE(std::find(codes.begin(), codes.end(), error.code()), codes.end())
        << "code " << error_code_name(error.code()) << ": " << error.what();
    return error.what();
  }
  ADD_FAILURE() << "no sls::Error thrown";
  return {};
}

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

void replace_all(std::string& text, const std::string& from, const std::string& to) {
  for (std::size_t at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size())) {
    text.replace(at, from.size(), to);
  }
}

TEST(AravisCamera, OpensByAddressAndReportsItself) {
  SLS_REQUIRE_NETNS();
  FakeGigeCamera fake(fake_options());
  auto camera = AravisCamera::open(fake.address(), camera_options("Mono8", 64, 48));
  const CameraInfo info = camera->info();
  EXPECT_EQ(info.uri, "gige://127.0.0.1");
  EXPECT_EQ(info.model, "Aravis Fake");
  EXPECT_EQ(info.serial, "SLS-FAKE-01");
  EXPECT_EQ(info.width, 64);
  EXPECT_EQ(info.height, 48);
  EXPECT_EQ(info.bit_depth, 8);
  EXPECT_EQ(camera->device().protocol, "GigEVision");
  EXPECT_EQ(camera->device().address, "127.0.0.1");
  EXPECT_EQ(camera->feature_value("PixelFormat"), "Mono8");
  EXPECT_EQ(camera->feature_value("Width"), "64");
}

TEST(AravisCamera, NobodyAtTheAddressIsNotFound) {
  SLS_REQUIRE_NETNS();
  const auto before = Clock::now();
  const std::string message = expect_error(
      [&] { AravisCamera::open("127.0.0.2", camera_options("Mono8", 0, 0)); }, {ErrorCode::kNotFound});
  EXPECT_NE(message.find("127.0.0.2"), std::string::npos) << message;
  EXPECT_LT(Clock::now() - before, std::chrono::seconds(10));
}

struct FormatCase {
  const char* format;
  bool sfnc_xml;  // Mono12 exists only in tests/hardware-free/aravis/fake-sfnc.xml
  int bit_depth;
};

void PrintTo(const FormatCase& format, std::ostream* out) { *out << format.format; }

class AravisPixels : public ::testing::TestWithParam<FormatCase> {};

TEST_P(AravisPixels, EqualWhatTheFakeCameraWrote) {
  SLS_REQUIRE_NETNS();
  const FormatCase& param = GetParam();
  FakeGigeCamera fake(fake_options("127.0.0.1", "SLS-PIX", param.sfnc_xml ? sfnc_xml() : ""));
  auto camera = AravisCamera::open(fake.address(), camera_options(param.format, 320, 240));
  EXPECT_EQ(camera->info().bit_depth, param.bit_depth);
  camera->start();
  std::uint64_t previous_id = 0;
  std::int64_t previous_timestamp = 0;
  for (int i = 0; i < 6; ++i) {
    // The last frames for a scan fused on a GPU: page-locked where a GPU is, the same pixels.
    if (i == 3) camera->set_image_memory(MemoryType::kPinned);
    const CapturedImage captured = grab(*camera);
    ASSERT_TRUE(captured.complete) << captured.problem;
    EXPECT_EQ(captured.image.memory_type(),
              i >= 3 && cuda_compiled() && cuda_device_count() > 0 ? MemoryType::kPinned : MemoryType::kHost);
    EXPECT_TRUE(captured.problem.empty());
    ASSERT_EQ(captured.image.width(), 320);
    ASSERT_EQ(captured.image.height(), 240);
    // Bit-exact: what the fill callback wrote for this frame id is what arrived.
    EXPECT_TRUE(captured.image == test::fake_test_pattern(captured.frame_id, 320, 240, param.bit_depth))
        << "frame " << captured.frame_id;
    if (i > 0) {
      EXPECT_EQ(captured.frames_missed, 0u);
      EXPECT_GT(captured.timestamp_ns, previous_timestamp);
      EXPECT_NE(captured.frame_id, previous_id);
    }
    previous_id = captured.frame_id;
    previous_timestamp = captured.timestamp_ns;
  }
  camera->stop();
  EXPECT_EQ(fake.source_error(), "");
  EXPECT_EQ(camera->statistics().images, 6u);
  EXPECT_EQ(camera->statistics().incomplete_images, 0u);
}

INSTANTIATE_TEST_SUITE_P(Formats, AravisPixels,
                         ::testing::Values(FormatCase{"Mono8", false, 8}, FormatCase{"Mono16", false, 16},
                                           FormatCase{"Mono12", true, 12}),
                         [](const ::testing::TestParamInfo<FormatCase>& format) { return std::string(format.param.format); });

TEST(AravisCamera, RefusesPixelFormatsItCannotRead) {
  SLS_REQUIRE_NETNS();
  FakeGigeCamera fake(fake_options());
  // The built-in description has no Mono12: the camera's list is named.
  const std::string message =
      expect_error([&] { AravisCamera::open(fake.address(), camera_options("Mono12", 0, 0)); }, {ErrorCode::kUnsupported});
  EXPECT_NE(message.find("Mono16"), std::string::npos) << message;
  expect_error([&] { AravisCamera::open(fake.address(), camera_options("Mono12Packed", 0, 0)); },
               {ErrorCode::kUnsupported});
  expect_error([&] { AravisCamera::open(fake.address(), camera_options("Mono8", 5000, 10)); },
               {ErrorCode::kInvalidArgument});
}

TEST(AravisCamera, ExposureAndGainReachTheSensor) {
  SLS_REQUIRE_NETNS();
  FakeGigeCameraOptions options = fake_options();
  // The fake hands its exposure and gain registers to the image source: show them as pixels.
  options.image_source = [](const test::FakeFrameRequest& request, ImageView<std::uint16_t> pixels) {
    for (int y = 0; y < pixels.height; ++y) {
      for (int x = 0; x < pixels.width; ++x) {
        pixels(x, y) = static_cast<std::uint16_t>(y == 0 ? request.exposure_us : request.gain_raw);
      }
    }
  };
  FakeGigeCamera fake(options);
  auto camera = AravisCamera::open(fake.address(), camera_options("Mono16", 16, 2));
  camera->set_exposure_us(2500.0);
  camera->set_gain(7.0);
  camera->start();
  const CapturedImage captured = grab(*camera);
  ASSERT_TRUE(captured.complete) << captured.problem;
  EXPECT_EQ(captured.image(3, 0), 2500);
  EXPECT_EQ(captured.image(3, 1), 7);
}

TEST(AravisCamera, FeatureFallbacksOnTheBuiltInDescription) {
  SLS_REQUIRE_NETNS();
  FakeGigeCamera fake(fake_options());
  auto camera = AravisCamera::open(fake.address(), camera_options("Mono8", 32, 32));
  // Aravis's fake has no SFNC ExposureTime or float Gain: the fallbacks are used.
  EXPECT_EQ(camera->exposure_feature(), "ExposureTimeAbs");
  EXPECT_EQ(camera->gain_feature(), "GainRaw");
  camera->set_exposure_us(1234.0);
  EXPECT_DOUBLE_EQ(camera->exposure_us(), 1234.0);
  camera->set_gain(3.4);  // GainRaw is an integer: rounded
  EXPECT_DOUBLE_EQ(camera->gain(), 3.0);
  const std::string message = expect_error([&] { camera->set_gain(50.0); }, {ErrorCode::kInvalidArgument});
  EXPECT_NE(message.find("GainRaw"), std::string::npos) << message;
  expect_error([&] { camera->set_exposure_us(1.0); }, {ErrorCode::kInvalidArgument});
}

TEST(AravisCamera, FeatureFallbacksPreferSfncNames) {
  SLS_REQUIRE_NETNS();
  FakeGigeCamera fake(fake_options("127.0.0.1", "SLS-SFNC", sfnc_xml()));
  auto camera = AravisCamera::open(fake.address(), camera_options("Mono8", 32, 32));
  EXPECT_EQ(camera->exposure_feature(), "ExposureTime");
  EXPECT_EQ(camera->gain_feature(), "Gain");
  camera->set_exposure_us(4321.0);
  EXPECT_DOUBLE_EQ(camera->exposure_us(), 4321.0);
  // Same register underneath: the SFNC write shows through the old name.
  EXPECT_EQ(camera->feature_value("ExposureTimeAbs"), camera->feature_value("ExposureTime"));
  camera->set_gain(4.0);
  EXPECT_DOUBLE_EQ(camera->gain(), 4.0);
  EXPECT_EQ(camera->feature_value("GainRaw"), "4");
}

TEST(AravisCamera, MissingFeaturesAreNamed) {
  SLS_REQUIRE_NETNS();
  // A description with neither exposure nor gain feature under any name the driver knows.
  std::string xml = read_text(sfnc_xml());
  ASSERT_FALSE(xml.empty());
  replace_all(xml, "ExposureTimeAbs", "VendorShutterAbs");
  replace_all(xml, "\"ExposureTime\"", "\"VendorShutter\"");
  replace_all(xml, ">ExposureTime<", ">VendorShutter<");
  replace_all(xml, "GainRaw", "VendorAmplifierRaw");
  replace_all(xml, "\"Gain\"", "\"VendorAmplifier\"");
  replace_all(xml, ">Gain<", ">VendorAmplifier<");
  test::TemporaryDirectory folder;
  std::ofstream(folder.file("vendor.xml")) << xml;

  FakeGigeCamera fake(fake_options("127.0.0.1", "SLS-VENDOR", folder.file("vendor.xml")));
  auto camera = AravisCamera::open(fake.address(), camera_options("Mono8", 32, 32));
  EXPECT_EQ(camera->exposure_feature(), "");
  EXPECT_EQ(camera->gain_feature(), "");
  const std::string exposure = expect_error([&] { camera->set_exposure_us(1000.0); }, {ErrorCode::kUnsupported});
  EXPECT_NE(exposure.find("ExposureTime nor ExposureTimeAbs"), std::string::npos) << exposure;
  EXPECT_NE(exposure.find("SLS-VENDOR"), std::string::npos) << exposure;
  const std::string gain = expect_error([&] { camera->gain(); }, {ErrorCode::kUnsupported});
  EXPECT_NE(gain.find("Gain nor GainRaw"), std::string::npos) << gain;
  // The camera still captures.
  camera->start();
  EXPECT_TRUE(grab(*camera).complete);
}

TEST(AravisCamera, SoftwareTriggerRoundTrip) {
  SLS_REQUIRE_NETNS();
  FakeGigeCamera fake(fake_options());
  auto camera = AravisCamera::open(fake.address(), camera_options("Mono16", 128, 64));
  EXPECT_EQ(camera->feature_value("TriggerMode"), "On");
  EXPECT_EQ(camera->feature_value("TriggerSource"), "Software");
  expect_error([&] { camera->software_trigger(); }, {ErrorCode::kInvalidArgument});  // before start()
  camera->start();
  // No trigger, no frame.
  const auto before = Clock::now();
  const std::string message = expect_error([&] { camera->wait_image(milliseconds(200)); }, {ErrorCode::kTimeout});
  EXPECT_GE(Clock::now() - before, milliseconds(200));
  EXPECT_NE(message.find("gige://127.0.0.1"), std::string::npos) << message;
  // One trigger, one frame, in order.
  std::vector<std::uint64_t> ids;
  for (int i = 0; i < 20; ++i) {
    const CapturedImage captured = grab(*camera);
    ASSERT_TRUE(captured.complete) << captured.problem;
    ids.push_back(captured.frame_id);
  }
  for (std::size_t i = 1; i < ids.size(); ++i) EXPECT_EQ(ids[i], ids[i - 1] + 1) << i;
  expect_error([&] { camera->wait_image(milliseconds(100)); }, {ErrorCode::kTimeout});
  camera->stop();
  expect_error([&] { camera->wait_image(milliseconds(10)); }, {ErrorCode::kInvalidArgument});  // after stop()
  // A second acquisition works the same.
  camera->start();
  EXPECT_TRUE(grab(*camera).complete);
}

TEST(AravisCamera, HardwareLineTrigger) {
  SLS_REQUIRE_NETNS();
  FakeGigeCamera fake(fake_options());
  auto camera = AravisCamera::open(fake.address(), camera_options("Mono8", 32, 32));
  camera->set_trigger_source(TriggerSource::kHardwareLine);
  EXPECT_EQ(camera->feature_value("TriggerMode"), "On");
  EXPECT_EQ(camera->feature_value("TriggerSource"), "Line0");
  camera->start();
  expect_error([&] { camera->software_trigger(); }, {ErrorCode::kInvalidArgument});
  // Nothing drives the fake's line: no frame arrives.
  expect_error([&] { camera->wait_image(milliseconds(200)); }, {ErrorCode::kTimeout});
  const std::string message = expect_error([&] { camera->set_trigger_line("Line7"); }, {ErrorCode::kUnsupported});
  EXPECT_NE(message.find("Line0, Software"), std::string::npos) << message;
  EXPECT_EQ(camera->feature_value("TriggerSource"), "Line0");
  camera->set_trigger_source(TriggerSource::kSoftware);
  EXPECT_EQ(camera->feature_value("TriggerSource"), "Software");
  EXPECT_TRUE(grab(*camera).complete);
}

TEST(AravisCamera, TwoCamerasOnTwoAddresses) {
  SLS_REQUIRE_NETNS();
  const auto constant = [](std::uint16_t value) {
    return [value](const test::FakeFrameRequest&, ImageView<std::uint16_t> pixels) {
      for (int y = 0; y < pixels.height; ++y) {
        for (int x = 0; x < pixels.width; ++x) pixels(x, y) = value;
      }
    };
  };
  FakeGigeCameraOptions left_options = fake_options("127.0.0.1", "CAM-L");
  left_options.image_source = constant(1111);
  FakeGigeCameraOptions right_options = fake_options("127.0.0.2", "CAM-R");
  right_options.image_source = constant(2222);
  FakeGigeCamera left_fake(left_options);
  FakeGigeCamera right_fake(right_options);
  auto left = AravisCamera::open("127.0.0.1", camera_options("Mono16", 64, 64));
  auto right = AravisCamera::open("127.0.0.2", camera_options("Mono16", 64, 64));
  EXPECT_EQ(left->info().serial, "CAM-L");
  EXPECT_EQ(right->info().serial, "CAM-R");
  left->start();
  right->start();
  for (int i = 0; i < 4; ++i) {
    left->software_trigger();
    right->software_trigger();
    const CapturedImage left_image = left->wait_image(kFrameTimeout);
    const CapturedImage right_image = right->wait_image(kFrameTimeout);
    ASSERT_TRUE(left_image.complete && right_image.complete);
    EXPECT_TRUE(left_image.image == Image16u(64, 64, 1111));
    EXPECT_TRUE(right_image.image == Image16u(64, 64, 2222));
  }
}

TEST(AravisCamera, DiscoveryListsTheFakesAndOpensByIdOrSerial) {
  SLS_REQUIRE_NETNS();
  FakeGigeCamera left_fake(fake_options("127.0.0.1", "CAM-L"));
  FakeGigeCamera right_fake(fake_options("127.0.0.2", "CAM-R"));
  const std::vector<DiscoveredCamera> cameras = discover_aravis_cameras();
  for (const FakeGigeCamera* fake : {&left_fake, &right_fake}) {
    const auto found = std::find_if(cameras.begin(), cameras.end(),
                                    [&](const DiscoveredCamera& camera) { return camera.id == fake->device_id(); });
    ASSERT_NE(found, cameras.end()) << fake->device_id() << " not discovered";
    EXPECT_EQ(found->address, fake->address());
    EXPECT_EQ(found->serial, fake->serial());
    EXPECT_EQ(found->vendor, "Aravis");
    EXPECT_EQ(found->model, "Fake");
    EXPECT_EQ(found->protocol, "GigEVision");
    EXPECT_EQ(found->uri(), fake->uri());
  }
  // By id and by serial: found through discovery, then opened by address, so frames arrive.
  auto by_id = AravisCamera::open(right_fake.device_id(), camera_options("Mono8", 32, 32));
  EXPECT_EQ(by_id->info().uri, "gige://127.0.0.2");
  by_id->start();
  EXPECT_TRUE(grab(*by_id).complete);
  by_id.reset();
  auto by_serial = AravisCamera::open("CAM-L", camera_options("Mono8", 32, 32));
  EXPECT_EQ(by_serial->info().uri, "gige://127.0.0.1");
  const std::string message = expect_error(
      [&] { AravisCamera::open("Nobody-0000", camera_options("Mono8", 32, 32)); }, {ErrorCode::kNotFound});
  EXPECT_NE(message.find("Aravis-Fake-CAM-R"), std::string::npos) << message;
}

TEST(AravisCamera, OpensByUriWithOptions) {
  SLS_REQUIRE_NETNS();
  FakeGigeCamera fake(fake_options());
  auto camera = AravisCamera::open(parse_device_uri("gige://127.0.0.1?format=Mono8&width=40&height=20&packet_size=1400&buffers=3"));
  EXPECT_EQ(camera->info().width, 40);
  EXPECT_EQ(camera->info().height, 20);
  EXPECT_EQ(camera->info().bit_depth, 8);
  EXPECT_EQ(camera->packet_size(), 1400);
  camera->start();
  EXPECT_TRUE(grab(*camera).complete);
  camera.reset();
  expect_error([&] { AravisCamera::open(parse_device_uri("gige://127.0.0.1?fps=30")); }, {ErrorCode::kInvalidArgument});
  expect_error([&] { AravisCamera::open(parse_device_uri("usb3://127.0.0.1")); }, {ErrorCode::kInvalidArgument});
  // The fake allows 220..16404 bytes: a larger explicit size is refused, not silently kept.
  expect_error([&] { AravisCamera::open(parse_device_uri("gige://127.0.0.1?packet_size=20000")); },
               {ErrorCode::kInvalidArgument});
}

TEST(AravisCamera, NegotiatesTheLargestPacketOnLoopback) {
  SLS_REQUIRE_NETNS();
  FakeGigeCamera fake(fake_options());
  auto camera = AravisCamera::open(fake.address(), camera_options("Mono16", 512, 512));
  // No test packets on the fake: the camera's maximum, as loopback's MTU (65536) allows it.
  EXPECT_EQ(camera->packet_size(), 16404);
  EXPECT_EQ(camera->feature_value("GevSCPSPacketSize"), "16404");
  camera->start();
  const CapturedImage captured = grab(*camera);
  ASSERT_TRUE(captured.complete) << captured.problem;
  EXPECT_TRUE(captured.image == test::fake_test_pattern(captured.frame_id, 512, 512, 16));
}

TEST(AravisCamera, FrameIdGapsAreCountedWhenThePoolRunsDry) {
  SLS_REQUIRE_NETNS();
  FakeGigeCamera fake(fake_options());
  AravisCameraOptions options = camera_options("Mono8", 32, 32);
  options.buffer_count = 2;
  auto camera = AravisCamera::open(fake.address(), options);
  camera->start();
  // Five frames while nobody takes them: two fill the pool, three are dropped on arrival.
  for (int i = 0; i < 5; ++i) {
    const std::uint64_t sent = fake.frames_sent();
    camera->software_trigger();
    const auto deadline = Clock::now() + kFrameTimeout;
    while (fake.frames_sent() == sent && Clock::now() < deadline) std::this_thread::sleep_for(milliseconds(1));
    std::this_thread::sleep_for(milliseconds(30));  // let it cross loopback
  }
  std::this_thread::sleep_for(milliseconds(200));  // the last ones too, before a buffer frees up
  ASSERT_TRUE(camera->transport_statistics().has_value()) << "a GigE Vision camera reports its stream";
  EXPECT_EQ(camera->transport_statistics()->output_queue_depth, 0u) << "no image taken yet";
  const CapturedImage first = camera->wait_image(kFrameTimeout);
  // The reader fell behind: the second image was already waiting when it took the first.
  EXPECT_EQ(camera->transport_statistics()->output_queue_depth, 1u);
  const CapturedImage second = camera->wait_image(kFrameTimeout);
  EXPECT_EQ(camera->transport_statistics()->output_queue_depth, 0u);
  EXPECT_EQ(second.frame_id, first.frame_id + 1);
  EXPECT_EQ(second.frames_missed, 0u);
  const CapturedImage next = grab(*camera);
  ASSERT_TRUE(next.complete) << next.problem;
  EXPECT_EQ(next.frame_id, first.frame_id + 5);
  EXPECT_EQ(next.frames_missed, 3u);
  EXPECT_EQ(camera->statistics().frames_missed, 3u);
}

TEST(AravisCamera, PacketLossNeverYieldsAWrongFrame) {
  SLS_REQUIRE_NETNS();
  FakeGigeCameraOptions options = fake_options();
  options.packet_loss_ratio = 0.002;  // the fake cannot resend: a lost packet stays lost
  FakeGigeCamera fake(options);
  AravisCameraOptions camera_settings = camera_options("Mono16", 256, 256);
  camera_settings.packet_size = 1400;  // about 100 packets per frame: ~18 % of frames lose one
  auto camera = AravisCamera::open(fake.address(), camera_settings);
  camera->start();
  int whole = 0;
  int incomplete = 0;
  int timeouts = 0;
  for (int i = 0; i < 60; ++i) {
    camera->software_trigger();
    CapturedImage captured;
    try {
      captured = camera->wait_image(kFrameTimeout);
    } catch (const Error& error) {
      ASSERT_EQ(error.code(), ErrorCode::kTimeout) << error.what();  // a frame lost entirely
      ++timeouts;
      continue;
    }
    if (captured.complete) {
      ++whole;
      EXPECT_TRUE(captured.problem.empty());
      EXPECT_TRUE(captured.image == test::fake_test_pattern(captured.frame_id, 256, 256, 16))
          << "frame " << captured.frame_id << " claims to be whole but is not what the camera sent";
    } else {
      ++incomplete;
      EXPECT_TRUE(captured.image.empty()) << "an incomplete frame must carry no pixels to misuse";
      EXPECT_NE(captured.problem.find("frame " + std::to_string(captured.frame_id)), std::string::npos)
          << captured.problem;
      EXPECT_NE(captured.problem.find("transport status"), std::string::npos) << captured.problem;
    }
  }
  EXPECT_GT(whole, 20);
  EXPECT_GT(incomplete, 0) << "no loss seen: the test exercised nothing";
  EXPECT_EQ(camera->statistics().incomplete_images, static_cast<std::uint64_t>(incomplete));
  EXPECT_LE(timeouts, 3);
  // The stream counted the packets that spoiled those frames: at least one each (the fake
  // ignores resend requests, so none was resent). They outlive the stream stop() drops.
  const std::optional<TransportStatistics> transport = camera->transport_statistics();
  ASSERT_TRUE(transport.has_value());
  std::printf("[ measured ] 60 frames at 0.2 %% packet loss: %d incomplete, %d timed out; the stream counted %llu "
              "missing and %llu resent packets\n",
              incomplete, timeouts, static_cast<unsigned long long>(transport->missing_packets),
              static_cast<unsigned long long>(transport->resent_packets));
  EXPECT_GE(transport->missing_packets, static_cast<std::uint64_t>(incomplete));
  camera->stop();
  camera->start();
  EXPECT_EQ(camera->transport_statistics()->missing_packets, transport->missing_packets);
  EXPECT_EQ(camera->transport_statistics()->resent_packets, transport->resent_packets);
}

TEST(AravisCamera, CameraDestroyedGivesAClearErrorWithinTheTimeout) {
  SLS_REQUIRE_NETNS();
  auto fake = std::make_unique<FakeGigeCamera>(fake_options("127.0.0.1", "SLS-GONE"));
  auto camera = AravisCamera::open(fake->address(), camera_options("Mono8", 32, 32));
  camera->start();
  ASSERT_TRUE(grab(*camera).complete);
  fake.reset();  // the camera vanishes

  auto before = Clock::now();
  std::string message = expect_error([&] { camera->wait_image(milliseconds(300)); },
                                     {ErrorCode::kTimeout, ErrorCode::kDevice});
  EXPECT_LT(Clock::now() - before, milliseconds(1500));
  EXPECT_NE(message.find("SLS-GONE"), std::string::npos) << message;
  // A command to it fails after Aravis's control-channel retries, naming the camera.
  before = Clock::now();
  message = expect_error([&] { camera->software_trigger(); }, {ErrorCode::kTimeout, ErrorCode::kDevice});
  EXPECT_LT(Clock::now() - before, std::chrono::seconds(6));
  EXPECT_NE(message.find("SLS-GONE"), std::string::npos) << message;
}

TEST(AravisCamera, CameraProcessKilledIsReportedAsLost) {
  SLS_REQUIRE_NETNS();
  test::FakeGigeCameraProcess process(fake_options("127.0.0.2", "SLS-KILLED"));
  auto camera = AravisCamera::open("127.0.0.2", camera_options("Mono8", 32, 32));
  camera->start();
  const CapturedImage captured = grab(*camera);
  ASSERT_TRUE(captured.complete) << captured.problem;
  EXPECT_TRUE(captured.image == test::fake_test_pattern(captured.frame_id, 32, 32, 8));
  process.kill();

  // Waiting for images times out until the heartbeat declares the camera lost; from then on
  // every call says it is gone.
  const auto killed = Clock::now();
  std::string lost;
  while (lost.empty() && Clock::now() - killed < std::chrono::seconds(30)) {
    try {
      camera->wait_image(milliseconds(500));
      ADD_FAILURE() << "an image from a killed camera";
    } catch (const Error& error) {
      if (error.code() == ErrorCode::kDevice) {
        lost = error.what();
      } else {
        ASSERT_EQ(error.code(), ErrorCode::kTimeout) << error.what();
      }
    }
  }
  ASSERT_FALSE(lost.empty()) << "the driver never noticed the camera was gone";
  EXPECT_NE(lost.find("SLS-KILLED"), std::string::npos) << lost;
  EXPECT_NE(lost.find("gone"), std::string::npos) << lost;
  expect_error([&] { camera->software_trigger(); }, {ErrorCode::kDevice});
  expect_error([&] { camera->set_exposure_us(1000.0); }, {ErrorCode::kDevice});
}

}  // namespace
}  // namespace sls::drivers
