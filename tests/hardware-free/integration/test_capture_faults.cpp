// Issue 19's fault-injection suite, through the real stacks (test_scan_through_real_stacks.cpp
// has the bench: the DLPC350 and head-controller drivers over libusb to the emulated firmware,
// the Aravis driver over GigE Vision to a fake camera rendering the simulator). Each fault must
// end the capture with a clear error naming the device or file, keep the frames captured
// before (RecordingReader::open + verify), and leave a recording that a resumed capture
// (RecordingWriter::append_to, CaptureOptions::first_frame) completes to the uninterrupted one.
//   - a turntable that never finishes its move (the board answers, its clock stands still);
//   - a turntable whose motor stalls (the board reports MOTOR_STALL);
//   - a full disk while a frame's images are written, and while its manifest is written.
//   - bursts of lost GVSP packets, shorter and longer than the retries;
//   - a projector that falls silent, resumed once it answers;
//   - kill -9 of the capturing process during a turntable move, mid-stack, after a frame's first
//     image is written, mid-frame and at the manifest (the capture runs in a child process: this
//     executable again, its test CaptureKilledChild.*; the parent kills it and resumes).
// Camera gone, projector and controller stalled or silent, and random packet loss are in
// test_scan_through_real_stacks.cpp.
//
// Runs under run_in_netns.sh (a user namespace) and umockdev-wrapper; the disk-full cases mount
// a small tmpfs in a private mount namespace taken before main(), and skip where that fails.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <sched.h>
#include <signal.h>
#include <spawn.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <mutex>
#include <ostream>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "drivers/aravis/aravis_camera.h"
#include "drivers/dlpc350/dlpc350_projector.h"
#include "drivers/headctl/head_controller.h"
#include "drivers/sim/renderer.h"
#include "drivers/sim/sim_recording.h"
#include "sdk/core/recording.h"
#include "sdk/session/capture_sequencer.h"
#include "tests/hardware-free/aravis/fake_gige_camera.h"
#include "tests/hardware-free/usb_test_bench.h"
#include "tests/support/test_support.h"

namespace sls::test {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

constexpr int kFrames = 4;         // turntable positions: 0, 90, 180, 270 degrees
constexpr int kCameraWidth = 96;   // small images keep the suite short
const milliseconds kUsbCommandTimeout(300);
constexpr const char* kTurntableName = "turntable: head controller 1209:5ca1 on bus 1 address 3";

// A private mount namespace for the whole process, taken before main() while it has one thread
// (a mount namespace is per thread; threads started later inherit it). Empty when it worked.
const std::string& mount_namespace_error() {
  static const std::string error = [] {
    if (::unshare(CLONE_NEWNS) != 0) return std::string("unshare(CLONE_NEWNS): ") + std::strerror(errno);
    if (::mount(nullptr, "/", nullptr, MS_REC | MS_PRIVATE, nullptr) != 0) {
      return std::string("making / private: ") + std::strerror(errno);
    }
    return std::string();
  }();
  return error;
}
const bool kMountNamespaceTaken = mount_namespace_error().empty();

sim::RigOptions rig_options() {
  sim::RigOptions options;
  options.preset = "ci";
  options.frames = kFrames;
  options.camera_width = kCameraWidth;
  return options;
}

// A device clock that can stand still: a stepper that never reaches its target while the board
// still answers every command. Thawed, it goes on from where it stopped.
class FreezableClock {
 public:
  std::int64_t now() {
    std::function<void()> read_while_frozen;
    std::int64_t value = 0;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      value = frozen_ ? frozen_at_ : steady() - offset_;
      if (frozen_) read_while_frozen = std::move(read_while_frozen_);
      read_while_frozen_ = nullptr;
    }
    if (read_while_frozen) read_while_frozen();
    return value;
  }
  // `read_while_frozen`: called once, the first time the board reads the frozen clock (the move
  // that will never end has begun).
  void freeze(std::function<void()> read_while_frozen = {}) {
    std::lock_guard<std::mutex> lock(mutex_);
    frozen_at_ = steady() - offset_;
    frozen_ = true;
    read_while_frozen_ = std::move(read_while_frozen);
  }
  void thaw() {
    std::lock_guard<std::mutex> lock(mutex_);
    offset_ = steady() - frozen_at_;
    frozen_ = false;
  }

 private:
  static std::int64_t steady() {
    return std::chrono::duration_cast<std::chrono::microseconds>(Clock::now().time_since_epoch()).count();
  }
  std::mutex mutex_;
  bool frozen_ = false;
  std::int64_t frozen_at_ = 0;
  std::int64_t offset_ = 0;
  std::function<void()> read_while_frozen_;
};

