// The device registry and the C API with the emulated DLPC350 and head controller behind real
// libusb (umockdev), in a private network namespace so GigE Vision discovery sees no camera:
// the USB devices are listed with their URIs, and each URI as listed opens the driver its
// roles name and drives the emulated device.
#include <sls/sls.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <string>
#include <vector>

#include "drivers/device_registry.h"
#include "tests/hardware-free/usb_test_bench.h"

namespace sls::test {
namespace {

using drivers::DeviceDescription;
using drivers::DeviceEnumeration;
using drivers::DeviceKind;
using std::chrono::milliseconds;
using DeviceRegistryUsbTest = UsbDevicesTest;

fwif::models::HeadctlModelOptions fast_table() {
  fwif::models::HeadctlModelOptions options;
  options.default_speed_steps_per_s = 32000;  // a revolution in 0.2 s keeps the test short
  return options;
}

const DeviceDescription* find_kind(const DeviceEnumeration& found, DeviceKind kind) {
  const auto it = std::find_if(found.devices.begin(), found.devices.end(),
                               [&](const DeviceDescription& device) { return device.kind == kind; });
  return it == found.devices.end() ? nullptr : &*it;
}

TEST_F(DeviceRegistryUsbTest, ListsTheProjectorAndControllerWithUrisThatOpenThem) {
  plug({}, fast_table());
  const DeviceEnumeration found = drivers::enumerate_devices();
  EXPECT_TRUE(found.hardware_found());
  ASSERT_EQ(found.transports.size(), 3u);
  EXPECT_TRUE(found.transports[2].searched) << found.transports[2].problem;

  const DeviceDescription* projector = find_kind(found, DeviceKind::kProjector);
  ASSERT_NE(projector, nullptr);
  EXPECT_EQ(projector->uri, "dlpc350://1:2");
  EXPECT_EQ(projector->serial, "LCR4500-EMU-0001");
  EXPECT_EQ(projector->roles, unsigned{drivers::kRoleProjector});
  EXPECT_NE(projector->model.find("Texas Instruments"), std::string::npos) << projector->model;
  EXPECT_NE(projector->details.find("0451:6401 on bus 1 address 2"), std::string::npos) << projector->details;

  const DeviceDescription* controller = find_kind(found, DeviceKind::kController);
  ASSERT_NE(controller, nullptr);
  EXPECT_EQ(controller->uri, "headctl://1:3");
  EXPECT_EQ(controller->serial, "HC-EMU-0001");
  EXPECT_EQ(controller->roles, unsigned{drivers::kRoleTurntable});

  // The URIs as listed open the drivers, which then drive the emulated devices.
  const std::unique_ptr<drivers::Projector> dlpc350 = drivers::open_projector(projector->uri);
  EXPECT_EQ(dlpc350->info().uri, projector->uri);
  EXPECT_EQ(dlpc350->info().firmware, "application 3.0.0, API 2.0.0");
  const std::unique_ptr<drivers::Turntable> turntable = drivers::open_turntable(controller->uri);
  EXPECT_EQ(turntable->steps_per_revolution(), 6400);
  turntable->home(milliseconds{2000});
  turntable->move_to_deg(90.0, milliseconds{2000});
  EXPECT_DOUBLE_EQ(turntable->position_deg(), 90.0);
  EXPECT_EQ(head_model_->turntable().position_step, 1600u) << "the move reached the board";

  // And nothing opens as what it is not.
  const std::string message = error_message([&] { drivers::open_camera(projector->uri); }, ErrorCode::kInvalidArgument);
  EXPECT_NE(message.find(projector->uri), std::string::npos) << message;
  error_message([&] { drivers::open_projector(controller->uri); }, ErrorCode::kInvalidArgument);
}

TEST_F(DeviceRegistryUsbTest, UnpluggedDevicesAreNotFound) {
  plug();
  error_message([] { drivers::open_projector("dlpc350://1:7"); }, ErrorCode::kNotFound);
  error_message([] { drivers::open_turntable("headctl://?serial=HC-NOT-HERE"); }, ErrorCode::kNotFound);
}

TEST_F(DeviceRegistryUsbTest, CApiListsThemWithTheirKindsAndRoles) {
  plug();
  sls_context* context = nullptr;
  ASSERT_EQ(sls_context_create(SLS_API_VERSION, nullptr, &context, nullptr), SLS_OK);
  sls_device_list* list = nullptr;
  ASSERT_EQ(sls_device_list_create(context, &list, nullptr), SLS_OK);
  std::size_t count = 0;
  ASSERT_EQ(sls_device_list_count(list, &count, nullptr), SLS_OK);
  // Cameras aside (none in the private network namespace; run without one, a real camera on
  // the network may appear): the simulator, then the USB devices in bus order.
  std::vector<std::string> uris;
  std::vector<sls_device_kind> kinds;
  std::vector<unsigned> roles;
  for (std::size_t i = 0; i < count; ++i) {
    sls_device_info info;
    sls_device_info_init(&info);
    ASSERT_EQ(sls_device_list_get_info(list, i, &info, nullptr), SLS_OK);
    if (info.kind == SLS_DEVICE_KIND_CAMERA) continue;
    uris.emplace_back(info.uri);
    kinds.push_back(info.kind);
    roles.push_back(info.roles);
  }
  EXPECT_EQ(uris, (std::vector<std::string>{"sim://knurled-screw?preset=ci", "dlpc350://1:2", "headctl://1:3"}));
  EXPECT_EQ(kinds, (std::vector<sls_device_kind>{SLS_DEVICE_KIND_SCANNER, SLS_DEVICE_KIND_PROJECTOR,
                                                 SLS_DEVICE_KIND_CONTROLLER}));
  EXPECT_EQ(roles, (std::vector<unsigned>{
                       SLS_DEVICE_ROLE_CAMERA | SLS_DEVICE_ROLE_PROJECTOR | SLS_DEVICE_ROLE_TURNTABLE,
                       SLS_DEVICE_ROLE_PROJECTOR, SLS_DEVICE_ROLE_TURNTABLE}));
  int has_hardware = 0;
  EXPECT_EQ(sls_device_list_has_hardware(list, &has_hardware, nullptr), SLS_OK);
  EXPECT_EQ(has_hardware, 1);
  sls_device_list_destroy(list);
  // A projector is no camera: refused by name, before any USB traffic.
  sls_camera* camera = nullptr;
  sls_error* error = nullptr;
  EXPECT_EQ(sls_camera_open(context, "dlpc350://1:2", &camera, &error), SLS_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(sls_error_message(error)).find("dlpc350://1:2"), std::string::npos);
  sls_error_free(error);
  sls_context_destroy(context);
}

}  // namespace
}  // namespace sls::test
