/* A head of two cameras captured through the C API (sls_calibration_capture.h, API 0.9) from a
 * C99 program, on sim:// devices: camera K of `sls sim --calibration --cameras 2`'s head is
 * sim://chessboard?...&cameras=2&camera=K, and the devices of one head share its projector and
 * its simulated operator.
 *   test_c_calibration_capture_head SCRATCH [--unsupported]
 * SCRATCH: a folder for the captures (created; it must not hold an earlier run's: ctest's
 * setup fixture removes it).
 * Checks: four hand poses captured by both cameras together into SCRATCH/head/camera0 and
 * camera1, result.cameras 2; then (with OpenCV) sls_calibration_run on the head's folder: two
 * cameras, camera 1 about 50 degrees round from camera 0, every pose used by both; a resume
 * that continues both recordings; a head whose recordings disagree refused naming the folder; a
 * camera that fails at the third pose (camera 1 of another head, whose operator has only two)
 * naming the camera, its URI and the pose, both recordings keeping the two poses; the config's
 * mistakes. --unsupported: a build without OpenCV (the capture works, the calibration answers
 * SLS_ERROR_UNSUPPORTED).
 * Exit status 0 when every check holds; each failed check prints its line. */
#define _POSIX_C_SOURCE 200809L

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <sls/sls.h>

#include "c_checks.h"

#define HEAD_URI "sim://chessboard?calibration=1&preset=ci&hand_poses=6&head=chessboard&cameras=2"

static double rotation_deg(const double T[16]) {
  double cosine = 0.5 * (T[0] + T[5] + T[10] - 1.0);
  if (cosine > 1.0) cosine = 1.0;
  if (cosine < -1.0) cosine = -1.0;
  return acos(cosine) * 180.0 / 3.14159265358979323846;
}

/* Frames listed in a recording's manifest (its "index" entries). */
static int manifest_frames(const char* recording) {
  char* path = path_join(recording, "manifest.json");
  char buffer[1 << 16];
  size_t length;
  int frames = 0;
  const char* at;
  FILE* file = fopen(path, "rb");
  free(path);
  if (file == NULL) return -1;
  length = fread(buffer, 1, sizeof(buffer) - 1, file);
  fclose(file);
  buffer[length] = '\0';
  for (at = strstr(buffer, "\"index\""); at != NULL; at = strstr(at + 1, "\"index\"")) ++frames;
  return frames;
}

typedef struct Head {
  sls_projector* projector;
  sls_camera* cameras[2];
} Head;

static int open_head(sls_context* context, const char* camera1_uri, Head* head) {
  memset(head, 0, sizeof(*head));
  CHECK_OK(sls_projector_open(context, HEAD_URI, &head->projector, &error_));
  CHECK_OK(sls_camera_open(context, HEAD_URI "&camera=0", &head->cameras[0], &error_));
  CHECK_OK(sls_camera_open(context, camera1_uri, &head->cameras[1], &error_));
  return head->projector != NULL && head->cameras[0] != NULL && head->cameras[1] != NULL;
}

static void close_head(Head* head) {
  sls_camera_close(head->cameras[1]);
  sls_camera_close(head->cameras[0]);
  sls_projector_close(head->projector);
}

static sls_calibration_capture_config head_config(int hand_poses, sls_camera* const* more) {
  sls_calibration_capture_config config;
  sls_calibration_capture_config_init(&config);
  config.hand_poses = hand_poses;
  config.more_cameras = more;
  config.more_camera_count = 1;
  return config;
}

