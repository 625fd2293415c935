/* Calibration through the C API (sls_calibration.h), from a C99 program.
 *   test_c_calibration CAPTURES SCRATCH   a library with calibration (built with OpenCV)
 *   test_c_calibration --unsupported      a library without
 * CAPTURES: ../shared/data/procam-calibration, real Gray-code captures of a 9x7-corner board
 * with 75 mm squares (five subfolders capture_0..4, and graycode_pattern/, the patterns
 * themselves, which has no board and must be rejected); SCRATCH: a folder for what the test
 * writes (created).
 * Checks, with calibration:
 *  - a run cancelled from the progress callback; a run to SLS_OK, its progress reports (one per
 *    view, then the solve, on this thread);
 *  - the summary (RMS figures, views, no truth: NaN errors, no axis), every view (the rejected
 *    one with its reason), both intrinsics (the camera's focal length within 2 % of the
 *    reference 3437 px), the extrinsics (a rigid transform), the axis getter's status without
 *    an axis;
 *  - the write refused above max_rms_px without force (nothing written), written with force, a
 *    calibration.yml with its figures;
 *  - the mistakes: NULL arguments, bad config fields and struct sizes, a missing input (named),
 *    a folder of captures without a pattern set, a view index out of range, a bad device value;
 *  - a program built against the 0.9 header (API 0.10 appended the board's kind): its smaller
 *    config, whatever lies past it, still calibrates the chessboard (three of the captures, in
 *    SCRATCH/three by symbolic links), and its smaller summary gets nothing past its end.
 * Without calibration: every function answers SLS_ERROR_UNSUPPORTED with the message, the
 * _init() functions still work, destroy(NULL) is a no-op.
 * Exit status 0 when every check holds; each failed check prints its line. */
/* POSIX mkdir for the scratch folder (C99 has none of its own). */
#define _POSIX_C_SOURCE 200809L

#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <sls/sls.h>

#include "c_checks.h"

#define UNSUPPORTED_MESSAGE "built without OpenCV: calibration is not available"

static int file_exists(const char* path) {
  FILE* file = fopen(path, "rb");
  if (file == NULL) return 0;
  fclose(file);
  return 1;
}

static sls_context* make_context(void) {
  sls_context* context = NULL;
  sls_error* error = NULL;
  if (sls_context_create(SLS_API_VERSION, NULL, &context, &error) != SLS_OK) {
    fprintf(stderr, "sls_context_create: %s\n", sls_error_message(error));
    sls_error_free(error);
    exit(2);
  }
  return context;
}

/* ---- Without calibration in the library. ---- */

