/* A ChArUco board calibrated through the C API (sls_calibration.h, API 0.10), from a C99 program.
 *   test_c_calibration_charuco CAPTURE
 * CAPTURE: a simulated ChArUco calibration capture (`sls sim --calibration --board charuco
 * --preset ci --hand-poses 4 --turntable-poses 0`: 12 x 9 squares of 1.2 mm with 0.9 mm markers
 * of DICT_5X5_100, larger than the field, so each view shows part of it; its exact calibration
 * and board.json in groundtruth/).
 * Checks:
 *  - the run with the board in the config (board_kind, 11 x 8 inner corners, board_marker_m, a
 *    dictionary named as `--dictionary` takes it): every view used; the summary's board (kind,
 *    marker, dictionary) and its errors against the exact calibration within the bounds of
 *    tests/cli/test_sls_charuco.py;
 *  - the run with the board from the ground truth (the config's board all 0): the same board and
 *    the same result;
 *  - the same board sizes through an older program's struct (struct_size of API 0.9, the bytes
 *    past it saying ChArUco): a chessboard, found in no view, each view named;
 *  - the board's bad values, each refused with SLS_ERROR_INVALID_ARGUMENT naming its field.
 * Exit status 0 when every check holds; each failed check prints its line. */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <sls/sls.h>

#include "c_checks.h"

static void charuco_config(sls_calibration_config* config) {
  sls_calibration_config_init(config);
  config->board_kind = SLS_CALIBRATION_BOARD_CHARUCO;
  config->board_inner_cols = 11; /* 12 x 9 squares */
  config->board_inner_rows = 8;
  config->board_square_m = 0.0012;
  config->board_marker_m = 0.0009;
  config->board_dictionary = "5x5_100"; /* "DICT_" optional, any case, as `--dictionary` */
}

/* Calibrates `capture` with `config`; NULL (the failure printed) when the run fails. */
static sls_calibration* calibrate(sls_context* context, const char* capture, const sls_calibration_config* config) {
  sls_calibration* calibration = NULL;
  sls_error* error = NULL;
  const sls_status status = sls_calibration_run(context, capture, config, NULL, NULL, &calibration, &error);
  if (status != SLS_OK) {
    fprintf(stderr, "sls_calibration_run(%s): %s: %s\n", capture, sls_status_str(status), sls_error_message(error));
    sls_error_free(error);
    ++failures;
  }
  return calibration;
}

static void check_calibration(const sls_calibration* calibration, sls_calibration_summary* summary) {
  size_t count = 0, i;
  sls_calibration_summary_init(summary);
  CHECK_OK(sls_calibration_get_summary(calibration, summary, &error_));
  printf("ChArUco through the C API: %zu of %zu views, RMS camera %.3f px, projector %.3f px, stereo %.3f px; "
         "truth: focal %.3f %%, principal point %.1f px, baseline %.3f %%, rotation %.3f deg; %.1f s\n",
         summary->views_used, summary->views_total, summary->camera_rms_px, summary->projector_rms_px,
         summary->stereo_rms_px, 100.0 * summary->focal_rel_err, summary->principal_point_err_px,
         100.0 * summary->baseline_rel_err, summary->rotation_err_deg, summary->seconds);
  CHECK(summary->board_kind == SLS_CALIBRATION_BOARD_CHARUCO);
  CHECK(summary->board_inner_cols == 11 && summary->board_inner_rows == 8 && summary->board_square_m == 0.0012);
  CHECK(summary->board_marker_m == 0.0009);
  CHECK(summary->board_dictionary != NULL && strcmp(summary->board_dictionary, "DICT_5X5_100") == 0);
  CHECK(summary->views_total == 4 && summary->views_used == 4);
  /* The bounds of tests/cli/test_sls_charuco.py (measured at 4 poses: focal 0.57 %, principal
   * point 40 px (the projector's; the camera's 20 px), baseline 0.53 %, rotation 0.30 deg). */
  CHECK(summary->camera_rms_px > 0.0 && summary->camera_rms_px < 0.2);
  CHECK(summary->has_truth == 1);
  CHECK(summary->focal_rel_err < 0.02);
  CHECK(summary->principal_point_err_px < 60.0);
  CHECK(summary->baseline_rel_err < 0.02);
  CHECK(summary->rotation_err_deg < 1.5);
  CHECK(summary->turntable_axis_fitted == 0);
  CHECK_OK(sls_calibration_view_count(calibration, &count, &error_));
  for (i = 0; i < count; ++i) {
    sls_calibration_view view;
    sls_calibration_view_init(&view);
    CHECK_OK(sls_calibration_get_view(calibration, i, &view, &error_));
    CHECK(view.used == 1 && view.board_found == 1 && view.corners == 88);
  }
}

