#include "tests/hardware-free/aravis/fake_gige_camera.h"

#include <arv.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <mutex>
#include <string>
#include <vector>

#include "sdk/core/error.h"

extern char** environ;

namespace sls::test {

std::uint16_t fake_test_pattern_value(std::uint64_t frame_id, int x, int y, int bit_depth) {
  const std::uint64_t mask = (std::uint64_t{1} << bit_depth) - 1;
  const std::uint64_t value =
      frame_id * 7919u + static_cast<std::uint64_t>(x) + 131u * static_cast<std::uint64_t>(y);
  return static_cast<std::uint16_t>(value & mask);
}

Image16u fake_test_pattern(std::uint64_t frame_id, int width, int height, int bit_depth) {
  Image16u image(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) image(x, y) = fake_test_pattern_value(frame_id, x, y, bit_depth);
  }
  return image;
}

struct FakeGigeCamera::Impl {
  FakeGigeCameraOptions options;
  ArvGvFakeCamera* gv_camera = nullptr;  // owned
  ArvFakeCamera* fake = nullptr;         // owned by gv_camera

  std::mutex mutex;  // guards the members below against the fake camera's thread
  FakeImageSource source;
  std::string source_error;
  Image16u scratch;
  std::atomic<std::uint64_t> frames_sent{0};
  int burst_frames_left = 0;    // frames still to send with burst_loss_ratio
  double burst_loss_ratio = 0.0;
  double applied_loss_ratio = 0.0;  // what the fake's "gvsp-lost-ratio" is now

  Impl() = default;
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;
  ~Impl() {
    if (gv_camera != nullptr) g_object_unref(gv_camera);  // joins the fake's thread
  }

  void record_error(const std::string& message) {
    if (source_error.empty()) source_error = message;
  }

  // Called by Aravis on the fake camera's thread for each frame it is about to send.
  static void fill(ArvBuffer* buffer, void* user, guint32 exposure_us, guint32 gain, ArvPixelFormat format) {
    static_cast<Impl*>(user)->fill(buffer, exposure_us, gain, format);
  }

  void fill(ArvBuffer* buffer, guint32 exposure_us, guint32 gain, ArvPixelFormat format) {
    int bytes_per_pixel = 0;
    int bit_depth = 0;
    if (format == ARV_PIXEL_FORMAT_MONO_8) {
      bytes_per_pixel = 1;
      bit_depth = 8;
    } else if (format == ARV_PIXEL_FORMAT_MONO_12) {
      bytes_per_pixel = 2;
      bit_depth = 12;
    } else if (format == ARV_PIXEL_FORMAT_MONO_16) {
      bytes_per_pixel = 2;
      bit_depth = 16;
    }
    std::lock_guard<std::mutex> lock(mutex);
    // A burst of loss: set on this thread, the one that reads the ratio as it sends this
    // frame's packets (the property is writable at any time, but read without a lock).
    const double loss = burst_frames_left > 0 ? burst_loss_ratio : options.packet_loss_ratio;
    if (burst_frames_left > 0) --burst_frames_left;
    if (loss != applied_loss_ratio) {
      g_object_set(gv_camera, "gvsp-lost-ratio", loss, nullptr);
      applied_loss_ratio = loss;
    }
    if (bit_depth == 0) {
      record_error("the fake camera was set to a pixel format that is not Mono8/12/16");
      return;
    }
    FakeFrameRequest request;
    request.frame_id = arv_buffer_get_frame_id(buffer);
    request.width = arv_buffer_get_image_width(buffer);
    request.height = arv_buffer_get_image_height(buffer);
    request.bit_depth = bit_depth;
    request.exposure_us = exposure_us;
    request.gain_raw = gain;
    const std::size_t bytes = static_cast<std::size_t>(request.width) * static_cast<std::size_t>(request.height) *
                              static_cast<std::size_t>(bytes_per_pixel);
    // The fake allocated the buffer for its current payload (and skips this call when it does
    // not fit); its data pointer is const only in the public API.
    if (request.width <= 0 || request.height <= 0 || bytes > arv_fake_camera_get_payload(fake)) {
      record_error("frame size does not match the fake camera's payload");
      return;
    }
    auto* data = static_cast<std::uint8_t*>(const_cast<void*>(arv_buffer_get_data(buffer, nullptr)));

    if (scratch.width() != request.width || scratch.height() != request.height) {
      scratch.resize(request.width, request.height);
    }
    try {
      if (source) {
        source(request, scratch.view());
      } else {
        scratch = fake_test_pattern(request.frame_id, request.width, request.height, bit_depth);
      }
    } catch (const std::exception& error) {
      record_error(error.what());
      scratch.resize(request.width, request.height);
    } catch (...) {
      record_error("unknown exception from the image source");
      scratch.resize(request.width, request.height);
    }

    const std::uint16_t* pixels = scratch.data();
    const std::size_t count = scratch.pixel_count();
    const unsigned limit = 1u << bit_depth;
    for (std::size_t i = 0; bit_depth < 16 && i < count; ++i) {
      if (pixels[i] >= limit) {
        record_error("the image source wrote a value above 2^" + std::to_string(bit_depth) + " - 1");
        break;
      }
    }
    if (bytes_per_pixel == 1) {
      for (std::size_t i = 0; i < count; ++i) data[i] = static_cast<std::uint8_t>(pixels[i]);
    } else {
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
      std::memcpy(data, pixels, count * 2);  // GVSP pixels are little-endian, like the host's
#else
      for (std::size_t i = 0; i < count; ++i) {
        data[2 * i] = static_cast<std::uint8_t>(pixels[i] & 0xFFu);
        data[2 * i + 1] = static_cast<std::uint8_t>(pixels[i] >> 8);
      }
#endif
    }
    frames_sent.fetch_add(1);
  }
};

