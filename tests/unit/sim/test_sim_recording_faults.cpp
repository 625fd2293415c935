// The simulator's recording under faults (issue 19 item 9): stopped at every step of a frame,
// by a failure it sees (an exception, as a full disk gives) or by a crash it does not see
// (_exit in a child process, as kill -9), every listed frame has its ground truth and its
// pose, and a resumed run ends with the recording an uninterrupted run writes, file for file.
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "drivers/sim/sim_recording.h"
#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/recording.h"
#include "sdk/core/trajectory.h"
#include "tests/support/test_support.h"

namespace sls::sim {
namespace {

namespace fs = std::filesystem;

constexpr int kFrames = 4;
constexpr int kStopFrame = 2;
const SimFrameStep kSteps[] = {SimFrameStep::kCaptured, SimFrameStep::kImagesWritten,
                               SimFrameStep::kGroundTruthWritten, SimFrameStep::kTrajectoryWritten,
                               SimFrameStep::kListed};
const char* const kFrameTruth[] = {"depth.pfm", "projector_u.pfm", "projector_v.pfm", "depth_sigma.pfm", "valid.png"};

SimRecordingOptions small_options() {
  SimRecordingOptions options;
  options.rig.preset = "ci";
  options.rig.frames = kFrames;
  options.rig.camera_width = 96;  // small frames: the test writes the recording a dozen times
  options.reference_spacing_m = 1e-3;
  return options;
}

void expect_same_recording(const std::string& folder, const std::string& reference) {
  const auto got = test::recording_snapshot(folder);
  const auto want = test::recording_snapshot(reference);
  ASSERT_EQ(got.size(), want.size()) << folder;
  for (std::size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].first, want[i].first);
    EXPECT_TRUE(got[i].second == want[i].second) << got[i].first << " differs from the uninterrupted run's";
  }
}

// What must hold after a stop at any moment: the recording opens, every listed frame has all
// its ground truth (equal to the uninterrupted run's) and its pose at its timestamp;
// trajectory.txt holds the listed frames' poses, at most one more (a frame not listed).
// Returns the number of frames listed.
std::size_t check_consistent(const std::string& folder, const std::string& reference, std::size_t max_extra_poses) {
  const RecordingReader reader = RecordingReader::open(folder);
  reader.verify(true);
  const std::string truth = reader.groundtruth_folder();
  const std::vector<StampedPose> poses = read_tum_trajectory(truth + "/trajectory.txt");
  EXPECT_GE(poses.size(), reader.frame_count());
  EXPECT_LE(poses.size(), reader.frame_count() + max_extra_poses);
  const std::vector<StampedPose> reference_poses = read_tum_trajectory(reference + "/groundtruth/trajectory.txt");
  for (std::size_t i = 0; i < reader.frame_count(); ++i) {
    const std::string relative = fmt::format("groundtruth/frames/{:06d}/", i);
    for (const char* name : kFrameTruth) {
      const bool exists = fs::is_regular_file(folder + "/" + relative + name);
      EXPECT_TRUE(exists) << "listed frame " << i << " lacks " << name;
      if (exists) {
        EXPECT_TRUE(test::bytes_of(folder + "/" + relative + name) == test::bytes_of(reference + "/" + relative + name));
      }
    }
    EXPECT_DOUBLE_EQ(poses[i].timestamp_s, static_cast<double>(reader.frame(i).timestamp_ns) * 1e-9);
    EXPECT_TRUE(poses[i].T_world_camera.is_approx(reference_poses[i].T_world_camera, 0.0));
  }
  return reader.frame_count();
}

struct StopHere {};

class SimRecordingFaults : public ::testing::Test {
 protected:
  static void TearDownTestSuite() {
    delete reference_;
    reference_ = nullptr;
  }
  // An uninterrupted run, made on first use (not in a crash test's child process).
  static std::string reference() {
    if (reference_ == nullptr) {
      reference_ = new test::TemporaryDirectory();
      write_sim_recording(reference_->file("rec"), small_options(), Device::cpu(), {});
    }
    return reference_->file("rec");
  }

  static test::TemporaryDirectory* reference_;
};

test::TemporaryDirectory* SimRecordingFaults::reference_ = nullptr;

TEST_F(SimRecordingFaults, AFailureAtAnyStepKeepsEveryListedFrameWholeAndResumesToTheSameRecording) {
  for (const SimFrameStep stop : kSteps) {
    SCOPED_TRACE(static_cast<int>(stop));
    test::TemporaryDirectory dir;
    SimRecordingOptions options = small_options();
    options.step_hook = [stop](SimFrameStep step, int frame) {
      if (step == stop && frame == kStopFrame) throw StopHere{};
    };
    EXPECT_THROW(write_sim_recording(dir.file("rec"), options, Device::cpu(), {}), StopHere);
    const std::size_t listed = check_consistent(dir.file("rec"), reference(), 0);
    EXPECT_EQ(listed, stop == SimFrameStep::kListed ? kStopFrame + 1u : kStopFrame + 0u);

    options.step_hook = {};
    options.resume = true;
    const SimRecordingSummary summary = write_sim_recording(dir.file("rec"), options, Device::cpu(), {});
    EXPECT_EQ(summary.resumed_from, static_cast<int>(listed));
    EXPECT_EQ(summary.frames, kFrames);
    expect_same_recording(dir.file("rec"), reference());
  }
}

// A crash: a child process ends at the step with no unwinding and no clean-up at all.
class SimRecordingCrash : public SimRecordingFaults, public ::testing::WithParamInterface<SimFrameStep> {};

