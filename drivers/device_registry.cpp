#include "drivers/device_registry.h"

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <map>
#include <mutex>

#include "drivers/interfaces/device_uri.h"
#include "drivers/replay/replay_recording.h"
#include "drivers/sim/rig.h"
#include "drivers/sim/scene.h"
#include "drivers/sim/sim_scanner.h"
#include "sdk/core/error.h"

#if defined(SLS_HAVE_ARAVIS)
#include "drivers/aravis/aravis_camera.h"
#endif
#if defined(SLS_HAVE_LIBUSB)
#include "drivers/dlpc350/dlpc350_projector.h"
#include "drivers/headctl/head_controller.h"
#include "drivers/usb/usb_scanner_devices.h"
#include "firmware-interface/headctl/headctl_protocol.h"
#endif

namespace sls::drivers {
namespace {

#if defined(SLS_HAVE_ARAVIS)
constexpr bool kHaveAravis = true;
#else
constexpr bool kHaveAravis = false;
#endif
#if defined(SLS_HAVE_LIBUSB)
constexpr bool kHaveLibusb = true;
#else
constexpr bool kHaveLibusb = false;
#endif

const char* const kAravisRequirement = "Aravis 0.8 (libaravis-dev) when it is configured";
const char* const kLibusbRequirement = "libusb 1.0 (libusb-1.0-0-dev) when it is configured";

// The simulator entry: the ci preset renders a 400 x 300 image in milliseconds on a CPU, so
// opening the listed URI is cheap everywhere.
const char* const kSimObject = "knurled-screw";
const char* const kSimPreset = "ci";

std::string join(const std::vector<std::string>& items, const char* separator) {
  std::string text;
  for (const std::string& item : items) text += (text.empty() ? "" : separator) + item;
  return text;
}

const char* role_name(DeviceRole role) {
  switch (role) {
    case kRoleCamera: return "camera";
    case kRoleProjector: return "projector";
    case kRoleTurntable: return "turntable";
  }
  return "device";
}

// "sim://, dlpc350://": the schemes that open `role`.
std::string schemes_for(DeviceRole role) {
  std::vector<std::string> schemes;
  for (const DeviceScheme& scheme : device_schemes()) {
    if ((scheme.roles & role) != 0) schemes.push_back(scheme.scheme + "://");
  }
  return join(schemes, ", ");
}

// Parses `text` and checks that its scheme is known, built in and opens `role`; throws as the
// header says.
DeviceUri checked_uri(const std::string& text, DeviceRole role) {
  const DeviceUri uri = parse_device_uri(text);
  if (uri.scheme == "file") {
    throw_error(ErrorCode::kUnsupported,
                "'{}' is a path (a recording), not a device URI; recordings are read as input, devices are "
                "opened by URI ({})",
                text, schemes_for(role));
  }
  const std::vector<DeviceScheme>& schemes = device_schemes();
  const auto found = std::find_if(schemes.begin(), schemes.end(),
                                  [&](const DeviceScheme& scheme) { return scheme.scheme == uri.scheme; });
  if (found == schemes.end()) {
    std::vector<std::string> known;
    for (const DeviceScheme& scheme : schemes) known.push_back(scheme.scheme + "://");
    throw_error(ErrorCode::kUnsupported, "'{}': unknown device scheme '{}' (known: {})", text, uri.scheme,
                join(known, ", "));
  }
  if ((found->roles & role) == 0) {
    throw_error(ErrorCode::kInvalidArgument, "'{}' names a {}, which cannot be opened as a {} (a {} is opened by {})",
                text, join(device_role_names(found->roles), "/"), role_name(role), role_name(role),
                schemes_for(role));
  }
  if (!found->built_in) {
    throw_error(ErrorCode::kUnsupported, "'{}': {} is not in this build; it is built with {}", text, found->driver,
                found->requirement);
  }
  return uri;
}

// Devices opened from one sim:// URI share one SimScanner while any of them lives: the
// scanner's camera, projector and turntable are views of one shared state.
std::shared_ptr<sim::SimScanner> shared_sim_scanner(DeviceUri uri, const OpenOptions& options) {
  if (options.sim_device && uri.query.count("device") == 0) uri.query["device"] = options.sim_device->to_string();
  const std::string key = uri.to_string();
  static std::mutex mutex;
  static std::map<std::string, std::weak_ptr<sim::SimScanner>> scanners;
  std::lock_guard<std::mutex> lock(mutex);
  for (auto it = scanners.begin(); it != scanners.end();) {  // forget scanners nobody holds
    it = it->second.expired() ? scanners.erase(it) : std::next(it);
  }
  if (auto scanner = scanners[key].lock()) return scanner;
  std::shared_ptr<sim::SimScanner> scanner = sim::SimScanner::open(key, options.sim_charuco_board);
  scanners[key] = scanner;
  return scanner;
}

// Devices opened from one replay:// URI share one opened recording while any of them lives,
// so the turntable selects the frame its camera plays. The key names the folder canonically:
// replay://rec and replay://./rec/ are one recording.
std::shared_ptr<replay::ReplayRecording> shared_replay_recording(const std::string& text, DeviceUri uri) {
  std::error_code error;
  std::filesystem::path folder = std::filesystem::weakly_canonical(uri.target, error);
  if (!error) {
    if (!folder.has_filename() && folder.has_parent_path()) folder = folder.parent_path();  // "rec/"
    uri.target = folder.string();
  }
  const std::string key = uri.to_string();
  static std::mutex mutex;
  static std::map<std::string, std::weak_ptr<replay::ReplayRecording>> recordings;
  std::lock_guard<std::mutex> lock(mutex);
  for (auto it = recordings.begin(); it != recordings.end();) {
    it = it->second.expired() ? recordings.erase(it) : std::next(it);
  }
  if (auto recording = recordings[key].lock()) return recording;
  std::shared_ptr<replay::ReplayRecording> recording = replay::ReplayRecording::open(text);
  recordings[key] = recording;
  return recording;
}

DeviceDescription simulator_entry() {
  sim::RigOptions rig_options;
  rig_options.preset = kSimPreset;
  const sim::SimRig rig = sim::make_rig(rig_options, sim::make_scene(kSimObject));
  DeviceDescription device;
  device.kind = DeviceKind::kScanner;
  device.uri = fmt::format("sim://{}?preset={}", kSimObject, kSimPreset);
  device.model = "slscan simulated scanner";
  device.details = fmt::format(
      "built in; camera {}x{} {}-bit, projector {}x{}, turntable {} steps; objects {} and presets ci, demo, paper "
      "by URI",
      rig.camera.width, rig.camera.height, rig.optics.camera_sensor.bit_depth, rig.projector.width,
      rig.projector.height, rig.turntable.steps_per_revolution, join(sim::scene_names(), ", "));
  device.roles = kRoleCamera | kRoleProjector | kRoleTurntable;
  return device;
}

#if defined(SLS_HAVE_ARAVIS)
void add_aravis_cameras(std::vector<DeviceDescription>& devices) {
  for (const DiscoveredCamera& camera : discover_aravis_cameras()) {
    DeviceDescription device;
    device.kind = DeviceKind::kCamera;
    device.uri = camera.uri();
    device.model = camera.vendor.empty() ? camera.model : camera.vendor + " " + camera.model;
    device.serial = camera.serial;
    const char* transport = camera.protocol == "USB3Vision" ? "USB3 Vision" : "GigE Vision";
    device.details = fmt::format("{} at {} (Aravis id {})", transport, camera.address, camera.id);
    device.roles = kRoleCamera;
    devices.push_back(std::move(device));
  }
}
#endif

#if defined(SLS_HAVE_LIBUSB)
void add_usb_devices(const EnumerateOptions& options, std::vector<DeviceDescription>& devices) {
  for (const usb::UsbScannerDevice& found : usb::list_usb_scanner_devices(options.head_controller_ids)) {
    const bool projector = found.kind == usb::UsbScannerDeviceKind::kDlpc350Projector;
    DeviceDescription device;
    device.kind = projector ? DeviceKind::kProjector : DeviceKind::kController;
    device.uri = found.uri;
    const std::string strings = join({found.usb.manufacturer, found.usb.product}, " ");
    device.model = strings.find_first_not_of(' ') == std::string::npos
                       ? usb::usb_scanner_device_kind_name(found.kind)
                       : strings;
    device.serial = found.usb.serial;
    device.details = fmt::format("{}, USB {:04x}:{:04x} on bus {} address {}",
                                 usb::usb_scanner_device_kind_name(found.kind), found.usb.vendor_id,
                                 found.usb.product_id, found.usb.bus, found.usb.address);
    // Whether a board has a turntable is only known once it is opened (its identify reply).
    device.roles = projector ? kRoleProjector : kRoleTurntable;
    devices.push_back(std::move(device));
  }
}
#endif

// Runs one transport's search; its failure is recorded, not thrown, so one broken transport
// (e.g. no access to USB in a container) does not hide the devices of the others.
template <typename Search>
TransportSearch search(const char* name, const char* covers, bool built_in, const char* requirement,
                       Search&& body) {
  TransportSearch transport{name, covers, false, ""};
  if (!built_in) {
    transport.problem = fmt::format("not in this build (it needs {})", requirement);
    return transport;
  }
  try {
    body();
    transport.searched = true;
  } catch (const Error& error) {
    transport.problem = error.what();
  }
  return transport;
}

}  // namespace

const char* device_kind_name(DeviceKind kind) {
  switch (kind) {
    case DeviceKind::kCamera: return "camera";
    case DeviceKind::kProjector: return "projector";
    case DeviceKind::kController: return "controller";
    case DeviceKind::kScanner: return "scanner";
  }
  return "device";
}

std::vector<std::string> device_role_names(unsigned roles) {
  std::vector<std::string> names;
  for (const DeviceRole role : {kRoleCamera, kRoleProjector, kRoleTurntable}) {
    if ((roles & role) != 0) names.emplace_back(role_name(role));
  }
  return names;
}

bool DeviceEnumeration::hardware_found() const {
  return std::any_of(devices.begin(), devices.end(),
                     [](const DeviceDescription& device) { return device.kind != DeviceKind::kScanner; });
}

const std::vector<DeviceScheme>& device_schemes() {
  static const std::vector<DeviceScheme> kSchemes = {
      {"sim", kRoleCamera | kRoleProjector | kRoleTurntable, "the simulated scanner (drivers/sim)", true, ""},
      {"replay", kRoleCamera | kRoleProjector | kRoleTurntable, "recorded sessions (drivers/replay)", true, ""},
      {"gige", kRoleCamera, "the Aravis camera driver (drivers/aravis)", kHaveAravis, kAravisRequirement},
      {"usb3", kRoleCamera, "the Aravis camera driver (drivers/aravis)", kHaveAravis, kAravisRequirement},
      {"dlpc350", kRoleProjector, "the DLPC350 projector driver (drivers/dlpc350)", kHaveLibusb, kLibusbRequirement},
      {"headctl", kRoleTurntable, "the head controller driver (drivers/headctl)", kHaveLibusb, kLibusbRequirement},
  };
  return kSchemes;
}

DeviceEnumeration enumerate_devices([[maybe_unused]] const EnumerateOptions& options) {
  DeviceEnumeration result;
  result.transports.push_back(search("simulator", "the built-in simulated scanner", true, "",
                                     [&] { result.devices.push_back(simulator_entry()); }));
  result.transports.push_back(
      search("Aravis", "GigE Vision and USB3 Vision cameras", kHaveAravis, kAravisRequirement, [&] {
#if defined(SLS_HAVE_ARAVIS)
        add_aravis_cameras(result.devices);
#endif
      }));
  result.transports.push_back(
      search("USB", "DLPC350 projectors and head controllers", kHaveLibusb, kLibusbRequirement, [&] {
#if defined(SLS_HAVE_LIBUSB)
        add_usb_devices(options, result.devices);
#endif
      }));
  return result;
}

std::unique_ptr<Camera> open_camera(const std::string& text, const OpenOptions& options) {
  const DeviceUri uri = checked_uri(text, kRoleCamera);
  if (uri.scheme == "sim") return shared_sim_scanner(uri, options)->camera();
  if (uri.scheme == "replay") return shared_replay_recording(text, uri)->camera();
#if defined(SLS_HAVE_ARAVIS)
  std::unique_ptr<AravisCamera> camera = AravisCamera::open(uri);
  camera->set_trigger_source(TriggerSource::kSoftware);  // what open() promises for every camera
  return camera;
#else
  throw_error(ErrorCode::kInternal, "'{}': scheme accepted but no camera driver built", text);
#endif
}

std::unique_ptr<Projector> open_projector(const std::string& text, const OpenOptions& options) {
  const DeviceUri uri = checked_uri(text, kRoleProjector);
  if (uri.scheme == "sim") return shared_sim_scanner(uri, options)->projector();
  if (uri.scheme == "replay") return shared_replay_recording(text, uri)->projector();
#if defined(SLS_HAVE_LIBUSB)
  return Dlpc350Projector::open(text);
#else
  throw_error(ErrorCode::kInternal, "'{}': scheme accepted but no projector driver built", text);
#endif
}

std::unique_ptr<Turntable> open_turntable(const std::string& text, const OpenOptions& options) {
  const DeviceUri uri = checked_uri(text, kRoleTurntable);
  if (uri.scheme == "sim") return shared_sim_scanner(uri, options)->turntable();
  if (uri.scheme == "replay") return shared_replay_recording(text, uri)->turntable();
#if defined(SLS_HAVE_LIBUSB)
  std::unique_ptr<HeadController> controller = HeadController::open(text);
  // The same test as the driver's own before any turntable command: the capability and a
  // step count to turn angles into steps.
  if ((controller->identity().capabilities & HEADCTL_CAP_TURNTABLE) == 0 || controller->steps_per_revolution() <= 0) {
    throw_error(ErrorCode::kUnsupported, "'{}': {} has no turntable", text, controller->name());
  }
  return controller;
#else
  throw_error(ErrorCode::kInternal, "'{}': scheme accepted but no turntable driver built", text);
#endif
}

ScannerDevices open_scanner_devices(const std::string& projector_uri, const std::string& camera_uri,
                                    const std::string& turntable_uri, const OpenOptions& options) {
  ScannerDevices devices;
  devices.projector = open_projector(projector_uri, options);
  devices.camera = open_camera(camera_uri, options);
  if (!turntable_uri.empty()) devices.turntable = open_turntable(turntable_uri, options);
  return devices;
}

}  // namespace sls::drivers