FakeGigeCamera::FakeGigeCamera(FakeGigeCameraOptions options) : impl_(std::make_unique<Impl>()) {
  Impl& impl = *impl_;
  impl.options = std::move(options);
  impl.source = impl.options.image_source;
  const FakeGigeCameraOptions& o = impl.options;
  if (o.serial.empty() || o.serial.size() > 15) {
    throw_error(ErrorCode::kInvalidArgument, "fake camera serial '{}' must have 1..15 characters", o.serial);
  }
  if (!(o.trigger_poll_hz > 0.0) || !(o.packet_loss_ratio >= 0.0 && o.packet_loss_ratio <= 1.0)) {
    throw_error(ErrorCode::kInvalidArgument, "fake camera: trigger poll {} Hz must be > 0, loss {} in 0..1",
                o.trigger_poll_hz, o.packet_loss_ratio);
  }
  // The loss ratio is a construction property: the fake's thread reads it without a lock.
  impl.gv_camera = static_cast<ArvGvFakeCamera*>(g_object_new(
      ARV_TYPE_GV_FAKE_CAMERA, "interface-name", o.address.c_str(), "serial-number", o.serial.c_str(),
      "genicam-filename", o.genicam_xml.empty() ? nullptr : o.genicam_xml.c_str(), "gvsp-lost-ratio",
      o.packet_loss_ratio, nullptr));
  if (impl.gv_camera == nullptr || arv_gv_fake_camera_is_running(impl.gv_camera) == FALSE) {
    throw_error(ErrorCode::kDevice,
                "fake GigE camera cannot listen on {} (no such local address, or port 3956 taken there)",
                o.address);
  }
  {
    // The fake's thread is already running and fill() reads `fake`: set it under the mutex
    // fill() takes. Aravis orders it too (the fill callback is installed below, under its own
    // GMutex), but GLib's futex locks are invisible to ThreadSanitizer, which reported this.
    std::lock_guard<std::mutex> lock(impl.mutex);
    impl.fake = arv_gv_fake_camera_get_fake_camera(impl.gv_camera);
    impl.applied_loss_ratio = o.packet_loss_ratio;
  }
  arv_fake_camera_set_trigger_frequency(impl.fake, o.trigger_poll_hz);
  arv_fake_camera_set_fill_pattern(impl.fake, &Impl::fill, &impl);
}