// What the fake camera sees: the simulator's image of the pattern on the emulated DMD at the
// frame the emulated turntable stands at (as in test_scan_through_real_stacks.cpp).
class SimulatedView {
 public:
  SimulatedView(std::shared_ptr<fwif::models::Dlpc350Model> projector,
                std::shared_ptr<fwif::models::HeadctlModel> head)
      : projector_(std::move(projector)),
        head_(std::move(head)),
        scene_(sim::make_scene("knurled-screw")),
        renderer_(sim::make_rig(rig_options(), scene_), scene_, Device::cpu()) {}

  // Called with the frame and pattern (-1: dark) of each image the camera takes, on its thread.
  void observe(std::function<void(int frame, int pattern)> observer) {
    std::lock_guard<std::mutex> lock(mutex_);
    observer_ = std::move(observer);
  }

  void render(const FakeFrameRequest& request, ImageView<std::uint16_t> pixels) {
    std::lock_guard<std::mutex> lock(mutex_);
    const fwif::headctl::TurntableStatusReply table = head_->turntable();
    const double turns = static_cast<double>(table.position_step) / table.steps_per_revolution;
    const int frame = static_cast<int>(std::lround(turns * kFrames) % kFrames);
    if (renderer_.frame() != frame) renderer_.set_frame(frame);
    const std::optional<fwif::models::DisplayedPattern> shown = projector_->displayed_pattern();
    const int pattern = shown ? drivers::dlpc350_pattern_index({shown->flash_image, shown->pattern_number}, 0) : -1;
    if (observer_) observer_(frame, pattern);
    Image16u image;
    if (pattern >= 0) {
      image = renderer_.render_pattern(pattern);
    } else {
      PatternDesc dark;
      dark.kind = PatternKind::kBlack;
      image = renderer_.render(dark, 1000);
    }
    if (image.width() != request.width || image.height() != request.height) {
      throw_error(ErrorCode::kInternal, "simulated {}x{} image for a {}x{} camera", image.width(), image.height(),
                  request.width, request.height);
    }
    for (int y = 0; y < pixels.height; ++y) {
      for (int x = 0; x < pixels.width; ++x) pixels(x, y) = image(x, y);
    }
  }

 private:
  std::shared_ptr<fwif::models::Dlpc350Model> projector_;
  std::shared_ptr<fwif::models::HeadctlModel> head_;
  std::mutex mutex_;
  sim::Scene scene_;
  sim::Renderer renderer_;
  std::function<void(int frame, int pattern)> observer_;
};

// The child process of CaptureKilled: how the parent starts it, and what the child reads.
constexpr const char* kChildMomentVariable = "SLS_KILLED_CAPTURE_MOMENT";
constexpr const char* kChildFolderVariable = "SLS_KILLED_CAPTURE_FOLDER";
constexpr int kToParentFd = 200;    // the child writes: '1' frame 1 recorded, 'K' kill me now
constexpr int kFromParentFd = 201;  // the parent writes '1': go on past frame 1

class CaptureFaults : public UsbDevicesTest {
 protected:
  static void SetUpTestSuite() {
    if (std::getenv("SLS_TEST_NETNS") == nullptr || std::getenv(kChildMomentVariable) != nullptr) return;
    direct_dir_ = new TemporaryDirectory();
    sim::SimRecordingOptions options;
    options.rig = rig_options();
    options.reference_spacing_m = 2e-3;
    sim::write_sim_recording(direct_dir_->file("direct"), options, Device::cpu(), {});
  }
  static void TearDownTestSuite() {
    delete direct_dir_;
    direct_dir_ = nullptr;
  }

  void SetUp() override {
    if (std::getenv("SLS_TEST_NETNS") == nullptr) {
      GTEST_SKIP() << "needs a private network namespace: run through run_in_netns.sh (unshare -rn)";
    }
  }

  static std::string direct_folder() { return direct_dir_->file("direct"); }

  // The bench of test_scan_through_real_stacks.cpp, with the head controller on `clock_`, and a
  // new recording for it.
  void start_scanner(const std::string& recording_folder) {
    open_scanner();
    if (HasFatalFailure()) return;
    recording_ = recording_folder;
    writer_ = std::make_unique<RecordingWriter>(RecordingWriter::create(
        recording_, session::make_recording_info(*projector_, *camera_, rig_->patterns), rig_->calibration(),
        writer_options()));
  }

