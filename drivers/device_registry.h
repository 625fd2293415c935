// The device registry: what is connected (enumerate_devices) and how a device URI becomes a
// driver object (open_camera / open_projector / open_turntable). The one place that maps URI
// schemes to drivers, so `sls devices`, the C API and the capture sequencer agree on which URIs
// open what:
//   sim://OBJECT?...        the simulated scanner: camera, projector and turntable
//   replay://PATH?...       a recording played back as camera, projector and turntable
//                           (drivers/replay/replay_recording.h)
//   gige://ADDRESS|ID       GenICam cameras through Aravis (GigE Vision)
//   usb3://SERIAL|ID        GenICam cameras through Aravis (USB3 Vision)
//   dlpc350://[BUS:ADDR]    the DLPC350 projector over USB
//   headctl://[BUS:ADDR]    the head controller's turntable over USB
// Every URI that enumerate_devices() lists is accepted by the open_* functions its roles name.
// Plain C++ structs and the driver interfaces only: no Aravis or libusb type appears here.
//
// Thread safety: all functions may be called from several threads; each returned driver
// object has the thread safety its own header states.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "drivers/interfaces/camera.h"
#include "drivers/interfaces/projector.h"
#include "drivers/interfaces/turntable.h"
#include "drivers/sim/scene.h"
#include "sdk/core/device.h"

namespace sls::drivers {

enum class DeviceKind {
  kCamera,      // a GenICam camera
  kProjector,   // a pattern projector (DLPC350)
  kController,  // the head controller board (trigger outputs, turntable)
  kScanner,     // a whole scanner behind one URI (the simulator)
};
const char* device_kind_name(DeviceKind kind);  // "camera", "projector", "controller", "scanner"

// What a device URI can be opened as (a bit set: DeviceRoles).
enum DeviceRole : unsigned {
  kRoleCamera = 1u,     // open_camera
  kRoleProjector = 2u,  // open_projector
  kRoleTurntable = 4u,  // open_turntable
};
// "camera", "projector", "turntable" for each bit set in `roles`, in that order.
std::vector<std::string> device_role_names(unsigned roles);

// One device found by enumerate_devices().
struct DeviceDescription {
  DeviceKind kind = DeviceKind::kCamera;
  std::string uri;       // what the open_* functions of `roles` accept
  std::string model;     // vendor and model, e.g. "Basler acA1920-40gm", "Texas Instruments DLPC350"
  std::string serial;    // "" when the device does not report one
  std::string details;   // transport and address, e.g. "GigE Vision at 192.168.1.20"
  unsigned roles = 0;    // DeviceRole bits
};

// One way of finding devices and whether it could be searched.
struct TransportSearch {
  std::string name;       // "simulator", "Aravis", "USB"
  std::string covers;     // what it finds, e.g. "GigE Vision and USB3 Vision cameras"
  bool searched = false;  // false: not in this build, or the search failed (see problem)
  std::string problem;    // why it was not searched; "" when it was
};

struct DeviceEnumeration {
  std::vector<DeviceDescription> devices;    // the simulator first, then cameras, then USB devices
  std::vector<TransportSearch> transports;   // every transport, searched or not
  // True when anything besides the always-present simulator was found.
  bool hardware_found() const;
};

struct EnumerateOptions {
  // Head controllers an OEM build ships with its own USB IDs (VID, PID), listed besides the
  // protocol's development IDs (their URIs carry ?vid=&pid=).
  std::vector<std::pair<std::uint16_t, std::uint16_t>> head_controller_ids;
};

// Lists the built-in simulator and every camera, projector and head controller the drivers in
// this build can find now. Blocks for Aravis's GigE Vision discovery (about a second) when
// Aravis is built in. A transport that fails to search (e.g. no USB access) is reported in
// `transports` instead of failing the whole enumeration.
DeviceEnumeration enumerate_devices(const EnumerateOptions& options = {});

// A URI scheme this SDK knows, and whether its driver is in this build.
struct DeviceScheme {
  std::string scheme;       // "gige"
  unsigned roles = 0;       // DeviceRole bits
  std::string driver;       // "the Aravis camera driver (drivers/aravis)"
  bool built_in = false;
  std::string requirement;  // what a build needs for it, e.g. "Aravis 0.8 (libaravis-dev)"
};
const std::vector<DeviceScheme>& device_schemes();

struct OpenOptions {
  // Where simulated devices render when their sim:// URI has no device= key; unset: the first
  // usable CUDA GPU, else the CPU.
  std::optional<Device> sim_device;
  // Makes the board of a sim:// calibration target with board=charuco[:COLSxROWS] (its markers
  // need calib, above the drivers; session::device_open_options() sets it); unset: such a URI
  // is refused (kUnsupported).
  sim::CharucoBoardMaker sim_charuco_board;
};

// Open a device by URI, ready to use (a camera in software-trigger mode, not yet started).
// sim:// devices opened with the same URI (and sim_device) while any of them is still open are
// parts of one simulated scanner, so its camera sees what its projector shows at its
// turntable's angle. replay:// devices opened with one URI (one folder, the same options)
// while any of them is open share one opened recording likewise.
// Errors (sls::Error), each message naming the URI:
//   kUnsupported      unknown scheme, a recording path, or a driver not in this build (the
//                     message says what the build lacks); a head controller without turntable
//   kInvalidArgument  malformed URI, or a scheme that names another kind of device (gige:// as
//                     a projector)
//   kNotFound         nothing answers at that address / no such device connected / no
//                     recording at a replay:// path (kFormat: a corrupt one)
//   kDevice, kTimeout the device misbehaved while being opened
std::unique_ptr<Camera> open_camera(const std::string& uri, const OpenOptions& options = {});
std::unique_ptr<Projector> open_projector(const std::string& uri, const OpenOptions& options = {});
std::unique_ptr<Turntable> open_turntable(const std::string& uri, const OpenOptions& options = {});

// A scanner head's devices opened together, as a capture uses them: the projector, the camera,
// and the turntable when `turntable_uri` is not empty (else nullptr). Closed in the reverse order.
struct ScannerDevices {
  std::unique_ptr<Projector> projector;
  std::unique_ptr<Camera> camera;
  std::unique_ptr<Turntable> turntable;
};
ScannerDevices open_scanner_devices(const std::string& projector_uri, const std::string& camera_uri,
                                    const std::string& turntable_uri, const OpenOptions& options = {});

}  // namespace sls::drivers