static void check_calibration(sls_context* context, const char* folder, int unsupported) {
  sls_calibration* calibration = NULL;
  sls_calibration_camera cameras[2];
  size_t count = 0, k;
  if (unsupported) {
    CHECK_ERROR(sls_calibration_run(context, folder, NULL, NULL, NULL, &calibration, &error_),
                SLS_ERROR_UNSUPPORTED, NULL);
    return;
  }
  {
    sls_calibration_config board;
    sls_calibration_config_init(&board);
    board.board_inner_cols = 9;
    board.board_inner_rows = 7;
    board.board_square_m = 0.0006;
    CHECK_OK(sls_calibration_run(context, folder, &board, NULL, NULL, &calibration, &error_));
  }
  if (calibration == NULL) return;
  CHECK_OK(sls_calibration_camera_count(calibration, &count, &error_));
  CHECK(count == 2);
  for (k = 0; k < 2 && count == 2; ++k) {
    sls_calibration_camera_init(&cameras[k]);
    CHECK_OK(sls_calibration_get_camera(calibration, k, &cameras[k], NULL, &error_));
    CHECK(cameras[k].views_used == 4);
    CHECK(cameras[k].stereo_rms_px > 0.0 && cameras[k].stereo_rms_px < 0.5);
    /* Captured through simulated devices: the recordings carry the exact calibration. At ci's
     * 400 x 300 pixels and 4 poses a camera is good to a few percent (bounds: a wrong truth,
     * another camera's, is off by far more). */
    CHECK(cameras[k].has_truth == 1);
    CHECK(cameras[k].focal_rel_err >= 0.0 && cameras[k].focal_rel_err < 0.1);
    CHECK(cameras[k].principal_point_err_px >= 0.0 && cameras[k].principal_point_err_px < 100.0);
  }
  if (count == 2) {
    printf("captured head: camera1 %.3f deg from camera0, %.3f px RMS from %zu views\n",
           rotation_deg(cameras[1].T_camera0_camera), cameras[1].camera_camera_rms_px,
           cameras[1].camera_camera_views);
    CHECK(fabs(rotation_deg(cameras[1].T_camera0_camera) - 50.0) < 0.5);
    CHECK(cameras[1].camera_camera_views == 4);
    CHECK(cameras[1].camera_camera_rms_px > 0.0 && cameras[1].camera_camera_rms_px < 0.5);
  }
  sls_calibration_destroy(calibration);
}