  // The bench alone: the emulated devices plugged, the fake camera started, the drivers open.
  void open_scanner() {
    ASSERT_TRUE(fwif::models::umockdev_preload_active()) << "run under umockdev-wrapper";
    bus_ = std::make_unique<fwif::models::EmulatedUsbBus>();
    projector_model_ = std::make_shared<fwif::models::Dlpc350Model>();
    fwif::models::HeadctlModelOptions head;
    head.default_speed_steps_per_s = 64000;  // 90 degrees in 25 ms
    head_model_ = std::make_shared<fwif::models::HeadctlModel>(head, [clock = clock_] { return clock->now(); });
    bus_->plug(projector_model_, 1, 2);
    bus_->plug(head_model_, 1, 3);

    view_ = std::make_shared<SimulatedView>(projector_model_, head_model_);
    FakeGigeCameraOptions camera_options;
    camera_options.serial = "SLS-SIM-CAM";
    camera_options.image_source = [view = view_](const FakeFrameRequest& request, ImageView<std::uint16_t> pixels) {
      view->render(request, pixels);
    };
    fake_camera_ = std::make_unique<FakeGigeCamera>(camera_options);

    drivers::Dlpc350Options projector_options;
    projector_options.retry = {kUsbCommandTimeout, 3};
    projector_ = drivers::Dlpc350Projector::open("dlpc350://", projector_options);
    drivers::HeadControllerOptions head_options;
    head_options.retry = {kUsbCommandTimeout, 3};
    turntable_ = drivers::HeadController::open("headctl://", head_options);
    drivers::AravisCameraOptions aravis;
    aravis.pixel_format = "Mono16";
    aravis.width = kCameraWidth;
    aravis.height = kCameraWidth * 3 / 4;
    camera_ = drivers::AravisCamera::open(fake_camera_->address(), aravis);

    const sim::Scene scene = sim::make_scene("knurled-screw");
    rig_ = std::make_unique<sim::SimRig>(sim::make_rig(rig_options(), scene));
  }

  static RecordingWriterOptions writer_options() {
    RecordingWriterOptions options;
    options.sync = false;       // tmpfs or scratch: nothing to flush
    options.encode_threads = 1;  // images written in order: the disk fills at the image the case says
    return options;
  }

  session::CaptureOptions capture_options(int first_frame = 0) const {
    session::CaptureOptions options;
    options.frames_per_revolution = kFrames;
    options.first_frame = first_frame;
    options.image_timeout = milliseconds(1000);
    options.turntable_timeout = milliseconds(1000);
    // Each frame written before on_frame sees it (no writer thread): the faults below are
    // injected once frame 1 is on disk, at a known point of frame 2's writing. The writer
    // thread's own faults: RecordingWriterThread.*, and `sls scan` on a full disk (cli).
    options.write_queue_frames = 0;
    return options;
  }

  // Runs the capture; `after_frame_one` injects the fault once frame 1 is recorded. Returns
  // the error's message (a test failure when there is none or it has another code).
  std::string capture_with_fault(const std::function<void()>& after_frame_one, ErrorCode expected) {
    session::CaptureSequencer scan(*projector_, {camera_.get()}, turntable_.get(), rig_->patterns, capture_options());
    const auto on_frame = [&](const session::CapturedFrame& frame) {
      if (frame.index == 1) after_frame_one();
    };
    const std::string message = error_message([&] { scan.run({writer_.get()}, on_frame); }, expected);
    writer_.reset();
    return message;
  }

  // The frames captured before the fault are listed, whole and readable; the capture resumed
  // (a new writer and sequencer, the same devices) completes the recording, every image the
  // simulator's.
  void expect_kept_and_resumable(std::size_t kept) {
    {
      const RecordingReader partial = RecordingReader::open(recording_);
      partial.verify(true);
      ASSERT_EQ(partial.frame_count(), kept);
      for (std::size_t f = 0; f < kept; ++f) EXPECT_TRUE(partial.frame(f).complete) << "frame " << f;
    }
    RecordingWriter writer = RecordingWriter::append_to(recording_, writer_options());
    ASSERT_EQ(writer.frame_count(), kept);
    session::CaptureSequencer resumed(*projector_, {camera_.get()}, turntable_.get(), rig_->patterns,
                                      capture_options(static_cast<int>(kept)));
    const session::CaptureStatistics stats = resumed.run({&writer});
    EXPECT_EQ(stats.frames, kFrames - static_cast<int>(kept));
    writer.close();

    const RecordingReader scanned = RecordingReader::open(recording_);
    scanned.verify(true);
    const RecordingReader direct = RecordingReader::open(direct_folder());
    ASSERT_EQ(scanned.frame_count(), static_cast<std::size_t>(kFrames));
    for (std::size_t f = 0; f < scanned.frame_count(); ++f) {
      EXPECT_EQ(scanned.frame(f).index, static_cast<int>(f));
      EXPECT_TRUE(scanned.frame(f).complete) << "frame " << f << ": " << scanned.frame(f).note;
      EXPECT_EQ(scanned.frame(f).turntable_angle_deg, direct.frame(f).turntable_angle_deg) << "frame " << f;
      const std::vector<Image16u> ours = scanned.load_images(f);
      const std::vector<Image16u> theirs = direct.load_images(f);
      ASSERT_EQ(ours.size(), theirs.size()) << "frame " << f;
      for (std::size_t k = 0; k < ours.size(); ++k) {
        EXPECT_TRUE(ours[k] == theirs[k]) << "frame " << f << " pattern " << k << " differs from the simulator's";
      }
    }
    EXPECT_EQ(fake_camera_->source_error(), "");
  }

