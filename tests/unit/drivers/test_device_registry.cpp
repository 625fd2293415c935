// The device registry with whatever this machine has connected (with no hardware: the
// simulator only): every listed URI opens through the factories of its roles, the simulator's
// parts share one scanner, and URIs that cannot open fail with a code and a message naming the
// URI and what is missing. The fake GigE camera and the emulated USB devices are covered by the
// hardware-free tests (tests/hardware-free/aravis/test_device_registry_gige.cpp,
// tests/hardware-free/test_device_registry_usb.cpp).
#include "drivers/device_registry.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <string>

#include "sdk/core/error.h"

namespace sls::drivers {
namespace {

using std::chrono::milliseconds;

template <typename Call>
std::string expect_error(Call&& call, ErrorCode code) {
  try {
    call();
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), code) << error.what();
    return error.what();
  }
  ADD_FAILURE() << "no sls::Error thrown";
  return {};
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

OpenOptions on_cpu() {
  OpenOptions options;
  options.sim_device = Device::cpu();
  return options;
}

TEST(DeviceRegistry, ListsTheSimulatorAndReportsEveryTransport) {
  const DeviceEnumeration found = enumerate_devices();
  ASSERT_FALSE(found.devices.empty());
  const DeviceDescription& sim = found.devices.front();
  EXPECT_EQ(sim.kind, DeviceKind::kScanner);
  EXPECT_EQ(sim.uri, "sim://knurled-screw?preset=ci");
  EXPECT_EQ(sim.roles, unsigned{kRoleCamera | kRoleProjector | kRoleTurntable});
  EXPECT_TRUE(contains(sim.details, "camera 400x300 12-bit")) << sim.details;
  // Only the simulator is a scanner; hardware_found() says whether anything else is there.
  const auto scanners = std::count_if(found.devices.begin(), found.devices.end(),
                                      [](const DeviceDescription& d) { return d.kind == DeviceKind::kScanner; });
  EXPECT_EQ(scanners, 1);
  EXPECT_EQ(found.hardware_found(), found.devices.size() > 1);

  ASSERT_EQ(found.transports.size(), 3u);
  EXPECT_EQ(found.transports[0].name, "simulator");
  EXPECT_TRUE(found.transports[0].searched);
  for (const TransportSearch& transport : found.transports) {
    EXPECT_EQ(transport.searched, transport.problem.empty()) << transport.name << ": " << transport.problem;
  }
#if !defined(SLS_HAVE_ARAVIS)
  EXPECT_TRUE(contains(found.transports[1].problem, "not in this build")) << found.transports[1].problem;
#endif
  for (const DeviceDescription& device : found.devices) {
    EXPECT_FALSE(device.uri.empty());
    EXPECT_FALSE(device.model.empty()) << device.uri;
    EXPECT_NE(device.roles, 0u) << device.uri;
  }
}

// The property `sls devices` promises: every URI it prints opens as what its roles say.
TEST(DeviceRegistry, EveryListedDeviceOpensByItsUri) {
  for (const DeviceDescription& device : enumerate_devices().devices) {
    SCOPED_TRACE(device.uri);
    if ((device.roles & kRoleCamera) != 0) {
      const std::unique_ptr<Camera> camera = open_camera(device.uri, on_cpu());
      ASSERT_NE(camera, nullptr);
      EXPECT_GT(camera->info().width, 0);
      EXPECT_GT(camera->info().height, 0);
    }
    if ((device.roles & kRoleProjector) != 0) {
      const std::unique_ptr<Projector> projector = open_projector(device.uri, on_cpu());
      ASSERT_NE(projector, nullptr);
      EXPECT_GT(projector->info().width, 0);
    }
    if ((device.roles & kRoleTurntable) != 0) {
      const std::unique_ptr<Turntable> turntable = open_turntable(device.uri, on_cpu());
      ASSERT_NE(turntable, nullptr);
      EXPECT_GT(turntable->steps_per_revolution(), 0);
    }
  }
}

TEST(DeviceRegistry, SimulatedDevicesOfOneUriAreOneScanner) {
  const std::string uri = "sim://plane?preset=ci&noise=0";
  auto camera = open_camera(uri, on_cpu());
  auto projector = open_projector(uri, on_cpu());
  auto turntable = open_turntable(uri, on_cpu());
  EXPECT_EQ(camera->info().width, 400);
  camera->start();
  const auto grab = [&] {
    camera->software_trigger();
    return camera->wait_image(milliseconds(1000)).image;
  };
  projector->go_dark();
  const Image16u dark = grab();
  projector->show_pattern(0);  // the first pattern of the set is all white
  const Image16u lit = grab();
  // The camera sees the projector it was opened with: a lit plane is brighter than a dark one.
  double dark_sum = 0, lit_sum = 0;
  for (int y = 0; y < dark.height(); ++y) {
    for (int x = 0; x < dark.width(); ++x) {
      dark_sum += dark(x, y);
      lit_sum += lit(x, y);
    }
  }
  EXPECT_GT(lit_sum, 2.0 * dark_sum + 1000.0);
  // A turntable of the same URI moves the same scanner (36 steps per revolution in ci).
  turntable->home(milliseconds(100));
  turntable->move_to_deg(10.0, milliseconds(100));
  EXPECT_DOUBLE_EQ(open_turntable(uri, on_cpu())->position_deg(), 10.0);
  // Another URI is another scanner.
  EXPECT_DOUBLE_EQ(open_turntable("sim://plane?preset=ci&noise=1", on_cpu())->position_deg(), 0.0);
}

TEST(DeviceRegistry, SimulatedScannerIsReleasedWhenItsLastDeviceCloses) {
  const std::string uri = "sim://sphere?preset=ci";
  {
    auto turntable = open_turntable(uri, on_cpu());
    turntable->home(milliseconds(100));
    turntable->move_to_deg(20.0, milliseconds(100));
  }
  EXPECT_DOUBLE_EQ(open_turntable(uri, on_cpu())->position_deg(), 0.0) << "a new scanner starts at home";
}

TEST(DeviceRegistry, UnknownSchemesAndPathsAreUnsupportedAndNamed) {
  std::string message = expect_error([] { open_camera("firewire://0"); }, ErrorCode::kUnsupported);
  EXPECT_TRUE(contains(message, "firewire://0")) << message;
  EXPECT_TRUE(contains(message, "gige://")) << message;  // says what it knows
  message = expect_error([] { open_projector("/data/recording"); }, ErrorCode::kUnsupported);
  EXPECT_TRUE(contains(message, "/data/recording")) << message;
  EXPECT_TRUE(contains(message, "dlpc350://")) << message;
  expect_error([] { open_turntable("://nothing"); }, ErrorCode::kInvalidArgument);
}

TEST(DeviceRegistry, ASchemeOfAnotherKindIsRefusedBeforeAnyConnection) {
  std::string message = expect_error([] { open_projector("gige://192.0.2.1"); }, ErrorCode::kInvalidArgument);
  EXPECT_TRUE(contains(message, "gige://192.0.2.1") && contains(message, "camera")) << message;
  message = expect_error([] { open_camera("headctl://1:3"); }, ErrorCode::kInvalidArgument);
  EXPECT_TRUE(contains(message, "turntable") && contains(message, "sim://")) << message;
  expect_error([] { open_turntable("dlpc350://"); }, ErrorCode::kInvalidArgument);
}

TEST(DeviceRegistry, SchemesMatchThisBuild) {
  const std::vector<DeviceScheme>& schemes = device_schemes();
  ASSERT_EQ(schemes.size(), 6u);
  for (const DeviceScheme& scheme : schemes) {
    SCOPED_TRACE(scheme.scheme);
    bool expected = true;
#if !defined(SLS_HAVE_ARAVIS)
    if (scheme.scheme == "gige" || scheme.scheme == "usb3") expected = false;
#endif
#if !defined(SLS_HAVE_LIBUSB)
    if (scheme.scheme == "dlpc350" || scheme.scheme == "headctl") expected = false;
#endif
    EXPECT_EQ(scheme.built_in, expected);
    if (scheme.built_in) continue;
    // A driver this build lacks: kUnsupported naming the URI and the missing library.
    const std::string uri = scheme.scheme + "://x";
    const std::string message = expect_error(
        [&] {
          if ((scheme.roles & kRoleCamera) != 0) open_camera(uri);
          if ((scheme.roles & kRoleProjector) != 0) open_projector(uri);
          if ((scheme.roles & kRoleTurntable) != 0) open_turntable(uri);
        },
        ErrorCode::kUnsupported);
    EXPECT_TRUE(contains(message, uri) && contains(message, scheme.requirement)) << message;
  }
}

TEST(DeviceRegistry, AbsentHardwareIsNotFound) {
#if defined(SLS_HAVE_LIBUSB)
  // No DLPC350 with this serial is connected on any machine.
  const std::string message =
      expect_error([] { open_projector("dlpc350://?serial=SLS-NO-SUCH-DEVICE"); }, ErrorCode::kNotFound);
  EXPECT_TRUE(contains(message, "SLS-NO-SUCH-DEVICE")) << message;
#else
  GTEST_SKIP() << "built without libusb";
#endif
}

TEST(DeviceRegistry, KindAndRoleNames) {
  EXPECT_STREQ(device_kind_name(DeviceKind::kCamera), "camera");
  EXPECT_STREQ(device_kind_name(DeviceKind::kProjector), "projector");
  EXPECT_STREQ(device_kind_name(DeviceKind::kController), "controller");
  EXPECT_STREQ(device_kind_name(DeviceKind::kScanner), "scanner");
  EXPECT_EQ(device_role_names(kRoleCamera | kRoleTurntable), (std::vector<std::string>{"camera", "turntable"}));
  EXPECT_TRUE(device_role_names(0).empty());
}

}  // namespace
}  // namespace sls::drivers