static int check_unsupported(void) {
  sls_context* context = make_context();
  sls_calibration_config config;
  sls_calibration_summary summary;
  sls_intrinsics intrinsics;
  sls_calibration_view view;
  sls_calibration* calibration = (sls_calibration*)&config; /* must be set to NULL */
  double T[16], point[3], direction[3];
  size_t count = 7;

  sls_calibration_config_init(&config);
  CHECK(config.struct_size == sizeof(config) && config.max_rms_px == 1.0);
  sls_calibration_summary_init(&summary);
  sls_intrinsics_init(&intrinsics);
  sls_calibration_view_init(&view);
  CHECK(summary.struct_size == sizeof(summary) && intrinsics.struct_size == sizeof(intrinsics));
  CHECK(view.struct_size == sizeof(view));

  CHECK_ERROR(sls_calibration_run(context, "anywhere", &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_UNSUPPORTED, UNSUPPORTED_MESSAGE);
  CHECK(calibration == NULL);
  CHECK_ERROR(sls_calibration_get_summary(NULL, &summary, &error_), SLS_ERROR_UNSUPPORTED, UNSUPPORTED_MESSAGE);
  CHECK_ERROR(sls_calibration_get_intrinsics(NULL, SLS_CALIBRATION_CAMERA, &intrinsics, &error_),
              SLS_ERROR_UNSUPPORTED, UNSUPPORTED_MESSAGE);
  CHECK_ERROR(sls_calibration_get_extrinsics(NULL, T, &error_), SLS_ERROR_UNSUPPORTED, UNSUPPORTED_MESSAGE);
  CHECK_ERROR(sls_calibration_get_turntable_axis(NULL, point, direction, &error_), SLS_ERROR_UNSUPPORTED,
              UNSUPPORTED_MESSAGE);
  CHECK_ERROR(sls_calibration_view_count(NULL, &count, &error_), SLS_ERROR_UNSUPPORTED, UNSUPPORTED_MESSAGE);
  CHECK(count == 0);
  CHECK_ERROR(sls_calibration_get_view(NULL, 0, &view, &error_), SLS_ERROR_UNSUPPORTED, UNSUPPORTED_MESSAGE);
  CHECK_ERROR(sls_calibration_write(NULL, "calibration.yml", 1, &error_), SLS_ERROR_UNSUPPORTED,
              UNSUPPORTED_MESSAGE);
  count = 7;
  CHECK_ERROR(sls_calibration_camera_count(NULL, &count, &error_), SLS_ERROR_UNSUPPORTED, UNSUPPORTED_MESSAGE);
  CHECK(count == 0);
  CHECK_ERROR(sls_calibration_get_camera(NULL, 0, NULL, &intrinsics, &error_), SLS_ERROR_UNSUPPORTED,
              UNSUPPORTED_MESSAGE);
  CHECK(sls_calibration_run(context, "anywhere", NULL, NULL, NULL, &calibration, NULL) == SLS_ERROR_UNSUPPORTED);
  sls_calibration_destroy(NULL);
  sls_context_destroy(context);
  return failures != 0;
}

/* ---- With calibration. ---- */

typedef struct progress_log {
  int calls;
  int cancel_at;       /* return 0 at this call (counted from 1); 0: never */
  int sane;            /* every report well formed and in order */
  size_t last_done;
  size_t total;
  char last_detail[64];
} progress_log;

static int on_progress(const sls_calibration_progress* progress, void* user) {
  progress_log* log = (progress_log*)user;
  ++log->calls;
  if (progress == NULL || progress->struct_size != sizeof(sls_calibration_progress) || progress->stage == NULL ||
      progress->detail == NULL || strcmp(progress->stage, "calibrate") != 0 || progress->done > progress->total ||
      (log->calls > 1 && progress->done < log->last_done)) {
    log->sane = 0;
    return 1;
  }
  log->last_done = progress->done;
  log->total = progress->total;
  strncpy(log->last_detail, progress->detail, sizeof(log->last_detail) - 1);
  log->last_detail[sizeof(log->last_detail) - 1] = '\0';
  return log->calls != log->cancel_at;
}

static void progress_log_init(progress_log* log, int cancel_at) {
  memset(log, 0, sizeof(*log));
  log->cancel_at = cancel_at;
  log->sane = 1;
}

static void procam_config(sls_calibration_config* config) {
  sls_calibration_config_init(config);
  config->board_inner_cols = 9;
  config->board_inner_rows = 7;
  config->board_square_m = 0.075;
  config->pattern_set = "opencv-graycode:1024x768";
}

static void check_mistakes(sls_context* context, const char* captures) {
  sls_calibration_config config;
  sls_calibration* calibration = NULL;
  sls_calibration_summary summary;
  sls_intrinsics intrinsics;
  sls_calibration_view view;
  double T[16], point[3], direction[3];
  size_t count = 0;
  char* missing = path_join(captures, "no-such-capture");

  procam_config(&config);
  sls_calibration_summary_init(&summary);
  sls_intrinsics_init(&intrinsics);
  sls_calibration_view_init(&view);

  /* NULL arguments. */
  CHECK_ERROR(sls_calibration_run(context, captures, &config, NULL, NULL, NULL, &error_), SLS_ERROR_INVALID_ARGUMENT,
              "calibration");
  CHECK_ERROR(sls_calibration_run(NULL, captures, &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "context");
  CHECK(calibration == NULL);
  CHECK_ERROR(sls_calibration_run(context, NULL, &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "input_path");
  CHECK_ERROR(sls_calibration_get_summary(NULL, &summary, &error_), SLS_ERROR_INVALID_ARGUMENT, "calibration is NULL");
  CHECK_ERROR(sls_calibration_get_intrinsics(NULL, SLS_CALIBRATION_CAMERA, &intrinsics, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "calibration is NULL");
  CHECK_ERROR(sls_calibration_get_extrinsics(NULL, T, &error_), SLS_ERROR_INVALID_ARGUMENT, "calibration is NULL");
  CHECK_ERROR(sls_calibration_get_turntable_axis(NULL, point, direction, &error_), SLS_ERROR_INVALID_ARGUMENT,
              "calibration is NULL");
  CHECK_ERROR(sls_calibration_view_count(NULL, &count, &error_), SLS_ERROR_INVALID_ARGUMENT, "calibration is NULL");
  CHECK_ERROR(sls_calibration_get_view(NULL, 0, &view, &error_), SLS_ERROR_INVALID_ARGUMENT, "calibration is NULL");
  CHECK_ERROR(sls_calibration_write(NULL, "calibration.yml", 1, &error_), SLS_ERROR_INVALID_ARGUMENT,
              "calibration is NULL");
  sls_calibration_destroy(NULL);

  /* Bad configs, refused before anything is read. */
  config.board_inner_rows = 0;
  CHECK_ERROR(sls_calibration_run(context, captures, &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "board_inner_rows");
  procam_config(&config);
  config.board_square_m = -0.075;
  CHECK_ERROR(sls_calibration_run(context, captures, &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "board_square_m");
  procam_config(&config);
  config.max_rms_px = 0.0;
  CHECK_ERROR(sls_calibration_run(context, captures, &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "max_rms_px");
  procam_config(&config);
  config.max_obliquity_deg = 120.0;
  CHECK_ERROR(sls_calibration_run(context, captures, &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "max_obliquity_deg");
  procam_config(&config);
  config.min_projector_corner_fraction = 1.5;
  CHECK_ERROR(sls_calibration_run(context, captures, &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "min_projector_corner_fraction");
  procam_config(&config);
  config.struct_size = 0;
  CHECK_ERROR(sls_calibration_run(context, captures, &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "struct_size");
  CHECK(calibration == NULL);

  /* A missing input, named; a folder of captures whose pattern set is not named. */
  procam_config(&config);
  CHECK_ERROR(sls_calibration_run(context, missing, &config, NULL, NULL, &calibration, &error_), SLS_ERROR_NOT_FOUND,
              missing);
  config.pattern_set = NULL;
  CHECK_ERROR(sls_calibration_run(context, captures, &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "pattern set");
  CHECK(calibration == NULL);
  free(missing);
}

static void check_cancel(sls_context* context, const char* captures) {
  sls_calibration_config config;
  sls_calibration* calibration = NULL;
  progress_log log;
  procam_config(&config);
  progress_log_init(&log, 1);
  CHECK_ERROR(sls_calibration_run(context, captures, &config, on_progress, &log, &calibration, &error_),
              SLS_ERROR_CANCELLED, NULL);
  CHECK(calibration == NULL);
  CHECK(log.calls == 1 && log.sane);
}

/* A 0.9 program's structs end where 0.10 appended the board's kind, marker and dictionary. */
static void check_older_structs(sls_context* context, const char* captures, const char* scratch) {
  static const char* const kUsed[] = {"capture_0", "capture_1", "capture_2"};
  sls_calibration_config config;
  sls_calibration_summary summary, older;
  sls_calibration* calibration = NULL;
  char* three = path_join(scratch, "three");
  size_t i;
  if (mkdir(three, 0755) != 0 && errno != EEXIST) {
    fprintf(stderr, "cannot create %s\n", three);
    exit(2);
  }
  for (i = 0; i < 3; ++i) {
    char* target = path_join(captures, kUsed[i]);
    char* link = path_join(three, kUsed[i]);
    remove(link);
    CHECK(symlink(target, link) == 0);
    free(target), free(link);
  }
  /* The bytes past the older struct say ChArUco: they are not the caller's, and not read. */
  procam_config(&config);
  config.board_kind = SLS_CALIBRATION_BOARD_CHARUCO;
  config.board_marker_m = 0.05;
  config.board_dictionary = "no such dictionary";
  config.struct_size = offsetof(sls_calibration_config, board_kind);
  CHECK_OK(sls_calibration_run(context, three, &config, NULL, NULL, &calibration, &error_));
  if (calibration != NULL) {
    sls_calibration_summary_init(&summary);
    CHECK_OK(sls_calibration_get_summary(calibration, &summary, &error_));
    printf("0.9 config: %zu views used, stereo RMS %.3f px\n", summary.views_used, summary.stereo_rms_px);
    CHECK(summary.views_used == 3 && summary.stereo_rms_px > 0.0 && summary.stereo_rms_px < 0.5);
    CHECK(summary.board_kind == SLS_CALIBRATION_BOARD_CHESSBOARD && summary.board_inner_cols == 9);
    CHECK(summary.board_marker_m == 0.0 && strcmp(summary.board_dictionary, "") == 0);
    /* A 0.9 summary: filled up to its end, the bytes past it left as they were. */
    memset(&older, 0x5A, sizeof(older));
    older.struct_size = offsetof(sls_calibration_summary, board_kind);
    CHECK_OK(sls_calibration_get_summary(calibration, &older, &error_));
    CHECK(older.struct_size == offsetof(sls_calibration_summary, board_kind));
    CHECK(older.stereo_rms_px == summary.stereo_rms_px && older.axis_point_err_um != older.axis_point_err_um);
    for (i = offsetof(sls_calibration_summary, board_kind); i < sizeof(older); ++i) {
      CHECK(((const unsigned char*)&older)[i] == 0x5A);
    }
  }
  sls_calibration_destroy(calibration);
  free(three);
}

static void check_result(const sls_calibration* calibration, const progress_log* log, const char* scratch) {
  sls_calibration_summary summary;
  sls_calibration_summary uninitialised;
  sls_intrinsics camera, projector, small;
  sls_calibration_view view;
  double T[16], point[3] = {7, 7, 7}, direction[3] = {7, 7, 7};
  double column_dot = 0.0;
  size_t count = 0, i;
  int rejected = -1, used = 0, row, column;
  char* written = path_join(scratch, "calibration.yml");
  char* refused = path_join(scratch, "refused.yml");

  /* Progress: one report per view (6) before it, then the solve. */
  CHECK(log->sane);
  CHECK(log->calls == 7);
  CHECK(log->total == 6 && log->last_done == 6);
  CHECK(strcmp(log->last_detail, "solve") == 0);

  sls_calibration_summary_init(&summary);
  CHECK_OK(sls_calibration_get_summary(calibration, &summary, &error_));
  printf("RMS camera %.3f px, projector %.3f px, stereo %.3f px; views %zu used of %zu; outliers %zu + %zu; %.1f s\n",
         summary.camera_rms_px, summary.projector_rms_px, summary.stereo_rms_px, summary.views_used,
         summary.views_total, summary.camera_outliers, summary.projector_outliers, summary.seconds);
  CHECK(summary.stereo_rms_px > 0.0 && summary.stereo_rms_px < 0.5);
  CHECK(summary.camera_rms_px > 0.0 && summary.camera_rms_px < 0.5);
  CHECK(summary.projector_rms_px > 0.0 && summary.projector_rms_px < 1.0);
  CHECK(summary.views_total == 6 && summary.views_used == 5 && summary.views_rejected == 1);
  /* Outlier rejection drops a few mislocated corners, less than a view's worth (63). */
  CHECK(summary.camera_outliers + summary.projector_outliers < 63);
  CHECK(summary.turntable_axis_fitted == 0 && summary.turntable_axis_rms_px == 0.0);
  CHECK(summary.seconds > 0.0);
  CHECK(summary.board_inner_cols == 9 && summary.board_inner_rows == 7 && summary.board_square_m == 0.075);
  CHECK(summary.pattern_set != NULL && strstr(summary.pattern_set, "graycode") != NULL &&
        strstr(summary.pattern_set, "1024x768") != NULL);
  CHECK(summary.has_truth == 0);
  CHECK(isnan(summary.focal_rel_err) && isnan(summary.principal_point_err_px) && isnan(summary.baseline_rel_err));
  CHECK(isnan(summary.rotation_err_deg) && isnan(summary.axis_direction_err_deg) && isnan(summary.axis_point_err_um));
  /* A struct not initialised by sls_calibration_summary_init() is refused. */
  memset(&uninitialised, 0, sizeof(uninitialised));
  uninitialised.struct_size = 3;
  CHECK_ERROR(sls_calibration_get_summary(calibration, &uninitialised, &error_), SLS_ERROR_INVALID_ARGUMENT,
              "sls_calibration_summary_init");

  /* Views: capture_0..4 used, graycode_pattern rejected with its reason. */
  CHECK_OK(sls_calibration_view_count(calibration, &count, &error_));
  CHECK(count == 6);
  for (i = 0; i < count; ++i) {
    sls_calibration_view_init(&view);
    CHECK_OK(sls_calibration_get_view(calibration, i, &view, &error_));
    CHECK(view.name != NULL && view.rejected_reason != NULL);
    if (view.name == NULL || view.rejected_reason == NULL) continue;
    printf("view %-16s %s: camera %.3f px, projector %.3f px, tilt %.1f deg, projector corners %zu/%zu\n", view.name,
           view.used ? "used" : view.rejected_reason, view.camera_rms_px, view.projector_rms_px, view.obliquity_deg,
           view.projector_corners_valid, view.corners);
    CHECK(view.corners == 63 && view.has_turntable_angle == 0);
    if (view.used) {
      ++used;
      CHECK(view.rejected_reason[0] == '\0' && view.board_found == 1);
      CHECK(strncmp(view.name, "capture_", 8) == 0);
      CHECK(view.camera_rms_px > 0.0 && view.camera_rms_px < 1.0 && view.projector_rms_px > 0.0);
      CHECK(view.obliquity_deg > 0.0 && view.obliquity_deg < 65.0);
      CHECK(view.projector_corners_valid >= 32 && view.projector_corners_valid <= 63);
      CHECK(view.decoded_fraction > 0.0 && view.decoded_fraction <= 1.0);
    } else {
      rejected = (int)i;
      CHECK(view.rejected_reason[0] != '\0');
      CHECK(strcmp(view.name, "graycode_pattern") == 0);
    }
  }
  CHECK(used == 5 && rejected == 5);
  sls_calibration_view_init(&view);
  CHECK_ERROR(sls_calibration_get_view(calibration, count, &view, &error_), SLS_ERROR_INVALID_ARGUMENT,
              "out of range");

  /* Intrinsics: the camera's focal length against the reference (calibration_result.xml). */
  sls_intrinsics_init(&camera);
  sls_intrinsics_init(&projector);
  CHECK_OK(sls_calibration_get_intrinsics(calibration, SLS_CALIBRATION_CAMERA, &camera, &error_));
  CHECK_OK(sls_calibration_get_intrinsics(calibration, SLS_CALIBRATION_PROJECTOR, &projector, &error_));
  printf("camera fx %.1f fy %.1f cx %.1f cy %.1f k1 %.4f k2 %.4f; projector fx %.1f fy %.1f cx %.1f cy %.1f\n",
         camera.fx, camera.fy, camera.cx, camera.cy, camera.k1, camera.k2, projector.fx, projector.fy, projector.cx,
         projector.cy);
  CHECK(camera.width == 1280 && camera.height == 1024);
  CHECK(fabs(camera.fx - 3437.0) < 0.02 * 3437.0 && fabs(camera.fy - camera.fx) < 0.02 * camera.fx);
  CHECK(fabs(camera.cx - 640.0) < 200.0 && fabs(camera.cy - 512.0) < 200.0);
  CHECK(camera.k3 == 0.0); /* estimate_k3 off */
  CHECK(projector.width == 1024 && projector.height == 768);
  CHECK(projector.fx > 0.0 && projector.fy > 0.0 && projector.cx > 0.0 && projector.cy > 0.0);
  sls_intrinsics_init(&small);
  CHECK_ERROR(sls_calibration_get_intrinsics(calibration, (sls_calibration_device)7, &small, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "sls_calibration_device");
  CHECK_ERROR(sls_calibration_get_intrinsics(calibration, SLS_CALIBRATION_CAMERA, NULL, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "intrinsics");

  /* Extrinsics: a rigid transform with a baseline of centimetres to a metre. */
  CHECK_OK(sls_calibration_get_extrinsics(calibration, T, &error_));
  CHECK(T[12] == 0.0 && T[13] == 0.0 && T[14] == 0.0 && T[15] == 1.0);
  for (row = 0; row < 3; ++row) {
    for (column = 0; column < 3; ++column) {
      double dot = T[row] * T[column] + T[4 + row] * T[4 + column] + T[8 + row] * T[8 + column];
      column_dot += fabs(dot - (row == column ? 1.0 : 0.0));
    }
  }
  CHECK(column_dot < 1e-9);
  {
    double baseline = sqrt(T[3] * T[3] + T[7] * T[7] + T[11] * T[11]);
    printf("baseline %.4f m\n", baseline);
    CHECK(baseline > 0.01 && baseline < 1.0);
  }
  CHECK_ERROR(sls_calibration_get_extrinsics(calibration, NULL, &error_), SLS_ERROR_INVALID_ARGUMENT,
              "T_camera_projector");

  /* One camera: camera 0 is the camera above, at the identity; there is no camera 1. */
  {
    sls_calibration_camera only;
    sls_intrinsics lens;
    CHECK_OK(sls_calibration_camera_count(calibration, &count, &error_));
    CHECK(count == 1);
    sls_calibration_camera_init(&only);
    sls_intrinsics_init(&lens);
    CHECK_OK(sls_calibration_get_camera(calibration, 0, &only, &lens, &error_));
    CHECK(lens.fx == camera.fx && lens.cy == camera.cy && only.stereo_rms_px == summary.stereo_rms_px);
    CHECK(only.T_camera0_camera[0] == 1.0 && only.T_camera0_camera[3] == 0.0 && only.T_camera0_camera[15] == 1.0);
    CHECK(only.camera_camera_views == 0 && only.has_truth == 0 && isnan(only.focal_rel_err));
    CHECK_ERROR(sls_calibration_get_camera(calibration, 1, &only, NULL, &error_), SLS_ERROR_INVALID_ARGUMENT,
                "out of range");
    CHECK_ERROR(sls_calibration_get_camera(calibration, 0, NULL, NULL, &error_), SLS_ERROR_INVALID_ARGUMENT,
                "both NULL");
  }

  /* No turntable in a folder of captures: no axis, said so, the arrays untouched. */
  CHECK_ERROR(sls_calibration_get_turntable_axis(calibration, point, direction, &error_), SLS_ERROR_NOT_FOUND,
              "no turntable axis");
  CHECK(point[0] == 7 && direction[2] == 7);

  /* The write: refused above max_rms_px (the config's 0.01 px) without force, written with it. */
  remove(written);
  remove(refused);
  CHECK_ERROR(sls_calibration_write(calibration, refused, 0, &error_), SLS_ERROR_INVALID_ARGUMENT, "max_rms_px");
  CHECK_ERROR(sls_calibration_write(calibration, refused, 0, &error_), SLS_ERROR_INVALID_ARGUMENT, "force");
  CHECK(!file_exists(refused));
  CHECK_OK(sls_calibration_write(calibration, written, 1, &error_));
  CHECK(file_contains(written, "%YAML:1.0") && file_contains(written, "camera_rms_px"));
  CHECK(file_contains(written, "projector_rms_px") && file_contains(written, "reprojection_rms_px"));
  CHECK_ERROR(sls_calibration_write(calibration, NULL, 1, &error_), SLS_ERROR_INVALID_ARGUMENT, "path");
  {
    char* unwritable = path_join(scratch, "no-such-folder/calibration.yml");
    CHECK_ERROR(sls_calibration_write(calibration, unwritable, 1, &error_), SLS_ERROR_IO, "no-such-folder");
    free(unwritable);
  }
  free(written), free(refused);
}

static int check_calibration(const char* captures, const char* scratch) {
  sls_context* context = make_context();
  sls_calibration_config config;
  sls_calibration* calibration = NULL;
  progress_log log;
  sls_error* error = NULL;
  sls_status status;

  CHECK(SLS_API_VERSION >= SLS_MAKE_VERSION(0, 3, 0)); /* sls_calibration_* came with 0.3 */
  sls_calibration_config_init(&config);
  CHECK(config.struct_size == sizeof(config) && config.board_inner_cols == 0 && config.board_square_m == 0.0);
  CHECK(config.pattern_set == NULL && config.estimate_k3 == 0 && config.max_obliquity_deg == 65.0);
  CHECK(config.min_projector_corner_fraction == 0.5 && config.max_rms_px == 1.0);

  check_mistakes(context, captures);
  check_cancel(context, captures);
  check_older_structs(context, captures, scratch);

  procam_config(&config);
  config.max_rms_px = 0.01; /* far below any real calibration: the write must refuse */
  progress_log_init(&log, 0);
  status = sls_calibration_run(context, captures, &config, on_progress, &log, &calibration, &error);
  if (status != SLS_OK) {
    fprintf(stderr, "sls_calibration_run(%s): %s: %s\n", captures, sls_status_str(status), sls_error_message(error));
    sls_error_free(error);
    sls_context_destroy(context);
    return 1;
  }
  CHECK(calibration != NULL && error == NULL);
  /* The context is not kept: the result outlives it. */
  sls_context_destroy(context);
  check_result(calibration, &log, scratch);
  sls_calibration_destroy(calibration);
  return failures != 0;
}

int main(int argc, char** argv) {
  if (argc == 2 && strcmp(argv[1], "--unsupported") == 0) return check_unsupported();
  if (argc != 3) {
    fprintf(stderr, "usage: %s CAPTURES SCRATCH | %s --unsupported\n", argv[0], argv[0]);
    return 2;
  }
  if (mkdir(argv[2], 0755) != 0 && errno != EEXIST) {
    fprintf(stderr, "cannot create %s\n", argv[2]);
    return 2;
  }
  return check_calibration(argv[1], argv[2]);
}