  static TemporaryDirectory* direct_dir_;
  TemporaryDirectory dir_;
  std::shared_ptr<FreezableClock> clock_ = std::make_shared<FreezableClock>();
  std::shared_ptr<SimulatedView> view_;
  std::unique_ptr<FakeGigeCamera> fake_camera_;
  std::unique_ptr<drivers::Dlpc350Projector> projector_;
  std::unique_ptr<drivers::HeadController> turntable_;
  std::unique_ptr<drivers::AravisCamera> camera_;
  std::unique_ptr<sim::SimRig> rig_;
  std::string recording_;
  std::unique_ptr<RecordingWriter> writer_;
};

TemporaryDirectory* CaptureFaults::direct_dir_ = nullptr;

// The board answers every command, but the table never gets to 180 degrees: the move times out
// within the turntable timeout, named, and the table is told to stop.
TEST_F(CaptureFaults, ATurntableThatNeverArrivesTimesOutNamedAndTheCaptureResumes) {
  start_scanner(dir_.file("scan"));
  Clock::time_point stuck_at{};
  const std::string message = capture_with_fault(
      [&] {
        clock_->freeze();
        stuck_at = Clock::now();
      },
      ErrorCode::kTimeout);
  const double latency_ms = elapsed_ms(stuck_at);
  std::printf("[ measured ] stuck turntable: kTimeout after %.0f ms (turntable timeout 1000 ms)\n", latency_ms);
  EXPECT_GE(latency_ms, 1000.0);
  EXPECT_LT(latency_ms, 1000.0 + 1500.0);
  EXPECT_NE(message.find("capture frame 2 of 4 (turntable at 90.000 deg), moving to 180.000 deg"), std::string::npos)
      << message;
  EXPECT_NE(message.find(kTurntableName), std::string::npos) << message;
  EXPECT_NE(message.find("moving to 180.000 deg (step 3200) not done within 1000 ms"), std::string::npos) << message;
  EXPECT_EQ(head_model_->turntable().state, fwif::headctl::TurntableState::kIdle) << "the driver stopped the table";
  EXPECT_FALSE(projector_model_->displayed_pattern().has_value()) << "the projector went dark";
  clock_->thaw();  // the mechanism freed: the same devices resume the capture
  expect_kept_and_resumable(2);
}

// The motor stalls on the way to 180 degrees and the board says so: a device error naming the
// turntable and the board's MOTOR_STALL, at once rather than after the timeout.
TEST_F(CaptureFaults, AStalledTurntableMotorIsNamedAndTheCaptureResumes) {
  start_scanner(dir_.file("scan"));
  const auto start = Clock::now();
  const std::string message =
      capture_with_fault([&] { head_model_->stall_next_move_after(100); }, ErrorCode::kDevice);
  EXPECT_NE(message.find(kTurntableName), std::string::npos) << message;
  EXPECT_NE(message.find("MOTOR_STALL"), std::string::npos) << message;
  EXPECT_NE(message.find("moving to 180.000 deg"), std::string::npos) << message;
  EXPECT_LT(elapsed_ms(start), 30000.0);
  expect_kept_and_resumable(2);
}

