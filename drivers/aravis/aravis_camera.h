// GenICam cameras (GigE Vision, USB3 Vision) through Aravis 0.8, behind drivers::Camera.
// Aravis and GLib types stay in aravis_camera.cpp (pimpl); this header is plain C++.
//
// What the driver guarantees:
// - Every buffer's transport status is checked. A frame Aravis could not complete (missing
//   packets, frame-retention timeout, size mismatch, ...) comes back with complete = false, an
//   empty image and `problem` naming the status and frame id. The driver does not re-request
//   it: Aravis has already asked the camera to resend the lost packets (GigE Vision packet
//   resend) before giving up, and re-exposing means re-projecting the pattern, which only the
//   capture sequencer can do.
// - Frame-id gaps (frames the camera sent that never arrived, e.g. a whole frame lost or the
//   buffer pool ran dry) are counted in CapturedImage::frames_missed of the next image.
// - Mono8 pixels are stored as they are (0..255, bit_depth 8), not scaled; Mono10/12/16 are
//   unpacked 16-bit containers stored as they are. Packed formats are refused.
// - A lost camera (no heartbeat answer, Aravis's "control-lost") makes every later call throw
//   sls::Error(kDevice) naming the camera; an image that does not arrive in time throws
//   kTimeout naming the camera. Control-channel commands to a camera that stopped answering
//   fail after Aravis's own GVCP retries with kTimeout: 5 tries of 500 ms per transaction in
//   0.8; a software trigger to a vanished camera is measured at about 5 s (two transactions).
//   Closing such a camera waits for Aravis's heartbeat thread to give up (up to about 10 s in
//   0.8).
// Thread safety: one thread drives a camera at a time; different cameras are independent.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "drivers/interfaces/camera.h"
#include "drivers/interfaces/device_uri.h"

namespace sls::drivers {

// A camera Aravis found, as discovery reports it.
struct DiscoveredCamera {
  std::string id;        // Aravis device id, e.g. "Basler-21234567"
  std::string vendor;
  std::string model;
  std::string serial;
  std::string address;   // IPv4 address (GigE Vision) or USB location (USB3 Vision)
  std::string protocol;  // "GigEVision" or "USB3Vision"

  // The URI that opens this camera: gige://<address> or usb3://<serial>.
  std::string uri() const;
};

// Lists the GigE Vision cameras that answer discovery on every network interface and the USB3
// Vision cameras on the USB buses. Blocks for Aravis's discovery time (a fraction of a second).
std::vector<DiscoveredCamera> discover_aravis_cameras();

struct AravisCameraOptions {
  std::string pixel_format = "Mono16";  // Mono8, Mono10, Mono12 or Mono16 (unpacked)
  int width = 0;                        // 0 keeps the camera's current region
  int height = 0;
  // GigE Vision stream packet size in bytes (GevSCPSPacketSize, IP and UDP headers included).
  // 0 negotiates: Aravis's test-packet search when the camera can fire test packets, otherwise
  // the largest size the camera allows that fits the MTU of the host interface it is reached on.
  int packet_size = 0;
  int buffer_count = 8;                 // buffers in the stream's pool
  std::string trigger_line = "Line0";   // the input used for TriggerSource::kHardwareLine
};

struct AravisStatistics {
  std::uint64_t images = 0;             // buffers returned by wait_image, whole or not
  std::uint64_t incomplete_images = 0;  // of those, complete = false
  std::uint64_t frames_missed = 0;      // frame-id gaps, summed
};

class AravisCamera final : public Camera {
 public:
  // Opens a camera by IPv4 address (GigE Vision, no discovery needed: the right way for
  // loopback and fixed-address cameras), or by Aravis device id or serial number (found through
  // discovery; a GigE camera found so is then opened by its address so that its stream binds to
  // the interface it answered on). Configures it per `options`, software trigger selected.
  // Throws sls::Error: kNotFound (nothing answers), kUnsupported (pixel format, missing
  // features), kInvalidArgument (bad options), kDevice/kTimeout (transport).
  static std::unique_ptr<AravisCamera> open(const std::string& id_or_address, const AravisCameraOptions& options = {});
  // gige://<address|id|serial> or usb3://<serial|id>, with optional query keys format, width,
  // height, packet_size, buffers and trigger_line (the options above).
  static std::unique_ptr<AravisCamera> open(const DeviceUri& uri);

  ~AravisCamera() override;
  AravisCamera(const AravisCamera&) = delete;
  AravisCamera& operator=(const AravisCamera&) = delete;

  // drivers::Camera
  CameraInfo info() const override;
  // Through the SFNC ExposureTime, else ExposureTimeAbs; the value must lie in the feature's
  // bounds (kInvalidArgument) and the camera must have one of them (kUnsupported naming both).
  void set_exposure_us(double exposure_us) override;
  double exposure_us() const override;
  void set_trigger_source(TriggerSource source) override;
  void start() override;
  void stop() override;
  void software_trigger() override;
  CapturedImage wait_image(std::chrono::milliseconds timeout) override;
  // GigE Vision: the stream's packet counters (Aravis's n_resent_packets; n_missing_packets,
  // which counts per incomplete image the packets after the last one received in sequence),
  // summed over the streams of every start() since open, and the images its output queue held
  // behind the last one wait_image() returned. USB3 Vision: nullopt (no packets to count).
  std::optional<TransportStatistics> transport_statistics() const override;

  // Through the SFNC Gain (float), else GainRaw (integer: the value is rounded).
  void set_gain(double gain);
  double gain() const;
  // The input line used by TriggerSource::kHardwareLine ("Line0", "Line1", ...); applied at
  // once when the hardware line is the current source. kUnsupported lists the camera's sources.
  void set_trigger_line(const std::string& line);

  // Which GenICam feature the fallbacks chose ("" when the camera has neither).
  const std::string& exposure_feature() const;
  const std::string& gain_feature() const;
  // Any GenICam feature's current value as text (e.g. "TriggerMode" → "On"), for diagnostics.
  // kUnsupported when the camera has no such feature.
  std::string feature_value(const std::string& feature) const;
  // The negotiated GigE Vision packet size in bytes (0 for USB3 Vision).
  int packet_size() const;
  const DiscoveredCamera& device() const;
  AravisStatistics statistics() const;

 private:
  struct Impl;
  explicit AravisCamera(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace sls::drivers
