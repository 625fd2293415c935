/* A turntable scan from C: captures one revolution from the scanner's devices (by URI; the
 * simulated scanner by default), fuses it, closes the loop and writes the model.
 *
 *   c_turntable_scan CALIBRATION.yml OUT_FOLDER [FRAMES] [DEVICE_URI]
 *
 * CALIBRATION.yml is the head's calibration (for the simulator: the one `sls sim` writes into
 * its recordings); OUT_FOLDER receives recording/, cloud.ply, mesh.ply and trajectory.txt.
 * Build against an installed slscan with the CMakeLists.txt beside this file
 * (find_package(slscan)) or the Makefile (pkg-config slscan). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <sls/sls.h>

/* Prints each frame as it is fused (the scan calls this on its own thread, in frame order). */
static void on_frame(const sls_frame_report* report, void* user) {
  static const char* const kStatus[] = {"fused", "lost", "skipped"};
  (void)user;
  printf("frame %d of %zu: %s%s%s (%.0f ms)\n", report->index + 1, report->recording_frames,
         kStatus[report->status], report->reason[0] != '\0' ? ": " : "", report->reason, report->total_ms);
  fflush(stdout);
}

static int fail(const char* what, sls_status status, sls_error* error) {
  fprintf(stderr, "%s failed: %s: %s\n", what, sls_status_str(status), sls_error_message(error));
  sls_error_free(error);
  return 1;
}

/* folder + "/" + name in `out` (of `size` bytes); 0 when it does not fit. */
static int join(char* out, size_t size, const char* folder, const char* name) {
  const int n = snprintf(out, size, "%s/%s", folder, name);
  return n > 0 && (size_t)n < size;
}

int main(int argc, char** argv) {
  char recording[4096], cloud[4096], mesh[4096], trajectory[4096];
  const char* uri = argc > 4 ? argv[4] : "sim://knurled-knob?preset=ci";
  sls_context* context = NULL;
  sls_scan* scan = NULL;
  sls_error* error = NULL;
  sls_scan_config config;
  sls_capture_config capture;
  sls_scan_summary summary;
  sls_loop_closure loop;
  sls_status status;
  if (argc < 3 || argc > 5) {
    fprintf(stderr, "usage: %s CALIBRATION.yml OUT_FOLDER [FRAMES] [DEVICE_URI]\n", argv[0]);
    return 2;
  }
  if (!join(recording, sizeof recording, argv[2], "recording") || !join(cloud, sizeof cloud, argv[2], "cloud.ply") ||
      !join(mesh, sizeof mesh, argv[2], "mesh.ply") || !join(trajectory, sizeof trajectory, argv[2], "trajectory.txt")) {
    fprintf(stderr, "%s: the output folder's path is too long\n", argv[0]);
    return 2;
  }

  status = sls_context_create(SLS_API_VERSION, NULL, &context, &error);
  if (status != SLS_OK) return fail("sls_context_create", status, error);
  printf("%s\n", sls_get_build_info());
  /* The defaults (GTSDF fusion, online deformation, an automatic volume), with the turntable's
   * angles about the calibrated axis as each frame's first guess: a knurled object turned by
   * 10 degrees looks alike to depth alone. */
  sls_scan_config_init(&config);
  config.use_turntable_prior = 1;
  status = sls_scan_create(context, &config, &scan, &error);
  sls_context_destroy(context); /* the scan does not need it any more */
  if (status != SLS_OK) return fail("sls_scan_create", status, error);
  status = sls_scan_set_frame_callback(scan, on_frame, NULL, &error);
  if (status != SLS_OK) goto failed;

  /* One device URI for camera, projector and turntable: the simulated head is all three. */
  sls_capture_config_init(&capture);
  capture.camera_uri = uri;
  capture.projector_uri = uri;
  capture.turntable_uri = uri;
  capture.calibration_path = argv[1];
  capture.recording_path = recording;
  capture.frames = argc > 3 ? atoi(argv[3]) : 0; /* 0: the turntable's 36 stops */
  status = sls_scan_run_devices(scan, &capture, &error);
  if (status != SLS_OK) goto failed;

  sls_scan_summary_init(&summary);
  status = sls_scan_get_summary(scan, &summary, &error);
  if (status != SLS_OK) goto failed;
  printf("fused %zu of %zu frames (%zu lost, %zu skipped), voxels of %.1f um\n", summary.fused, summary.frames,
         summary.lost, summary.skipped, summary.voxel_size_m * 1e6);

  /* A whole revolution ends where it began: close the loop (a partial one is reported, not
   * fatal: the model is written as tracked). */
  sls_loop_closure_init(&loop);
  status = sls_scan_close_loop(scan, &loop, &error);
  if (status == SLS_OK) {
    printf("loop closed: the last pose moved %.1f um, %.4f deg\n", loop.last_pose_correction_m * 1e6,
           loop.last_pose_correction_deg);
  } else {
    printf("loop not closed: %s\n", sls_error_message(error));
    sls_error_free(error);
    error = NULL;
  }

  status = sls_scan_write_cloud(scan, cloud, &error);
  if (status == SLS_OK) status = sls_scan_write_mesh(scan, mesh, &error);
  if (status == SLS_OK) status = sls_scan_write_trajectory(scan, trajectory, &error);
  if (status != SLS_OK) goto failed;
  printf("wrote %s, %s and %s\n", cloud, mesh, trajectory);
  sls_scan_destroy(scan);
  return 0;

failed:
  sls_scan_destroy(scan);
  return fail("the scan", status, error);
}