// The projector stops answering (a hung DLPC350): named, within its USB budget; once it answers
// again the same devices resume the capture (test_scan_through_real_stacks.cpp's DeviceFailure
// checks the message and the frames kept, not the resume).
TEST_F(CaptureFaults, ASilentProjectorIsNamedAndTheCaptureResumesWhenItAnswers) {
  start_scanner(dir_.file("scan"));
  const std::string message = capture_with_fault(
      [&] { projector_model_->set_behaviour(fwif::models::Behaviour::kSilent); }, ErrorCode::kTimeout);
  EXPECT_NE(message.find("capture frame 2 of 4"), std::string::npos) << message;
  EXPECT_NE(message.find("projector dlpc350://1:2: DLPC350 0451:6401 on bus 1 address 2"), std::string::npos)
      << message;
  EXPECT_NE(message.find("gave no reply"), std::string::npos) << message;
  projector_model_->set_behaviour(fwif::models::Behaviour::kNormal);
  expect_kept_and_resumable(2);
}

// A burst of lost packets while frame 2 is taken, shorter than the retries: the frame is
// re-captured, counted, and the recording holds the simulator's images only.
TEST_F(CaptureFaults, ABurstOfLostPacketsIsRecapturedAndCounted) {
  start_scanner(dir_.file("scan"));
  session::CaptureOptions options = capture_options();
  options.image_timeout = milliseconds(300);
  options.max_retries = 3;
  session::CaptureSequencer scan(*projector_, {camera_.get()}, turntable_.get(), rig_->patterns, options);
  // Every packet of the next 3 frames lost: the first 3 attempts at frame 2 see their first
  // image never arrive, the fourth gets the whole stack.
  const session::CaptureStatistics stats = scan.run({writer_.get()}, [&](const session::CapturedFrame& frame) {
    if (frame.index == 1) fake_camera_->lose_packets(1.0, 3);
  });
  std::printf("[ measured ] burst of 3 lost frames: %d re-captures, %d lost images, %d incomplete frames\n",
              stats.retries, stats.lost_images, stats.incomplete_frames);
  EXPECT_EQ(stats.frames, kFrames);
  EXPECT_EQ(stats.retries, 3);
  EXPECT_EQ(stats.lost_images, 3);
  EXPECT_EQ(stats.incomplete_frames, 0);
  writer_.reset();
  const RecordingReader scanned = RecordingReader::open(recording_);
  ASSERT_EQ(scanned.frame_count(), static_cast<std::size_t>(kFrames));
  EXPECT_NE(scanned.frame(2).note.find("re-captured 3 time(s); first problem: camera gige://127.0.0.1"),
            std::string::npos)
      << scanned.frame(2).note;
  EXPECT_NE(scanned.frame(2).note.find("sent no image for pattern 0 within 300 ms"), std::string::npos)
      << scanned.frame(2).note;
  expect_kept_and_resumable(kFrames);  // nothing left to capture: the resumed run adds nothing
}

// A burst longer than the retries, every packet lost: no attempt at frame 2 gets an image, so
// the camera is taken for gone — named, the frames before kept — and the capture resumes once
// the link is back. It found a bug: the failed run leaves the silent camera acquiring (cleanup
// spares the failed device), and the resumed run's start() kept that stream, whose late images
// then filed every image one pattern late in about half the runs; start() now begins afresh.
TEST_F(CaptureFaults, ABurstLongerThanTheRetriesIsNamedAndTheCaptureResumes) {
  start_scanner(dir_.file("scan"));
  session::CaptureOptions options = capture_options();
  options.image_timeout = milliseconds(300);
  options.max_retries = 1;
  session::CaptureSequencer scan(*projector_, {camera_.get()}, turntable_.get(), rig_->patterns, options);
  const std::string message = error_message(
      [&] {
        scan.run({writer_.get()}, [&](const session::CapturedFrame& frame) {
          if (frame.index == 1) fake_camera_->lose_packets(1.0, 2);
        });
      },
      ErrorCode::kTimeout);
  writer_.reset();
  EXPECT_NE(message.find("capture frame 2 of 4 (turntable at 180.000 deg), pattern 0 of 22, no image in any of 2 "
                         "attempt(s): camera gige://127.0.0.1"),
            std::string::npos)
      << message;
  EXPECT_NE(message.find("SLS-SIM-CAM"), std::string::npos) << message;
  expect_kept_and_resumable(2);
}

// Where the disk fills up while frame 2 is written: the byte budget left free after frame 1.
struct DiskFull {
  const char* name;
  int images_that_fit;   // of frame 2's images; all of them: the manifest is what fails
  const char* file_in_message;
};

void PrintTo(const DiskFull& full, std::ostream* out) { *out << full.name; }