/* The board's bad values: refused before anything is read, the message naming the field. */
static void check_bad_values(sls_context* context, const char* capture) {
  sls_calibration_config config;
  sls_calibration* calibration = NULL;
  int bad_kind = 7;

  charuco_config(&config);
  memcpy(&config.board_kind, &bad_kind, sizeof(bad_kind)); /* what a C caller can store in an enum */
  CHECK_ERROR(sls_calibration_run(context, capture, &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "config.board_kind 7 is not an sls_calibration_board_kind");
  charuco_config(&config);
  config.board_marker_m = 0.0012;
  CHECK_ERROR(sls_calibration_run(context, capture, &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "config.board_marker_m 0.0012 m must be smaller than config.board_square_m");
  charuco_config(&config);
  config.board_marker_m = 0.0;
  CHECK_ERROR(sls_calibration_run(context, capture, &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "config.board_marker_m 0 ");
  charuco_config(&config);
  config.board_marker_m = NAN;
  CHECK_ERROR(sls_calibration_run(context, capture, &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "config.board_marker_m");
  charuco_config(&config);
  config.board_dictionary = "DICT_9X9_7";
  CHECK_ERROR(sls_calibration_run(context, capture, &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "config.board_dictionary 'DICT_9X9_7': unknown ArUco dictionary");
  charuco_config(&config);
  config.board_inner_cols = 19; /* 20 x 20 squares: 200 light ones */
  config.board_inner_rows = 19;
  config.board_dictionary = "DICT_4X4_50";
  CHECK_ERROR(sls_calibration_run(context, capture, &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "config.board_dictionary 'DICT_4X4_50': ChArUco board of 20x20 squares needs 200");
  charuco_config(&config);
  config.board_inner_cols = 1; /* 2 x 9 squares */
  CHECK_ERROR(sls_calibration_run(context, capture, &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "config.board_inner_cols 1, board_inner_rows 8: a ChArUco board of 2x9 squares");
  charuco_config(&config);
  config.board_inner_rows = 2; /* 12 x 3 squares */
  CHECK_ERROR(sls_calibration_run(context, capture, &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "a ChArUco board of 12x3 squares");
  /* A marker or a dictionary for a chessboard. */
  charuco_config(&config);
  config.board_kind = SLS_CALIBRATION_BOARD_CHESSBOARD;
  config.board_dictionary = NULL;
  CHECK_ERROR(sls_calibration_run(context, capture, &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "config.board_marker_m 0.0009 and board_dictionary '' describe a ChArUco");
  charuco_config(&config);
  config.board_kind = SLS_CALIBRATION_BOARD_CHESSBOARD;
  config.board_marker_m = 0.0;
  CHECK_ERROR(sls_calibration_run(context, capture, &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "board_dictionary '5x5_100' describe a ChArUco board");
  /* The kind with the board from the ground truth, which gives the kind itself. */
  sls_calibration_config_init(&config);
  config.board_kind = SLS_CALIBRATION_BOARD_CHARUCO;
  CHECK_ERROR(sls_calibration_run(context, capture, &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "config.board_kind 1");
  CHECK(calibration == NULL);
}

/* A program built against the 0.9 header: its struct ends at max_rms_px, so the board is a
 * chessboard whatever lies past it; the ChArUco capture then has no usable view. */
static void check_older_struct(sls_context* context, const char* capture) {
  sls_calibration_config config;
  sls_calibration* calibration = NULL;
  charuco_config(&config);
  config.struct_size = offsetof(sls_calibration_config, board_kind);
  CHECK_ERROR(sls_calibration_run(context, capture, &config, NULL, NULL, &calibration, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "frame 3: board of 11x8 inner corners not found");
  CHECK(calibration == NULL);
}

int main(int argc, char** argv) {
  sls_context* context = NULL;
  sls_calibration_config config;
  sls_calibration_summary given, from_truth;
  sls_calibration* calibration;
  if (argc != 2) {
    fprintf(stderr, "usage: %s CAPTURE\n", argv[0]);
    return 2;
  }
  CHECK(SLS_API_VERSION >= SLS_MAKE_VERSION(0, 10, 0)); /* the board's kind came with 0.10 */
  CHECK_OK(sls_context_create(SLS_API_VERSION, NULL, &context, &error_));
  if (context == NULL) return 1;
  sls_calibration_config_init(&config);
  CHECK(config.board_kind == SLS_CALIBRATION_BOARD_CHESSBOARD && config.board_marker_m == 0.0);
  CHECK(config.board_dictionary == NULL);

  check_bad_values(context, argv[1]);
  check_older_struct(context, argv[1]);

  charuco_config(&config);
  calibration = calibrate(context, argv[1], &config);
  if (calibration != NULL) check_calibration(calibration, &given);
  sls_calibration_destroy(calibration);

  /* The board from the ground truth (groundtruth/board.json): the same board, the same result. */
  sls_calibration_config_init(&config);
  calibration = calibrate(context, argv[1], &config);
  if (calibration != NULL) {
    check_calibration(calibration, &from_truth);
    CHECK(from_truth.stereo_rms_px == given.stereo_rms_px && from_truth.focal_rel_err == given.focal_rel_err);
  }
  sls_calibration_destroy(calibration);
  sls_context_destroy(context);
  return failures != 0;
}