TEST_P(SimRecordingCrash, KeepsEveryListedFrameWholeAndResumesToTheSameRecording) {
  const SimFrameStep stop = GetParam();
  GTEST_FLAG_SET(death_test_style, "threadsafe");  // a fresh process: the renderer's threads
  // The child re-runs this body up to EXPECT_EXIT: it takes the parent's folder from the
  // environment.
  constexpr const char* kFolderVariable = "SLS_TEST_SIM_CRASH_FOLDER";
  const char* inherited = std::getenv(kFolderVariable);
  std::optional<test::TemporaryDirectory> dir;
  if (inherited == nullptr) dir.emplace();
  const std::string folder = inherited != nullptr ? std::string(inherited) : dir->file("rec");
  ::setenv(kFolderVariable, folder.c_str(), 1);
  EXPECT_EXIT(
      {
        SimRecordingOptions options = small_options();
        // A kill while frames wait for the writer thread loses those (at most its queue; the
        // recording stays valid and resumes): killed on the capturing thread (kCaptured), the
        // frames before are written there first, so that what was listed is known. The other
        // steps run on the writer thread, with its queue.
        if (stop == SimFrameStep::kCaptured) options.write_queue_frames = 0;
        options.step_hook = [stop](SimFrameStep step, int frame) {
          if (step == stop && frame == kStopFrame) ::_exit(9);
        };
        write_sim_recording(folder, options, Device::cpu(), {});
        ::_exit(0);
      },
      ::testing::ExitedWithCode(9), "");
  ::unsetenv(kFolderVariable);
  // Killed after its pose was written, before the manifest listed the frame: one pose more.
  const std::size_t listed = check_consistent(folder, reference(), stop == SimFrameStep::kTrajectoryWritten ? 1 : 0);
  EXPECT_EQ(listed, stop == SimFrameStep::kListed ? kStopFrame + 1u : kStopFrame + 0u);

  SimRecordingOptions options = small_options();
  options.resume = true;
  write_sim_recording(folder, options, Device::cpu(), {});
  expect_same_recording(folder, reference());
}

INSTANTIATE_TEST_SUITE_P(AtEveryStep, SimRecordingCrash, ::testing::ValuesIn(kSteps));

TEST_F(SimRecordingFaults, ACancelledRunResumesAndAFinishedOneResumesToItself) {
  test::TemporaryDirectory dir;
  SimRecordingOptions options = small_options();
  const ProgressCallback stop_after_one = [](const ProgressUpdate& update) { return update.done < 1; };
  try {
    write_sim_recording(dir.file("rec"), options, Device::cpu(), stop_after_one);
    FAIL() << "expected a cancellation";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kCancelled);
  }
  EXPECT_EQ(check_consistent(dir.file("rec"), reference(), 0), 1u);
  options.resume = true;
  EXPECT_EQ(write_sim_recording(dir.file("rec"), options, Device::cpu(), {}).resumed_from, 1);
  expect_same_recording(dir.file("rec"), reference());
  // Nothing left to capture: the recording stays as it is.
  EXPECT_EQ(write_sim_recording(dir.file("rec"), options, Device::cpu(), {}).resumed_from, kFrames);
  expect_same_recording(dir.file("rec"), reference());
}

// A recording of an older writer, killed after listing a frame but before its ground truth:
// the resume writes what the listed frames lack.
TEST_F(SimRecordingFaults, AResumeWritesTheGroundTruthListedFramesLack) {
  test::TemporaryDirectory dir;
  fs::copy(reference(), dir.file("rec"), fs::copy_options::recursive);
  fs::remove_all(dir.file("rec/groundtruth/frames/000001"));
  fs::remove(dir.file("rec/groundtruth/reference.ply"));
  const std::vector<StampedPose> poses = read_tum_trajectory(dir.file("rec/groundtruth/trajectory.txt"));
  write_tum_trajectory(dir.file("rec/groundtruth/trajectory.txt"), {poses.begin(), poses.begin() + 1});
  SimRecordingOptions options = small_options();
  options.resume = true;
  write_sim_recording(dir.file("rec"), options, Device::cpu(), {});
  expect_same_recording(dir.file("rec"), reference());
}

TEST_F(SimRecordingFaults, AResumeWithOtherOptionsIsRefusedNamingWhatDiffers) {
  test::TemporaryDirectory dir;
  SimRecordingOptions options = small_options();
  options.resume = true;
  try {
    write_sim_recording(dir.file("none"), options, Device::cpu(), {});
    FAIL() << "expected kNotFound";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kNotFound) << error.what();
  }
  fs::copy(reference(), dir.file("rec"), fs::copy_options::recursive);
  const auto expect_refused = [&](const SimRecordingOptions& other, const std::string& named) {
    try {
      write_sim_recording(dir.file("rec"), other, Device::cpu(), {});
      FAIL() << "expected a refusal naming " << named;
    } catch (const Error& error) {
      EXPECT_EQ(error.code(), ErrorCode::kInvalidArgument) << error.what();
      EXPECT_NE(std::string(error.what()).find(named), std::string::npos) << error.what();
    }
  };
  SimRecordingOptions other = options;
  other.rig.seed = 7;
  expect_refused(other, "seed=7");
  other = options;
  other.object = "knurled-knob";
  expect_refused(other, "sim://knurled-knob");
  other = options;
  other.rig.frames = 6;
  expect_refused(other, "frames=6");
  other = options;
  other.rig.bit_depth = 8;
  expect_refused(other, "bit");
  other = options;
  other.rig.angle_jitter_deg = 0.5;
  expect_refused(other, "angle_jitter_deg");
  other = options;
  other.depth_mode = true;
  expect_refused(other, "--mode");
  // Refusals write nothing.
  expect_same_recording(dir.file("rec"), reference());
}

}  // namespace
}  // namespace sls::sim