class CaptureOnAFullDisk : public CaptureFaults, public ::testing::WithParamInterface<DiskFull> {
 protected:
  void SetUp() override {
    CaptureFaults::SetUp();
    if (IsSkipped()) return;
    if (!kMountNamespaceTaken) GTEST_SKIP() << "no private mount namespace: " << mount_namespace_error();
    mount_point_ = dir_.file("small-disk");
    fs::create_directories(mount_point_);
    if (::mount("tmpfs", mount_point_.c_str(), "tmpfs", 0, "size=4m") != 0) {
      GTEST_SKIP() << "cannot mount a tmpfs here: " << std::strerror(errno);
    }
    mounted_ = true;
  }
  void TearDown() override {
    if (mounted_) ::umount2(mount_point_.c_str(), MNT_DETACH);
  }

  // Fills the disk so that `bytes` stay free (rounded down to its blocks).
  void leave_free(std::uintmax_t bytes) {
    struct statvfs st {};
    ASSERT_EQ(::statvfs(mount_point_.c_str(), &st), 0);
    const std::uintmax_t block = st.f_frsize;
    const std::uintmax_t keep_blocks = bytes / block;
    ASSERT_GE(st.f_bavail, keep_blocks) << "the tmpfs is too small for the case";
    const std::uintmax_t filler = (st.f_bavail - keep_blocks) * block;
    std::ofstream out(mount_point_ + "/filler", std::ios::binary);
    const std::vector<char> chunk(block, 'x');
    for (std::uintmax_t written = 0; written < filler; written += block) out.write(chunk.data(), static_cast<std::streamsize>(block));
    out.close();
    ASSERT_TRUE(out) << "writing the filler";
    ASSERT_EQ(::statvfs(mount_point_.c_str(), &st), 0);
    ASSERT_EQ(st.f_bavail, keep_blocks);
  }

  std::string mount_point_;
  bool mounted_ = false;
};

TEST_P(CaptureOnAFullDisk, StopsWithTheFileAndNoSpaceNamedKeepsTheFramesAndResumes) {
  const DiskFull full = GetParam();
  start_scanner(mount_point_ + "/scan");
  // Frame 2's image files as the capture writes them: byte for byte the simulator's (the images
  // are identical, PNG encoding deterministic), so the budget lands where the case says.
  std::uintmax_t budget = 0;
  const RecordingReader direct = RecordingReader::open(direct_folder());
  const std::size_t block = 4096;
  for (int k = 0; k < full.images_that_fit; ++k) {
    const std::uintmax_t size = fs::file_size(direct.file_path(direct.frame(2).image_files[static_cast<std::size_t>(k)]));
    budget += (size + block - 1) / block * block;
  }
  const std::string message = capture_with_fault([&] { leave_free(budget); }, ErrorCode::kIo);
  // The recording's writer names the frame and the folder (recording_writer_thread.h).
  EXPECT_NE(message.find("writing frame 2 to the recording " + mount_point_ + "/scan"), std::string::npos) << message;
  EXPECT_NE(message.find(full.file_in_message), std::string::npos) << message;
  EXPECT_NE(message.find("No space left on device"), std::string::npos) << message;
  EXPECT_FALSE(projector_model_->displayed_pattern().has_value()) << "the projector went dark";
  fs::remove(mount_point_ + "/filler");  // space freed: the capture goes on where it stopped
  expect_kept_and_resumable(2);
}

INSTANTIATE_TEST_SUITE_P(
    EachStage, CaptureOnAFullDisk,
    ::testing::Values(DiskFull{"at_the_first_image", 0, "frames/000002/pattern_000.png"},
                      DiskFull{"mid_frame", 10, "frames/000002/pattern_010.png"},
                      DiskFull{"at_the_manifest", 22, "manifest.json.tmp-"}),
    [](const ::testing::TestParamInfo<DiskFull>& param) { return std::string(param.param.name); });

// kill -9 of a process capturing through the real stacks, at each stage of a frame: the frames
// recorded before stay listed and whole, and the capture resumed (in this process, with its own
// devices) completes the recording to the simulator's. The capture runs in a child process
// (this executable again, running CaptureKilledChild.* alone: forking this one would copy
// Aravis' and GLib's threads' locks mid-use); it reports over a pipe, and the parent kills it:
//   - during_a_turntable_move: once the board reads its clock, frozen, for the move to 180°;
//   - mid_stack: while the camera takes frame 2's pattern 10 (nothing of frame 2 written);
//   - after_the_first_image: frame 2's first image written, the second being opened;
//   - mid_frame: frame 2's images 0-9 written, the 11th being opened;
//   - at_the_manifest: every image of frame 2 written, the manifest listing it being opened.
// The last three wait on a FIFO put where the child is about to write (its open() waits for a
// reader, which never comes): the parent sees it wait there, kills it, and removes the FIFO.
struct KillMoment {
  const char* name;
  const char* fifo;  // relative to the recording; "manifest" for manifest.json.tmp-PID; null: the child says when
};

