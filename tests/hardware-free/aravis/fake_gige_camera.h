// A GigE Vision camera for hardware-free tests: Aravis's ArvGvFakeCamera listening on a
// loopback address, speaking real GVCP/GVSP over UDP, with the image of every frame produced by
// a function the test supplies (DESIGN.md section 8). The integration test plugs the simulator
// in here: the image source renders what the emulated projector currently shows.
//
// Run tests that use it in a private network namespace (tests/hardware-free/aravis/
// run_in_netns.sh: `unshare -rn`, lo up, 127.0.0.2 added) so that several fake cameras can each
// have an address and parallel test runs do not share UDP port 3956. Aravis types stay in the
// .cpp: this header is plain C++.
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "sdk/core/image.h"

namespace sls::test {

// What the fake camera is about to send.
struct FakeFrameRequest {
  std::uint64_t frame_id = 0;    // the id the receiving driver sees (the GigE Vision block id)
  int width = 0;
  int height = 0;
  int bit_depth = 0;             // 8 (Mono8), 12 (Mono12) or 16 (Mono16): values must fit
  std::uint32_t exposure_us = 0; // the camera's exposure register, as the driver set it
  std::uint32_t gain_raw = 0;    // the camera's raw gain register
};

// Writes the frame's pixels into `pixels` (width × height; it still holds the previous frame's
// pixels, so write every one). Runs on the fake camera's own thread, not the test's: guard
// shared state. An exception it throws is caught, the frame goes out black and
// FakeGigeCamera::source_error() tells what happened.
using FakeImageSource = std::function<void(const FakeFrameRequest& request, ImageView<std::uint16_t> pixels)>;

// The default image: every pixel and every frame differ, so a stale or misplaced packet shows.
std::uint16_t fake_test_pattern_value(std::uint64_t frame_id, int x, int y, int bit_depth);
Image16u fake_test_pattern(std::uint64_t frame_id, int width, int height, int bit_depth);

struct FakeGigeCameraOptions {
  std::string address = "127.0.0.1";  // an IPv4 address of a local interface
  std::string serial = "SLS-FAKE-01"; // at most 15 characters (GigE Vision bootstrap field)
  std::string genicam_xml;            // path of a GenICam description; empty: Aravis's built-in one
  // How often the fake looks for a software trigger. Aravis's default, 25 Hz, delays every
  // triggered frame by up to 40 ms.
  double trigger_poll_hz = 1000.0;
  // Fraction of GVSP packets the fake drops, never resent: ArvGvFakeCamera's "gvsp-lost-ratio"
  // property, the in-process form of `arv-fake-gv-camera-0.8 -r`.
  double packet_loss_ratio = 0.0;
  FakeImageSource image_source;       // empty: fake_test_pattern
};

class FakeGigeCamera {
 public:
  // Starts listening; throws sls::Error(kDevice) when the address cannot be bound (no such
  // local address, or another camera already listens there).
  explicit FakeGigeCamera(FakeGigeCameraOptions options = {});
  // Stops the fake: a driver still connected sees the camera vanish.
  ~FakeGigeCamera();
  FakeGigeCamera(const FakeGigeCamera&) = delete;
  FakeGigeCamera& operator=(const FakeGigeCamera&) = delete;

  const std::string& address() const;
  std::string uri() const;        // gige://<address>
  std::string device_id() const;  // Aravis's id for it: Aravis-Fake-<serial>
  const std::string& serial() const;

  void set_image_source(FakeImageSource source);
  // A burst of loss: the next `frames` frames sent lose this fraction of their GVSP packets
  // (1.0: all, the frames never arrive), then the loss is packet_loss_ratio again.
  void lose_packets(double ratio, int frames);
  std::uint64_t frames_sent() const;
  std::string source_error() const;  // the first exception of the image source, "" if none

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The same fake camera in a child process (tests/hardware-free/aravis/fake_gige_camera_main.cpp),
// for a camera that disappears without a goodbye: kill() sends SIGKILL.
class FakeGigeCameraProcess {
 public:
  // Starts the child and waits until it listens; throws sls::Error(kDevice) when it does not.
  explicit FakeGigeCameraProcess(const FakeGigeCameraOptions& options);
  ~FakeGigeCameraProcess();  // kills the child if still running
  FakeGigeCameraProcess(const FakeGigeCameraProcess&) = delete;
  FakeGigeCameraProcess& operator=(const FakeGigeCameraProcess&) = delete;

  void kill();
  pid_t pid() const { return pid_; }

 private:
  pid_t pid_ = -1;
  int stdin_fd_ = -1;  // the child exits when this closes
};

}  // namespace sls::test
