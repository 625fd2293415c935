/* A head of two cameras calibrated through the C API (sls_calibration.h, API 0.8), from a C99
 * program.
 *   test_c_calibration_head HEAD SCRATCH
 * HEAD: a simulated two-camera calibration capture (`sls sim --calibration --cameras 2 --preset
 * ci --hand-poses 3 --turntable-poses 0`: camera0/ and camera1/, the exact calibration in
 * groundtruth/); SCRATCH: a folder for what the test writes (created).
 * Checks: the run to SLS_OK on the head's folder; two cameras; camera 0 at the identity, its
 * lens the one sls_calibration_get_intrinsics() gives; camera 1 about 50 degrees round from
 * camera 0 (the simulator mirrors it across the projector), its figures and truth filled;
 * an index out of range; the write, whose file carries camera 1.
 * Exit status 0 when every check holds; each failed check prints its line. */
/* POSIX mkdir for the scratch folder (C99 has none of its own). */
#define _POSIX_C_SOURCE 200809L

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <sls/sls.h>

#include "c_checks.h"

/* The rotation angle of a row-major 4x4 rigid transform, degrees. */
static double rotation_deg(const double T[16]) {
  double cosine = 0.5 * (T[0] + T[5] + T[10] - 1.0);
  if (cosine > 1.0) cosine = 1.0;
  if (cosine < -1.0) cosine = -1.0;
  return acos(cosine) * 180.0 / 3.14159265358979323846;
}

static void check_head(const sls_calibration* calibration, const char* scratch) {
  sls_calibration_camera cameras[2];
  sls_intrinsics lenses[2], primary;
  size_t count = 0, k;
  char written[4096];

  CHECK_OK(sls_calibration_camera_count(calibration, &count, &error_));
  CHECK(count == 2);
  for (k = 0; k < 2; ++k) {
    sls_calibration_camera_init(&cameras[k]);
    sls_intrinsics_init(&lenses[k]);
    CHECK_OK(sls_calibration_get_camera(calibration, k, &cameras[k], &lenses[k], &error_));
    printf("camera%zu: fx %.1f, camera %.3f px, projector %.3f px, stereo %.3f px, %zu views; against camera0 %.3f px "
           "from %zu views, %.2f deg; truth focal %.4f %%, pp %.2f px, baseline %.4f %%, rotation %.4f deg\n",
           k, lenses[k].fx, cameras[k].camera_rms_px, cameras[k].projector_rms_px, cameras[k].stereo_rms_px,
           cameras[k].views_used, cameras[k].camera_camera_rms_px, cameras[k].camera_camera_views,
           rotation_deg(cameras[k].T_camera0_camera), 100.0 * cameras[k].focal_rel_err,
           cameras[k].principal_point_err_px, 100.0 * cameras[k].camera_camera_baseline_rel_err,
           cameras[k].camera_camera_rotation_err_deg);
    CHECK(cameras[k].camera_rms_px > 0.0 && cameras[k].projector_rms_px > 0.0 && cameras[k].stereo_rms_px > 0.0);
    CHECK(cameras[k].views_used == 3);
    CHECK(cameras[k].has_truth == 1 && cameras[k].focal_rel_err >= 0.0 && cameras[k].principal_point_err_px >= 0.0);
    CHECK(lenses[k].width == 400 && lenses[k].height == 300 && lenses[k].fx > 0.0);
  }
  /* Camera 0: the primary camera, at the identity; the getters above describe it. */
  sls_intrinsics_init(&primary);
  CHECK_OK(sls_calibration_get_intrinsics(calibration, SLS_CALIBRATION_CAMERA, &primary, &error_));
  CHECK(primary.fx == lenses[0].fx && primary.cx == lenses[0].cx);
  CHECK(rotation_deg(cameras[0].T_camera0_camera) == 0.0 && cameras[0].T_camera0_camera[3] == 0.0);
  CHECK(cameras[0].camera_camera_views == 0 && cameras[0].camera_camera_rms_px == 0.0);
  CHECK(isnan(cameras[0].camera_camera_baseline_rel_err) && isnan(cameras[0].camera_camera_rotation_err_deg));
  /* Camera 1: mirrored across the projector, 2 x 25 degrees round the focus. */
  CHECK(fabs(rotation_deg(cameras[1].T_camera0_camera) - 50.0) < 2.0);
  CHECK(cameras[1].camera_camera_views == 3);
  CHECK(cameras[1].camera_camera_rms_px > 0.0 && cameras[1].camera_camera_rms_px < 0.5);
  CHECK(cameras[1].camera_camera_baseline_rel_err < 0.2 && cameras[1].camera_camera_rotation_err_deg < 5.0);
  CHECK(cameras[1].T_camera0_camera[15] == 1.0 && cameras[1].T_camera0_camera[12] == 0.0);
  CHECK_ERROR(sls_calibration_get_camera(calibration, 2, &cameras[0], NULL, &error_), SLS_ERROR_INVALID_ARGUMENT,
              "the head has 2 cameras");

  snprintf(written, sizeof(written), "%s/head.yml", scratch);
  remove(written);
  CHECK_OK(sls_calibration_write(calibration, written, 1, &error_));
  CHECK(file_contains(written, "camera_count: 2") && file_contains(written, "T_camera0_camera1: !!opencv-matrix"));
  CHECK(file_contains(written, "camera1_matrix: !!opencv-matrix"));
}

int main(int argc, char** argv) {
  sls_context* context = NULL;
  sls_calibration* calibration = NULL;
  sls_error* error = NULL;
  sls_status status;
  if (argc != 3) {
    fprintf(stderr, "usage: %s HEAD SCRATCH\n", argv[0]);
    return 2;
  }
  if (mkdir(argv[2], 0755) != 0 && errno != EEXIST) {
    fprintf(stderr, "cannot create %s\n", argv[2]);
    return 2;
  }
  if (sls_context_create(SLS_API_VERSION, NULL, &context, &error) != SLS_OK) {
    fprintf(stderr, "sls_context_create: %s\n", sls_error_message(error));
    sls_error_free(error);
    return 2;
  }
  CHECK(SLS_API_VERSION >= SLS_MAKE_VERSION(0, 8, 0)); /* the cameras of a head came with 0.8 */
  /* The board and the pattern set come from the simulated capture itself. */
  status = sls_calibration_run(context, argv[1], NULL, NULL, NULL, &calibration, &error);
  sls_context_destroy(context);
  if (status != SLS_OK) {
    fprintf(stderr, "sls_calibration_run(%s): %s: %s\n", argv[1], sls_status_str(status), sls_error_message(error));
    sls_error_free(error);
    return 1;
  }
  check_head(calibration, argv[2]);
  sls_calibration_destroy(calibration);
  return failures != 0;
}