void PrintTo(const KillMoment& moment, std::ostream* out) { *out << moment.name; }

// Whether a thread of `pid` waits in open() of the FIFO `path` for a reader: the kernel's
// wait_for_partner, or (where /proc hides wait channels) an openat() of that path.
bool waits_to_open(pid_t pid, const std::string& path) {
  std::error_code error;
  for (const fs::directory_entry& task : fs::directory_iterator(fmt::format("/proc/{}/task", pid), error)) {
    std::string wchan, call;
    std::getline(std::ifstream(task.path() / "wchan"), wchan);
    if (wchan == "wait_for_partner") return true;
    std::ifstream(task.path() / "syscall") >> call;
    if (call != std::to_string(SYS_openat)) continue;
    std::string directory, address;
    std::ifstream(task.path() / "syscall") >> call >> directory >> address;
    const int memory = ::open(fmt::format("/proc/{}/mem", pid).c_str(), O_RDONLY | O_CLOEXEC);
    if (memory < 0) continue;
    std::string name(path.size() + 1, '\0');
    const ssize_t n = ::pread(memory, name.data(), name.size(), static_cast<off_t>(std::stoull(address, nullptr, 16)));
    ::close(memory);
    if (n == static_cast<ssize_t>(name.size()) && name == path + '\0') return true;
  }
  return false;
}

class CaptureKilled : public CaptureFaults, public ::testing::WithParamInterface<KillMoment> {
 protected:
  void TearDown() override {
    if (child_ > 0) {
      ::kill(child_, SIGKILL);
      ::waitpid(child_, nullptr, 0);
    }
    for (const int fd : {to_child_, from_child_}) {
      if (fd >= 0) ::close(fd);
    }
  }

  // Starts this executable running CaptureKilledChild.* into `folder`, with the pipes to it.
  void start_child(const std::string& moment, const std::string& folder) {
    int to_parent[2], from_parent[2];
    ASSERT_EQ(::pipe2(to_parent, O_CLOEXEC), 0);
    ASSERT_EQ(::pipe2(from_parent, O_CLOEXEC), 0);
    posix_spawn_file_actions_t actions;
    ::posix_spawn_file_actions_init(&actions);
    ::posix_spawn_file_actions_adddup2(&actions, to_parent[1], kToParentFd);
    ::posix_spawn_file_actions_adddup2(&actions, from_parent[0], kFromParentFd);
    std::vector<std::string> environment{std::string(kChildMomentVariable) + "=" + moment,
                                         std::string(kChildFolderVariable) + "=" + folder};
    for (char** variable = environ; *variable != nullptr; ++variable) environment.emplace_back(*variable);
    std::vector<char*> envp;
    for (std::string& variable : environment) envp.push_back(variable.data());
    envp.push_back(nullptr);
    std::string self = fs::read_symlink("/proc/self/exe").string();
    std::string filter = "--gtest_filter=CaptureKilledChild.*";
    char* argv[] = {self.data(), filter.data(), nullptr};
    const int spawned = ::posix_spawn(&child_, self.c_str(), &actions, nullptr, argv, envp.data());
    ::posix_spawn_file_actions_destroy(&actions);
    ::close(to_parent[1]);
    ::close(from_parent[0]);
    from_child_ = to_parent[0];
    to_child_ = from_parent[1];
    ASSERT_EQ(spawned, 0) << std::strerror(spawned);
  }

  // The child's next word, within a minute; fails the test when it ended or stayed silent.
  void expect_from_child(char expected) {
    pollfd ready{from_child_, POLLIN, 0};
    ASSERT_EQ(::poll(&ready, 1, 60000), 1) << "the child said nothing within a minute";
    char word = 0;
    ASSERT_EQ(::read(from_child_, &word, 1), 1) << "the child ended before saying '" << expected << "'";
    ASSERT_EQ(word, expected);
  }

  void kill_child() {
    ASSERT_EQ(::kill(child_, SIGKILL), 0);
    int status = 0;
    ASSERT_EQ(::waitpid(child_, &status, 0), child_);
    child_ = -1;
    ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "the child ended before the kill: " << status;
  }

  pid_t child_ = -1;
  int from_child_ = -1;
  int to_child_ = -1;
};