FakeGigeCamera::~FakeGigeCamera() = default;

const std::string& FakeGigeCamera::address() const { return impl_->options.address; }
std::string FakeGigeCamera::uri() const { return "gige://" + impl_->options.address; }
std::string FakeGigeCamera::device_id() const { return "Aravis-Fake-" + impl_->options.serial; }
const std::string& FakeGigeCamera::serial() const { return impl_->options.serial; }

void FakeGigeCamera::set_image_source(FakeImageSource source) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->source = std::move(source);
}

void FakeGigeCamera::lose_packets(double ratio, int frames) {
  if (!(ratio >= 0.0 && ratio <= 1.0) || frames < 0) {
    throw_error(ErrorCode::kInvalidArgument, "fake camera: burst loss {} must be in 0..1, frames {} >= 0", ratio,
                frames);
  }
  std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->burst_loss_ratio = ratio;
  impl_->burst_frames_left = frames;
}

std::uint64_t FakeGigeCamera::frames_sent() const { return impl_->frames_sent.load(); }

std::string FakeGigeCamera::source_error() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->source_error;
}

FakeGigeCameraProcess::FakeGigeCameraProcess(const FakeGigeCameraOptions& options) {
  if (options.image_source) {
    throw_error(ErrorCode::kInvalidArgument, "a fake camera process sends the test pattern: no image source");
  }
  int to_child[2] = {-1, -1};
  int from_child[2] = {-1, -1};
  if (pipe(to_child) != 0 || pipe(from_child) != 0) throw_error(ErrorCode::kIo, "pipe: {}", std::strerror(errno));

  std::vector<std::string> args = {SLS_FAKE_GIGE_CAMERA_EXECUTABLE, "--address", options.address, "--serial",
                                   options.serial, "--loss", std::to_string(options.packet_loss_ratio),
                                   "--trigger-hz", std::to_string(options.trigger_poll_hz)};
  if (!options.genicam_xml.empty()) {
    args.push_back("--xml");
    args.push_back(options.genicam_xml);
  }
  std::vector<char*> argv;
  for (std::string& arg : args) argv.push_back(arg.data());
  argv.push_back(nullptr);

  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, to_child[0], STDIN_FILENO);
  posix_spawn_file_actions_adddup2(&actions, from_child[1], STDOUT_FILENO);
  for (int fd : {to_child[0], to_child[1], from_child[0], from_child[1]}) posix_spawn_file_actions_addclose(&actions, fd);
  const int spawned = posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  close(to_child[0]);
  close(from_child[1]);
  stdin_fd_ = to_child[1];
  if (spawned != 0) {
    close(from_child[0]);
    close(stdin_fd_);
    stdin_fd_ = -1;
    pid_ = -1;
    throw_error(ErrorCode::kDevice, "cannot start {}: {}", args[0], std::strerror(spawned));
  }

  // The child prints one line once it listens (or dies trying).
  std::string line;
  pollfd ready{from_child[0], POLLIN, 0};
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (line.find('\n') == std::string::npos && std::chrono::steady_clock::now() < deadline) {
    if (poll(&ready, 1, 100) <= 0) continue;
    char chunk[256];
    const ssize_t got = read(from_child[0], chunk, sizeof chunk);
    if (got <= 0) break;
    line.append(chunk, static_cast<std::size_t>(got));
  }
  close(from_child[0]);
  if (line.rfind("listening", 0) != 0) {
    kill();
    throw_error(ErrorCode::kDevice, "fake camera process on {} did not start: '{}'", options.address, line);
  }
}

FakeGigeCameraProcess::~FakeGigeCameraProcess() { kill(); }

void FakeGigeCameraProcess::kill() {
  if (pid_ > 0) {
    ::kill(pid_, SIGKILL);
    int status = 0;
    waitpid(pid_, &status, 0);
    pid_ = -1;
  }
  if (stdin_fd_ >= 0) {
    close(stdin_fd_);
    stdin_fd_ = -1;
  }
}

}  // namespace sls::test
