// The calibration capture through the C API (sls_calibration_capture.h) on sim:// devices
// opened with sls_camera_open & co: the same recording as the library's capture of the same
// devices (session::capture_calibration_from_devices, what `sls calibrate --camera` runs), image
// for image, and with sls_calib the same calibration from it, bit for bit; the pose callback's
// skip and stop; a cancel keeps a valid recording that a resume completes; a device that stops
// answering (a replay:// camera past its last frame) names the pose and keeps the frames; and
// the mistakes, each a status with nothing captured.
#include <sls/sls.h>

#include <gtest/gtest.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "sdk/core/recording.h"
#include "sdk/session/calibration_capture.h"
#include "tests/api/c_results_fixture.h"

#if defined(SLS_TEST_HAVE_CALIB)
#include "calib/calibrate_capture.h"
#endif

namespace sls::test {
namespace {

// The simulator's calibration target with its simulated operator (docs/calibration.md): the
// same URI for camera, projector and turntable.
std::string target(int hand_poses, bool small) {
  return "sim://chessboard?calibration=1&preset=ci" + std::string(small ? "&width=64" : "") +
         "&hand_poses=" + std::to_string(hand_poses) + "&head=chessboard";
}

struct CameraDeleter {
  void operator()(sls_camera* camera) const { sls_camera_close(camera); }
};
struct ProjectorDeleter {
  void operator()(sls_projector* projector) const { sls_projector_close(projector); }
};
struct TurntableDeleter {
  void operator()(sls_turntable* turntable) const { sls_turntable_close(turntable); }
};

struct Head {
  std::unique_ptr<sls_projector, ProjectorDeleter> projector;
  std::unique_ptr<sls_camera, CameraDeleter> camera;
  std::unique_ptr<sls_turntable, TurntableDeleter> turntable;  // null without one
};

// Opened as session::open_scanner_devices opens them: projector, camera, turntable.
Head open_head(sls_context* context, const std::string& uri, bool with_turntable) {
  Head head;
  sls_projector* projector = nullptr;
  sls_camera* camera = nullptr;
  sls_turntable* turntable = nullptr;
  SLS_OK_CALL(sls_projector_open(context, uri.c_str(), &projector, &error_));
  head.projector.reset(projector);
  SLS_OK_CALL(sls_camera_open(context, uri.c_str(), &camera, &error_));
  head.camera.reset(camera);
  if (with_turntable) {
    SLS_OK_CALL(sls_turntable_open(context, uri.c_str(), &turntable, &error_));
    head.turntable.reset(turntable);
  }
  return head;
}

// The operator and the progress display, behind the callbacks' one `user` pointer.
struct Operator {
  int skip_hand = -1;        // this hand pose is skipped
  int stop_at_hand = -1;     // at this hand pose the capture is stopped
  int answer = SLS_CALIBRATION_POSE_CAPTURE;  // the answer to every other pose
  std::size_t cancel_after = 0;  // progress answers 0 once this many poses are done (0: never)
  std::vector<std::string> asked;
  std::vector<sls_calibration_pose> poses;  // their description pointers are stale after the call
  std::vector<std::string> progress;        // "done/total detail"
  std::vector<std::string> stages;
};

int confirm(const sls_calibration_pose* pose, void* user) {
  Operator& person = *static_cast<Operator*>(user);
  person.asked.push_back(pose->description);
  person.poses.push_back(*pose);
  if (pose->kind == SLS_CALIBRATION_POSE_HAND && pose->index == person.skip_hand) return SLS_CALIBRATION_POSE_SKIP;
  if (pose->kind == SLS_CALIBRATION_POSE_HAND && pose->index == person.stop_at_hand) return SLS_CALIBRATION_POSE_STOP;
  return person.answer;
}

int show_progress(const sls_calibration_progress* progress, void* user) {
  Operator& person = *static_cast<Operator*>(user);
  person.progress.push_back(std::to_string(progress->done) + "/" + std::to_string(progress->total) + " " +
                            progress->detail);
  person.stages.push_back(progress->stage);
  return person.cancel_after == 0 || progress->done < person.cancel_after ? 1 : 0;
}

sls_calibration_capture_config config_for(int hand_poses, const std::vector<double>& angles) {
  sls_calibration_capture_config config;
  sls_calibration_capture_config_init(&config);
  config.hand_poses = hand_poses;
  config.turntable_angles_deg = angles.empty() ? nullptr : angles.data();
  config.turntable_angle_count = angles.size();
  return config;
}

sls_calibration_capture_result fresh_result() {
  sls_calibration_capture_result result;
  sls_calibration_capture_result_init(&result);
  return result;
}

std::size_t frames_in(const std::string& folder) { return RecordingReader::open(folder).frame_count(); }

// Five hand poses (the third skipped) and three table angles at the ci preset, as
// cli.sls_calibrate_capture's operator answers them: through the C API and through the library.
TEST(CCalibrationCapture, SameRecordingAndCalibrationAsTheLibrarysCapture) {
  TemporaryDirectory dir;
  const std::string uri = target(5, false);
  const std::vector<double> angles{320.0, 0.0, 40.0};
  const ContextPtr context = cpu_context();
  Operator person;
  person.skip_hand = 2;
  sls_calibration_capture_result result = fresh_result();
  {
    const Head head = open_head(context.get(), uri, true);
    const sls_calibration_capture_config config = config_for(5, angles);
    SLS_OK_CALL(sls_calibration_capture(head.camera.get(), head.projector.get(), head.turntable.get(),
                                        dir.file("c").c_str(), &config, confirm, show_progress, &person, &result,
                                        &error_));
  }
  EXPECT_EQ((std::vector<std::size_t>{result.poses_captured, result.poses_skipped, result.frames, result.hand_frames,
                                      result.turntable_frames, result.resumed_from, result.images_per_frame}),
            (std::vector<std::size_t>{7, 1, 7, 4, 3, 0, 42}));
  EXPECT_EQ(result.stopped, 0);
  EXPECT_EQ(result.retries, 0u);
  EXPECT_GT(result.capture_seconds, 0.0);
  EXPECT_GE(result.seconds, result.capture_seconds);
  std::printf("C API capture: %zu poses in %.2f s (capture %.2f s)\n", result.poses_captured, result.seconds,
              result.capture_seconds);
  ASSERT_EQ(person.asked.size(), 8u);
  EXPECT_EQ(person.asked[0], "hand pose 1 of 5");
  EXPECT_EQ(person.asked[5], "turntable pose 1 of 3 (320.000 deg)");
  EXPECT_EQ(person.poses[5].kind, SLS_CALIBRATION_POSE_TURNTABLE);
  EXPECT_EQ((std::vector<int>{person.poses[7].index, person.poses[7].count}), (std::vector<int>{2, 3}));
  EXPECT_EQ(person.poses[7].turntable_angle_deg, 40.0);
  EXPECT_EQ(person.poses[1].turntable_angle_deg, 0.0);
  EXPECT_EQ(person.poses[1].struct_size, sizeof(sls_calibration_pose));
  ASSERT_EQ(person.progress.size(), 8u);
  EXPECT_EQ(person.progress[2], "3/8 hand pose 3 of 5 skipped");
  EXPECT_EQ(person.progress[7], "8/8 turntable pose 3 of 3 (40.000 deg)");
  EXPECT_EQ(person.stages[7], "calibration capture");

  session::CalibrationDeviceRequest request;
  request.camera_uri = request.projector_uri = request.turntable_uri = uri;
  request.sim_device = Device::cpu();
  session::CalibrationCaptureOptions options;
  options.hand_poses = 5;
  options.turntable_angles_deg = angles;
  const session::CalibrationCapture library = session::capture_calibration_from_devices(
      dir.file("library"), request, options, [](const session::CalibrationPose& pose) {
        return pose.kind == session::CalibrationPoseKind::kHand && pose.index == 2 ? session::PoseDecision::kSkip
                                                                                    : session::PoseDecision::kCapture;
      });
  EXPECT_EQ(library.frames, 7);

  // The same recording: frames, angles and every image, pixel for pixel.
  const RecordingReader ours = RecordingReader::open(dir.file("c"));
  const RecordingReader theirs = RecordingReader::open(dir.file("library"));
  ASSERT_EQ(ours.frame_count(), theirs.frame_count());
  EXPECT_FALSE(ours.has_calibration());
  EXPECT_EQ(ours.info().pattern_set_json, theirs.info().pattern_set_json);
  std::size_t differing = 0;
  for (std::size_t frame = 0; frame < ours.frame_count(); ++frame) {
    EXPECT_EQ(ours.frame(frame).turntable_angle_deg, theirs.frame(frame).turntable_angle_deg) << frame;
    for (int image = 0; image < ours.info().images_per_frame; ++image) {
      const auto k = static_cast<std::size_t>(image);
      differing += !(ours.load_image(frame, k) == theirs.load_image(frame, k));
    }
  }
  EXPECT_EQ(differing, 0u);

#if defined(SLS_TEST_HAVE_CALIB)
  // The same calibration, bit for bit: sls_calibration_run on the C API's recording against
  // calib::calibrate_capture (what `sls calibrate --input` runs) on the library's.
  sls_calibration_config board;
  sls_calibration_config_init(&board);
  board.board_inner_cols = 9;
  board.board_inner_rows = 7;
  board.board_square_m = 0.0006;
  sls_calibration* raw = nullptr;
  SLS_OK_CALL(sls_calibration_run(context.get(), dir.file("c").c_str(), &board, nullptr, nullptr, &raw, &error_));
  ASSERT_NE(raw, nullptr);
  const std::unique_ptr<sls_calibration, void (*)(sls_calibration*)> calibration(raw, sls_calibration_destroy);
  calib::CalibrateCaptureOptions calibrate;
  calibrate.input = dir.file("library");
  calibrate.board = {9, 7, 0.0006};
  const calib::CalibrateCaptureResult expected = calib::calibrate_capture(calibrate, {});
  const ScannerCalibration& exact = expected.procam.calibration;
  for (const auto& [device, lens] : {std::pair{SLS_CALIBRATION_CAMERA, exact.camera},
                                     std::pair{SLS_CALIBRATION_PROJECTOR, exact.projector}}) {
    sls_intrinsics got;
    sls_intrinsics_init(&got);
    SLS_OK_CALL(sls_calibration_get_intrinsics(calibration.get(), device, &got, &error_));
    EXPECT_EQ((std::vector<double>{got.fx, got.fy, got.cx, got.cy, got.k1, got.k2, got.k3, got.p1, got.p2}),
              (std::vector<double>{lens.fx, lens.fy, lens.cx, lens.cy, lens.k1, lens.k2, lens.k3, lens.p1, lens.p2}));
  }
  double T[16];
  SLS_OK_CALL(sls_calibration_get_extrinsics(calibration.get(), T, &error_));
  const Eigen::Matrix4d expected_T = exact.T_camera_projector.matrix();
  for (int i = 0; i < 16; ++i) EXPECT_EQ(T[i], expected_T(i / 4, i % 4)) << i;
  sls_calibration_summary summary;
  sls_calibration_summary_init(&summary);
  SLS_OK_CALL(sls_calibration_get_summary(calibration.get(), &summary, &error_));
  EXPECT_EQ(summary.stereo_rms_px, expected.procam.stereo_rms_px);
  EXPECT_EQ(summary.views_used, 7u);
  EXPECT_EQ(summary.turntable_axis_fitted, 1);
  EXPECT_LT(summary.stereo_rms_px, 0.5);
  double point[3], direction[3];
  SLS_OK_CALL(sls_calibration_get_turntable_axis(calibration.get(), point, direction, &error_));
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(point[i], expected.axis.axis.point_camera[i]);
    EXPECT_EQ(direction[i], expected.axis.axis.direction_camera[i]);
  }
#endif
}

// The pose callback skips the first pose, captures the second and stops at the third: the call
// succeeds with the one pose captured, in a valid recording.
TEST(CCalibrationCapture, SkipAndStopFromThePoseCallback) {
  TemporaryDirectory dir;
  const ContextPtr context = cpu_context();
  const Head head = open_head(context.get(), target(3, true), false);
  Operator person;
  person.skip_hand = 0;
  person.stop_at_hand = 2;
  const sls_calibration_capture_config config = config_for(3, {});
  sls_calibration_capture_result result = fresh_result();
  SLS_OK_CALL(sls_calibration_capture(head.camera.get(), head.projector.get(), nullptr, dir.file("rec").c_str(),
                                      &config, confirm, show_progress, &person, &result, &error_));
  EXPECT_EQ((std::vector<std::size_t>{result.poses_captured, result.poses_skipped, result.frames}),
            (std::vector<std::size_t>{1, 1, 1}));
  EXPECT_EQ(result.stopped, 1);
  EXPECT_EQ(person.asked, (std::vector<std::string>{"hand pose 1 of 3", "hand pose 2 of 3", "hand pose 3 of 3"}));
  EXPECT_EQ(frames_in(dir.file("rec")), 1u);

  // No pose callback: every pose captured without asking.
  const sls_calibration_capture_config two = config_for(2, {});
  SLS_OK_CALL(sls_calibration_capture(head.camera.get(), head.projector.get(), nullptr, dir.file("all").c_str(), &two,
                                      nullptr, nullptr, nullptr, nullptr, &error_));
  EXPECT_EQ(frames_in(dir.file("all")), 2u);
}

// A cancel from the progress callback after the second pose: SLS_ERROR_CANCELLED, the two poses
// in a valid recording; a resume asks for the rest (hand pose 3, then both table angles).
TEST(CCalibrationCapture, ACancelKeepsAValidRecordingThatAResumeCompletes) {
  TemporaryDirectory dir;
  const std::string folder = dir.file("rec");
  const ContextPtr context = cpu_context();
  const Head head = open_head(context.get(), target(3, true), true);
  const std::vector<double> angles{350.0, 10.0};
  sls_calibration_capture_config config = config_for(3, angles);
  Operator person;
  person.cancel_after = 2;
  sls_calibration_capture_result result = fresh_result();
  SLS_FAILS(sls_calibration_capture(head.camera.get(), head.projector.get(), head.turntable.get(), folder.c_str(),
                                    &config, confirm, show_progress, &person, &result, &error_),
            SLS_ERROR_CANCELLED, "cancelled after hand pose 2 of 3; 2 frame(s) are in");
  EXPECT_EQ(result.frames, 2u);
  EXPECT_EQ(result.poses_captured, 0u);  // only `frames` on a failure
  EXPECT_EQ(frames_in(folder), 2u);

  // Continuing it without resume is refused, naming the way out.
  SLS_FAILS(sls_calibration_capture(head.camera.get(), head.projector.get(), head.turntable.get(), folder.c_str(),
                                    &config, confirm, nullptr, &person, nullptr, &error_),
            SLS_ERROR_INVALID_ARGUMENT, "set config.resume to continue it");

  config.resume = 1;
  Operator resumed;
  result = fresh_result();
  SLS_OK_CALL(sls_calibration_capture(head.camera.get(), head.projector.get(), head.turntable.get(), folder.c_str(),
                                      &config, confirm, show_progress, &resumed, &result, &error_));
  EXPECT_EQ(resumed.asked, (std::vector<std::string>{"hand pose 3 of 3", "turntable pose 1 of 2 (350.000 deg)",
                                                     "turntable pose 2 of 2 (10.000 deg)"}));
  EXPECT_EQ((std::vector<std::size_t>{result.resumed_from, result.poses_captured, result.frames, result.hand_frames,
                                      result.turntable_frames}),
            (std::vector<std::size_t>{2, 3, 5, 3, 2}));
  const RecordingReader reader = RecordingReader::open(folder);
  ASSERT_EQ(reader.frame_count(), 5u);
  EXPECT_FALSE(reader.frame(2).turntable_angle_deg.has_value());
  ASSERT_TRUE(reader.frame(4).turntable_angle_deg.has_value());
  EXPECT_NEAR(*reader.frame(4).turntable_angle_deg, 10.0, 0.1);

  // Complete: another resume captures nothing.
  Operator again;
  SLS_OK_CALL(sls_calibration_capture(head.camera.get(), head.projector.get(), head.turntable.get(), folder.c_str(),
                                      &config, confirm, nullptr, &again, &result, &error_));
  EXPECT_TRUE(again.asked.empty());
  EXPECT_EQ((std::vector<std::size_t>{result.resumed_from, result.poses_captured, result.frames}),
            (std::vector<std::size_t>{5, 0, 5}));
}

// A camera that stops answering (a replay of a two-pose capture asked for a third pose): the
// driver's status, the message naming the pose and the camera, the two frames kept.
TEST(CCalibrationCapture, ADeviceFaultNamesThePoseAndKeepsTheFrames) {
  TemporaryDirectory dir;
  const ContextPtr context = cpu_context();
  {
    const Head head = open_head(context.get(), target(2, true), false);
    const sls_calibration_capture_config two = config_for(2, {});
    SLS_OK_CALL(sls_calibration_capture(head.camera.get(), head.projector.get(), nullptr, dir.file("two").c_str(),
                                        &two, nullptr, nullptr, nullptr, nullptr, &error_));
  }
  const std::string replay = "replay://" + std::filesystem::absolute(dir.file("two")).string();
  const Head head = open_head(context.get(), replay, false);
  sls_calibration_capture_config three = config_for(3, {});
  three.max_retries = 0;
  sls_calibration_capture_result result = fresh_result();
  sls_error* error = nullptr;
  const sls_status status = sls_calibration_capture(head.camera.get(), head.projector.get(), nullptr,
                                                    dir.file("fault").c_str(), &three, nullptr, nullptr, nullptr,
                                                    &result, &error);
  EXPECT_EQ(status, SLS_ERROR_NOT_FOUND);
  const std::string message = sls_error_message(error);
  EXPECT_STREQ(sls_error_function(error), "sls_calibration_capture");
  sls_error_free(error);
  EXPECT_NE(message.find("calibration hand pose 3 of 3"), std::string::npos) << message;
  EXPECT_NE(message.find(replay), std::string::npos) << message;
  EXPECT_NE(message.find("end of the recording"), std::string::npos) << message;
  EXPECT_NE(message.find("2 frame(s) are in"), std::string::npos) << message;
  EXPECT_EQ(result.frames, 2u);
  EXPECT_EQ(frames_in(dir.file("fault")), 2u);
}

TEST(CCalibrationCapture, MistakesAreStatusesWithNothingCaptured) {
  TemporaryDirectory dir;
  const std::string folder = dir.file("rec");
  const ContextPtr context = cpu_context();
  const Head head = open_head(context.get(), target(2, true), false);
  sls_camera* camera = head.camera.get();
  sls_projector* projector = head.projector.get();
  const sls_calibration_capture_config config = config_for(2, {});
  const auto refused = [&](const sls_calibration_capture_config* with, sls_calibration_capture_result* result,
                         const char* part, sls_status expected = SLS_ERROR_INVALID_ARGUMENT) {
    SLS_FAILS(sls_calibration_capture(camera, projector, nullptr, folder.c_str(), with, nullptr, nullptr, nullptr,
                                      result, &error_),
              expected, part);
  };

  SLS_FAILS(sls_calibration_capture(nullptr, projector, nullptr, folder.c_str(), &config, nullptr, nullptr, nullptr,
                                    nullptr, &error_),
            SLS_ERROR_INVALID_ARGUMENT, "camera is NULL");
  SLS_FAILS(sls_calibration_capture(camera, nullptr, nullptr, folder.c_str(), &config, nullptr, nullptr, nullptr,
                                    nullptr, &error_),
            SLS_ERROR_INVALID_ARGUMENT, "projector is NULL");
  SLS_FAILS(sls_calibration_capture(camera, projector, nullptr, nullptr, &config, nullptr, nullptr, nullptr, nullptr,
                                    &error_),
            SLS_ERROR_INVALID_ARGUMENT, "recording_folder");
  SLS_FAILS(sls_calibration_capture(camera, projector, nullptr, "", &config, nullptr, nullptr, nullptr, nullptr,
                                    &error_),
            SLS_ERROR_INVALID_ARGUMENT, "recording_folder");

  sls_calibration_capture_config bad = config;
  bad.struct_size = 0;
  refused(&bad, nullptr, "sls_calibration_capture_config.struct_size is 0");
  bad.struct_size = 1u << 30;  // an uninitialised struct
  refused(&bad, nullptr, "initialise it with sls_calibration_capture_config_init");
  sls_calibration_capture_result result = fresh_result();
  result.struct_size = 3;
  refused(&config, &result, "sls_calibration_capture_result.struct_size is 3");

  const double angle = 10.0;
  bad = config;
  bad.turntable_angles_deg = &angle;
  bad.turntable_angle_count = 1;
  refused(&bad, nullptr, "1 turntable angle(s) but no turntable");
  bad.turntable_angles_deg = nullptr;
  refused(&bad, nullptr, "config.turntable_angles_deg is NULL but config.turntable_angle_count is 1");
  const double full_turn = 360.0;
  bad.turntable_angles_deg = &full_turn;
  refused(&bad, nullptr, "turntable angle 360 deg");
  bad = config;
  bad.hand_poses = -1;
  refused(&bad, nullptr, "-1 hand poses");
  bad.hand_poses = 0;
  refused(&bad, nullptr, "nothing to capture");
  bad = config;
  bad.image_timeout_ms = 0;
  refused(&bad, nullptr, "image_timeout");
  bad = config;
  bad.pattern_set = "no-such-set";
  refused(&bad, nullptr, "no-such-set");
  bad = config;
  bad.resume = 1;
  refused(&bad, nullptr, "holds no recording to continue");
  // None of these made anything.
  EXPECT_FALSE(std::filesystem::exists(folder));

  // A folder with something else in it is not a recording to write into.
  std::filesystem::create_directories(folder);
  std::FILE* other = std::fopen((folder + "/notes.txt").c_str(), "w");
  ASSERT_NE(other, nullptr);
  std::fclose(other);
  result = fresh_result();
  refused(&config, &result, "is not an empty folder; set config.resume");
  EXPECT_EQ(result.frames, 0u);

  // An answer that is no decision ends the capture naming the pose; the recording is kept.
  Operator odd;
  odd.answer = 7;
  SLS_FAILS(sls_calibration_capture(camera, projector, nullptr, dir.file("odd").c_str(), &config, confirm, nullptr,
                                    &odd, nullptr, &error_),
            SLS_ERROR_INVALID_ARGUMENT, "the pose callback answered 7 for calibration hand pose 1 of 2");
  EXPECT_EQ(frames_in(dir.file("odd")), 0u);

  // A NULL config is the defaults (12 hand poses: stopped at once here, nothing captured).
  Operator stops;
  stops.stop_at_hand = 0;
  result = fresh_result();
  SLS_OK_CALL(sls_calibration_capture(camera, projector, nullptr, dir.file("defaults").c_str(), nullptr, confirm,
                                      nullptr, &stops, &result, &error_));
  EXPECT_EQ(stops.asked, (std::vector<std::string>{"hand pose 1 of 12"}));
  EXPECT_EQ((std::vector<std::size_t>{result.frames, result.poses_captured}), (std::vector<std::size_t>{0, 0}));
  EXPECT_EQ(result.stopped, 1);
}

TEST(CCalibrationCapture, ConfigDefaultsAreTheLibrarys) {
  sls_calibration_capture_config config;
  sls_calibration_capture_config_init(&config);
  const session::CalibrationCaptureOptions library;
  EXPECT_EQ(config.struct_size, sizeof(config));
  EXPECT_EQ(config.hand_poses, library.hand_poses);
  EXPECT_EQ(config.turntable_angles_deg, nullptr);
  EXPECT_EQ(config.turntable_angle_count, 0u);
  EXPECT_EQ(config.home_turntable, 1);
  EXPECT_EQ(config.resume, 0);
  EXPECT_EQ(config.pattern_set, nullptr);
  EXPECT_EQ(config.exposure_us, 0.0);
  EXPECT_EQ(config.image_timeout_ms, library.image_timeout.count());
  EXPECT_EQ(config.turntable_timeout_ms, library.turntable_timeout.count());
  EXPECT_EQ(config.max_retries, library.max_retries);
  EXPECT_EQ(config.more_cameras, nullptr);  // 0.9: one camera unless a head's others are given
  EXPECT_EQ(config.more_camera_count, 0u);
}

}  // namespace
}  // namespace sls::test