int main(int argc, char** argv) {
  sls_context* context = NULL;
  sls_context_config context_config;
  sls_error* error = NULL;
  sls_calibration_capture_config config;
  sls_calibration_capture_result result;
  Head head;
  char* folder;
  char* camera0;
  char* camera1;
  int unsupported;
  if (argc < 2 || argc > 3) {
    fprintf(stderr, "usage: %s SCRATCH [--unsupported]\n", argv[0]);
    return 2;
  }
  unsupported = argc == 3 && strcmp(argv[2], "--unsupported") == 0;
  if (mkdir(argv[1], 0755) != 0 && errno != EEXIST) {
    fprintf(stderr, "cannot create %s\n", argv[1]);
    return 2;
  }
  sls_context_config_init(&context_config);
  context_config.device = SLS_DEVICE_CPU;
  if (sls_context_create(SLS_API_VERSION, &context_config, &context, &error) != SLS_OK) {
    fprintf(stderr, "sls_context_create: %s\n", sls_error_message(error));
    sls_error_free(error);
    return 2;
  }
  CHECK(SLS_API_VERSION >= SLS_MAKE_VERSION(0, 9, 0)); /* heads captured through devices came with 0.9 */
  folder = path_join(argv[1], "head");
  camera0 = path_join(folder, "camera0");
  camera1 = path_join(folder, "camera1");

  /* Four poses, each captured by both cameras together; then calibrated as a head. */
  if (open_head(context, HEAD_URI "&camera=1", &head)) {
    config = head_config(4, &head.cameras[1]);
    sls_calibration_capture_result_init(&result);
    CHECK_OK(sls_calibration_capture(head.cameras[0], head.projector, NULL, folder, &config, NULL, NULL, NULL, &result,
                                     &error_));
    CHECK(result.cameras == 2 && result.frames == 4 && result.poses_captured == 4 && result.images_per_frame == 42);
    CHECK(manifest_frames(camera0) == 4 && manifest_frames(camera1) == 4);
    check_calibration(context, folder, unsupported);

    /* The config's mistakes, each refused before anything is captured. */
    config = head_config(4, NULL);
    CHECK_ERROR(sls_calibration_capture(head.cameras[0], head.projector, NULL, folder, &config, NULL, NULL, NULL, NULL,
                                        &error_),
                SLS_ERROR_INVALID_ARGUMENT, "config.more_cameras is NULL but config.more_camera_count is 1");
    config = head_config(4, &head.cameras[0]);
    CHECK_ERROR(sls_calibration_capture(head.cameras[0], head.projector, NULL, folder, &config, NULL, NULL, NULL, NULL,
                                        &error_),
                SLS_ERROR_INVALID_ARGUMENT, "is camera 0 of the head again");
    config = head_config(4, &head.cameras[1]);
    config.more_camera_count = 16;
    CHECK_ERROR(sls_calibration_capture(head.cameras[0], head.projector, NULL, folder, &config, NULL, NULL, NULL, NULL,
                                        &error_),
                SLS_ERROR_INVALID_ARGUMENT, "at most 16 cameras");
    config = head_config(5, &head.cameras[1]);
    CHECK_ERROR(sls_calibration_capture(head.cameras[0], head.projector, NULL, folder, &config, NULL, NULL, NULL, NULL,
                                        &error_),
                SLS_ERROR_INVALID_ARGUMENT, "not an empty folder");

    /* Resumed to five poses: both recordings continued. */
    config.resume = 1;
    sls_calibration_capture_result_init(&result);
    CHECK_OK(sls_calibration_capture(head.cameras[0], head.projector, NULL, folder, &config, NULL, NULL, NULL, &result,
                                     &error_));
    CHECK(result.resumed_from == 4 && result.frames == 5 && result.poses_captured == 1 && result.cameras == 2);
    CHECK(manifest_frames(camera0) == 5 && manifest_frames(camera1) == 5);
    /* As one camera, the head's folder holds no recording of its own to continue. */
    config.more_camera_count = 0;
    CHECK_ERROR(sls_calibration_capture(head.cameras[0], head.projector, NULL, folder, &config, NULL, NULL, NULL, NULL,
                                        &error_),
                SLS_ERROR_INVALID_ARGUMENT, "holds no recording to continue");
    close_head(&head);
  }

  /* Camera 1's recording replaced by a shorter one: the head disagrees, refused naming it. */
  {
    char* two = path_join(argv[1], "two");
    if (open_head(context, HEAD_URI "&camera=1", &head)) {
      sls_calibration_capture_config_init(&config);
      config.hand_poses = 2;
      CHECK_OK(sls_calibration_capture(head.cameras[1], head.projector, NULL, two, &config, NULL, NULL, NULL, NULL,
                                       &error_));
      close_head(&head);
    }
    /* A camera that fails at the third pose: camera 1 of another head (its own operator, who
     * has two poses to place), a third pose asked. */
    if (open_head(context, "sim://chessboard?calibration=1&preset=ci&hand_poses=2&head=chessboard&cameras=2&camera=1",
                  &head)) {
      char* fault = path_join(argv[1], "fault");
      sls_error* failure = NULL;
      sls_status status;
      config = head_config(3, &head.cameras[1]);
      config.max_retries = 0;
      sls_calibration_capture_result_init(&result);
      status = sls_calibration_capture(head.cameras[0], head.projector, NULL, fault, &config, NULL, NULL, NULL, &result,
                                       &failure);
      CHECK(status == SLS_ERROR_INVALID_ARGUMENT);
      if (failure != NULL) {
        const char* message = sls_error_message(failure);
        printf("a camera that fails at the third pose: %s\n", message);
        CHECK(strstr(message, "calibration hand pose 3 of 3") != NULL);
        CHECK(strstr(message, "camera 1 (sim://chessboard?") != NULL && strstr(message, "hand_poses=2") != NULL);
        CHECK(strstr(message, "all of its 2 poses") != NULL);
        CHECK(strstr(message, "2 frame(s) are in each of the 2 cameras' recordings") != NULL);
        sls_error_free(failure);
      }
      CHECK(result.frames == 2);
      {
        char* fault0 = path_join(fault, "camera0");
        char* fault1 = path_join(fault, "camera1");
        CHECK(manifest_frames(fault0) == 2 && manifest_frames(fault1) == 2);
        free(fault0);
        free(fault1);
      }
      free(fault);
      close_head(&head);
    }
    {
      char* kept = path_join(argv[1], "camera1-kept");
      CHECK(rename(camera1, kept) == 0);
      CHECK(rename(two, camera1) == 0);
      free(kept);
    }
    if (open_head(context, HEAD_URI "&camera=1", &head)) {
      config = head_config(6, &head.cameras[1]);
      config.resume = 1;
      CHECK_ERROR(sls_calibration_capture(head.cameras[0], head.projector, NULL, folder, &config, NULL, NULL, NULL,
                                          NULL, &error_),
                  SLS_ERROR_INVALID_ARGUMENT, "camera1 holds 2 pose(s)");
      CHECK(manifest_frames(camera0) == 5 && manifest_frames(camera1) == 2);
      close_head(&head);
    }
    free(two);
  }
  free(camera1);
  free(camera0);
  free(folder);
  sls_context_destroy(context);
  return failures != 0;
}