TEST_P(CaptureKilled, ListsTheFramesRecordedBeforeWholeAndResumesToTheSimulatorsRecording) {
  const KillMoment moment = GetParam();
  const std::string folder = dir_.file("scan");
  start_child(moment.name, folder);
  ASSERT_FALSE(HasFatalFailure());
  expect_from_child('1');  // frame 1 recorded; the child waits
  ASSERT_FALSE(HasFatalFailure());
  std::string fifo;
  if (moment.fifo != nullptr) {
    fifo = std::string(moment.fifo) == "manifest" ? fmt::format("{}/manifest.json.tmp-{}", folder, child_)
                                                  : folder + "/" + moment.fifo;
    fs::create_directories(fs::path(fifo).parent_path());
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0644), 0) << std::strerror(errno);
  }
  ASSERT_EQ(::write(to_child_, "1", 1), 1);
  if (moment.fifo == nullptr) {
    expect_from_child('K');
    ASSERT_FALSE(HasFatalFailure());
  } else {
    const auto start = Clock::now();
    while (!waits_to_open(child_, fifo)) {
      ASSERT_EQ(::waitpid(child_, nullptr, WNOHANG), 0) << "the child ended without opening " << fifo;
      ASSERT_LT(elapsed_ms(start), 60000.0) << "the child did not open " << fifo << " within a minute";
      std::this_thread::sleep_for(milliseconds(2));
    }
  }
  kill_child();
  ASSERT_FALSE(HasFatalFailure());
  if (!fifo.empty()) fs::remove(fifo);  // ours: the recording is left as the kill left it

  // Frame 2's files written before the kill lie there unlisted.
  const std::string frame_two = folder + "/frames/000002";
  const std::string name = moment.name;
  EXPECT_EQ(fs::exists(frame_two + "/pattern_000.png"), name != "during_a_turntable_move" && name != "mid_stack");
  EXPECT_EQ(fs::exists(frame_two + "/pattern_009.png"), name == "mid_frame" || name == "at_the_manifest");
  EXPECT_EQ(fs::exists(frame_two + "/pattern_021.png"), name == "at_the_manifest");
  open_scanner();  // this process's own devices: the child's went with it
  ASSERT_FALSE(HasFatalFailure());
  recording_ = folder;
  expect_kept_and_resumable(2);
}

INSTANTIATE_TEST_SUITE_P(EachMoment, CaptureKilled,
                         ::testing::Values(KillMoment{"during_a_turntable_move", nullptr},
                                           KillMoment{"mid_stack", nullptr},
                                           KillMoment{"after_the_first_image", "frames/000002/pattern_001.png"},
                                           KillMoment{"mid_frame", "frames/000002/pattern_010.png"},
                                           KillMoment{"at_the_manifest", "manifest"}),
                         [](const ::testing::TestParamInfo<KillMoment>& param) { return std::string(param.param.name); });

// The child of CaptureKilled (skipped when run otherwise): captures into the folder it is given
// and reports over its pipes; it never ends by itself.
class CaptureKilledChild : public CaptureFaults {};

void tell_parent(char word) {
  if (::write(kToParentFd, &word, 1) != 1) std::_Exit(3);
}

TEST_F(CaptureKilledChild, CapturesUntilItsParentKillsIt) {
  const char* moment_variable = std::getenv(kChildMomentVariable);
  if (moment_variable == nullptr) GTEST_SKIP() << "the child process of CaptureKilled.*, which starts and kills it";
  const std::string moment = moment_variable;
  start_scanner(std::getenv(kChildFolderVariable));
  ASSERT_FALSE(HasFatalFailure());
  session::CaptureOptions options = capture_options();
  options.turntable_timeout = milliseconds(120000);  // a table stuck for good: the kill ends the move
  session::CaptureSequencer scan(*projector_, {camera_.get()}, turntable_.get(), rig_->patterns, options);
  scan.run({writer_.get()}, [&](const session::CapturedFrame& frame) {
    if (frame.index != 1) return;
    tell_parent('1');
    char go = 0;
    if (::read(kFromParentFd, &go, 1) != 1) std::_Exit(3);
    if (moment == "during_a_turntable_move") clock_->freeze([] { tell_parent('K'); });
    if (moment == "mid_stack") {
      view_->observe([](int frame_index, int pattern) {
        if (frame_index != 2 || pattern != 10) return;
        tell_parent('K');
        for (;;) std::this_thread::sleep_for(std::chrono::seconds(1));
      });
    }
  });
  ADD_FAILURE() << "the capture ended without being killed";
}

}  // namespace
}  // namespace sls::test
