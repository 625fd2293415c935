// The camera driver interface: what the capture sequencer needs from any camera — the
// simulated one (drivers/sim), GenICam cameras through Aravis (drivers/aravis, issue #7)
// and recorded sessions (drivers/replay).
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>

#include "sdk/core/calibration.h"
#include "sdk/core/image.h"
#include "sdk/core/memory_type.h"

namespace sls::drivers {

struct CameraInfo {
  std::string uri;     // how it was opened, e.g. "sim://knurled-screw?preset=demo"
  std::string model;
  std::string serial;
  int width = 0;
  int height = 0;
  int bit_depth = 0;   // significant bits per pixel (8, 10, 12, 16)
};

enum class TriggerSource {
  kSoftware,      // software_trigger() starts an exposure
  kHardwareLine,  // an electrical trigger input (the projector's or head controller's output)
};

struct CapturedImage {
  Image16u image;             // values 0 .. 2^bit_depth − 1
  std::int64_t timestamp_ns = 0;  // device clock when the exposure started
  std::uint64_t frame_id = 0;     // the camera's own counter; gaps reveal dropped frames
  // Frames the camera counted (by frame id) since the previous image that never arrived: with
  // hardware triggers a gap means this image belongs to a later trigger than expected.
  std::uint64_t frames_missed = 0;
  // false when the transport lost part of the image (e.g. missing GigE Vision packets): the
  // sequencer must re-capture or mark the stack incomplete, never use it as if whole.
  bool complete = true;
  std::string problem;            // why it is incomplete
};

// What a camera's transport says about its stream: packets counted since the camera was opened
// (across start() / stop()), and how far behind the reader of its images is.
struct TransportStatistics {
  // Packets the camera sent again because the host asked (GigE Vision packet resend).
  std::uint64_t resent_packets = 0;
  // Packets missing from the images the transport could not complete, resend or not (Aravis
  // counts, per such image, every packet after the last one received in sequence: an upper
  // bound on those lost).
  std::uint64_t missing_packets = 0;
  // Images waiting in the stream's output queue behind the last one wait_image() returned: how
  // far behind the reader was when it took that image (0: it kept up). Not cumulative; 0
  // before the first image of an acquisition.
  std::uint64_t output_queue_depth = 0;
};

class Camera {
 public:
  virtual ~Camera() = default;

  virtual CameraInfo info() const = 0;
  virtual void set_exposure_us(double exposure_us) = 0;
  virtual double exposure_us() const = 0;
  virtual void set_trigger_source(TriggerSource source) = 0;

  // Acquisition: between start() and stop() each trigger yields one image.
  virtual void start() = 0;
  virtual void stop() = 0;
  virtual void software_trigger() = 0;
  // The next image; throws sls::Error(kTimeout) naming the camera when none arrives in time,
  // kDevice when the camera is gone.
  virtual CapturedImage wait_image(std::chrono::milliseconds timeout) = 0;

  // The transport's figures, or nullopt for a camera whose transport keeps none (the
  // simulator, recorded sessions). Cheap (no device I/O, callable after every image) and
  // never throws.
  virtual std::optional<TransportStatistics> transport_statistics() const { return std::nullopt; }

  // Where wait_image() puts its images from now on: MemoryType::kPinned for a scan fused on a
  // GPU, whose copy engine then uploads each stack without staging it (issue 18). A camera
  // that cannot honour it (a kPinned request without CUDA or a GPU) delivers pageable images;
  // CapturedImage::image.memory_type() says which. Default: kHost. Never throws.
  virtual void set_image_memory(MemoryType memory) { image_memory_ = memory; }
  MemoryType image_memory() const { return image_memory_; }

  // The exact calibration of a simulated camera (sim://): this camera with the projector it is
  // simulated with (and the turntable axis), as a simulated recording's groundtruth/ holds it,
  // so a capture through simulated devices carries its truth (issue 17). nullopt for a real
  // camera or a replayed one (their calibration is what is being measured). Never throws.
  virtual std::optional<ScannerCalibration> exact_calibration() const { return std::nullopt; }

 private:
  MemoryType image_memory_ = MemoryType::kHost;
};

}  // namespace sls::drivers
