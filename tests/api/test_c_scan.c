/* Scans through the C API, from a C99 program, as an OEM would run them.
 *   test_c_scan RECORDING SCRATCH
 * RECORDING: a depth-mode recording of the simulated knurled knob (ci preset, 36 frames per
 * revolution) with its ground truth; SCRATCH: an empty folder for what the test writes.
 * Checks:
 *  - a tracked turntable scan of RECORDING, cancelled from the frame callback after frame k:
 *    one callback per frame in order, sane reports, poses against the ground truth, the run
 *    returns SLS_ERROR_CANCELLED and keeps the model, whose cloud, mesh and trajectory files
 *    are valid; a cancel is final;
 *  - the same scan cancelled from another thread while it runs;
 *  - the whole revolution scanned with online deformation (a config of the size before
 *    online_deformation: the default, on), then the loop closed (sls_scan_close_loop): its
 *    result, the summary, and the writes, which give the closed model and poses; the
 *    mistakes of a loop closure (before a run, deformation off, a run that fused nothing, a
 *    bad struct, during a run);
 *  - sim:// devices captured into a recording and scanned (sls_scan_run_devices), to SLS_OK
 *    (the camera never moves: no loop to close, said clearly, the model kept);
 *  - sim:// devices with a turntable, fused while they capture and cancelled from the callback:
 *    the model fused so far is written, the recording keeps every frame captured and scans again;
 *  - the mistakes: NULL handles, bad configs, a missing or corrupt recording, a recording of
 *    which no frame can be fused, a run or a query on a running scan (from the callback).
 * Exit status 0 when every check holds; each failed check prints its line. */
/* POSIX threads for the cancel from another thread (C99 has none of its own). */
#define _POSIX_C_SOURCE 200809L

#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <sls/sls.h>

#include "c_checks.h"
#include "c_scan_files.h"

/* ---- The frame callback's record. ---- */

#define MAX_FRAMES 64

typedef struct frame_log {
  sls_scan* scan;
  int cancel_after; /* cancel from the callback after this frame index; -1: never */
  int count;
  int out_of_order;
  int index[MAX_FRAMES];
  sls_frame_status status[MAX_FRAMES];
  double T_world_camera[MAX_FRAMES][16];
  int tracked[MAX_FRAMES];
  int sane[MAX_FRAMES]; /* struct size, strings, counts, times */
  int keyframes;        /* frames reported as keyframes */
  size_t max_deformation_nodes;
  double deform_ms;     /* the frame loop's share, summed */
  char first_reason[256];
  sls_status busy_summary, busy_run, busy_callback, busy_write, busy_close; /* calls on the running scan */
} frame_log;

static void frame_log_init(frame_log* log, sls_scan* scan, int cancel_after) {
  memset(log, 0, sizeof(*log));
  log->scan = scan;
  log->cancel_after = cancel_after;
  log->busy_summary = log->busy_run = log->busy_callback = log->busy_write = log->busy_close = SLS_OK;
}

static void on_frame(const sls_frame_report* report, void* user) {
  frame_log* log = (frame_log*)user;
  int n = log->count;
  int times_ok, deformation_ok;
  if (n >= MAX_FRAMES) return;
  if (n > 0 && report->index != log->index[n - 1] + 1) log->out_of_order = 1;
  log->index[n] = report->index;
  log->status[n] = report->status;
  memcpy(log->T_world_camera[n], report->T_world_camera, sizeof(report->T_world_camera));
  log->tracked[n] = report->tracked;
  times_ok = report->read_ms >= 0 && report->decode_ms >= 0 && report->track_ms >= 0 && report->integrate_ms >= 0 &&
             report->move_ms >= 0 && report->raycast_ms >= 0 && report->deform_ms >= 0 &&
             fabs(report->total_ms - (report->read_ms + report->decode_ms + report->track_ms + report->integrate_ms +
                                      report->move_ms + report->raycast_ms + report->deform_ms)) < 1e-6;
  /* A keyframe is a fused frame; the worker's counts never exceed what was queued. */
  deformation_ok = (report->keyframe == 0 || report->keyframe == 1) &&
                   (!report->keyframe || report->status == SLS_FRAME_FUSED) &&
                   report->deformation_nodes <= (size_t)report->index + 1 && report->deformation_solve_ms >= 0;
  log->keyframes += report->keyframe;
  if (report->deformation_nodes > log->max_deformation_nodes) log->max_deformation_nodes = report->deformation_nodes;
  log->deform_ms += report->deform_ms;
  log->sane[n] = report->struct_size == sizeof(sls_frame_report) && report->reason != NULL && deformation_ok &&
                 (report->status == SLS_FRAME_FUSED) == (report->reason[0] == '\0') &&
                 report->recording_frames > (size_t)report->index && times_ok &&
                 (report->status == SLS_FRAME_SKIPPED || report->depth_pixels > 0) &&
                 (!report->tracked || (report->inlier_fraction > 0 && report->inlier_fraction <= 1 &&
                                       report->residual_rms_m >= 0));
  if (n == 0) {
    sls_scan_summary summary;
    strncpy(log->first_reason, report->reason, sizeof(log->first_reason) - 1);
    /* The scan is running: everything but a cancel is refused, and nothing deadlocks. */
    sls_scan_summary_init(&summary);
    log->busy_summary = sls_scan_get_summary(log->scan, &summary, NULL);
    log->busy_run = sls_scan_run_recording(log->scan, "elsewhere", NULL);
    log->busy_callback = sls_scan_set_frame_callback(log->scan, NULL, NULL, NULL);
    log->busy_write = sls_scan_write_cloud(log->scan, "never.ply", NULL);
    log->busy_close = sls_scan_close_loop(log->scan, NULL, NULL);
  }
  log->count = n + 1;
  if (report->index == log->cancel_after) sls_scan_cancel(log->scan, NULL);
}

static sls_scan* make_scan(sls_context* context, int turntable_prior) {
  sls_scan_config config;
  sls_scan* scan = NULL;
  sls_error* error = NULL;
  sls_scan_config_init(&config);
  config.use_turntable_prior = turntable_prior;
  config.max_voxels = 2e6; /* a ~70 um volume of the 12 x 9 mm view: fast on two cores */
  if (!succeeded(sls_scan_create(context, &config, &scan, &error), error, __LINE__)) return NULL;
  return scan;
}

/* A capture from `uri` as camera and projector (and turntable, unless NULL) into `recording`. */
static void sim_capture(sls_capture_config* capture, const char* uri, const char* turntable, const char* calibration,
                        const char* recording, int frames) {
  sls_capture_config_init(capture);
  capture->camera_uri = uri;
  capture->projector_uri = uri;
  capture->turntable_uri = turntable;
  capture->calibration_path = calibration;
  capture->recording_path = recording;
  capture->frames = frames;
}

/* A turntable scan of the recording (10 degree steps, the turntable prior), cancelled from the
 * callback after frame `cancel_after`. */
static void check_cancelled_turntable_scan(sls_context* context, const char* recording, const char* scratch) {
  enum { kCancelAfter = 4 };
  static frame_log log;
  double truth[kCancelAfter + 1][16];
  char* truth_path = path_join(recording, "groundtruth/trajectory.txt");
  char* cloud = path_join(scratch, "cancelled_cloud.ply");
  char* mesh = path_join(scratch, "cancelled_mesh.ply");
  char* trajectory = path_join(scratch, "cancelled_trajectory.txt");
  sls_scan_summary summary;
  sls_error* error = NULL;
  sls_status status;
  int i;
  sls_scan* scan = make_scan(context, 1);
  if (scan == NULL) return;
  frame_log_init(&log, scan, kCancelAfter);
  CHECK_OK(sls_scan_set_frame_callback(scan, on_frame, &log, &error_));

  status = sls_scan_run_recording(scan, recording, &error);
  check_error(status, SLS_ERROR_CANCELLED, error, "cancelled", __LINE__);
  /* One callback per frame, in order, the last the frame the cancel came from. */
  CHECK(log.count == kCancelAfter + 1);
  CHECK(!log.out_of_order);
  CHECK(log.index[0] == 0 && log.index[log.count - 1] == kCancelAfter);
  for (i = 0; i < log.count; ++i) {
    CHECK(log.sane[i]);
    CHECK(log.status[i] == SLS_FRAME_FUSED);
    CHECK(is_rigid(log.T_world_camera[i]));
    CHECK(log.tracked[i] == (i > 0)); /* the first frame places the world */
  }
  CHECK(log.first_reason[0] == '\0');
  CHECK(log.busy_summary == SLS_ERROR_BUSY && log.busy_run == SLS_ERROR_BUSY);
  CHECK(log.busy_callback == SLS_ERROR_BUSY && log.busy_write == SLS_ERROR_BUSY);
  CHECK(log.busy_close == SLS_ERROR_BUSY);

  /* Poses: world is the first camera, so frame i's pose is the camera's motion since frame 0;
   * the truth's is T_object_camera(0)^-1 T_object_camera(i). The camera turns 10 degrees a
   * frame about the axis ~0.12 m away (~20 mm); tracked, it is within 0.25 mm and 0.1 degree
   * (about 50 um and 0.04 degree after 4 frames when this test was written). */
  CHECK(read_tum(truth_path, truth, kCancelAfter + 1) == kCancelAfter + 1);
  for (i = 1; i < log.count; ++i) {
    double true_motion[16], translation_m, rotation_deg, moved_m, turned_deg;
    relative_pose(truth[0], truth[i], true_motion);
    pose_difference(truth[0], truth[i], &moved_m, &turned_deg);
    pose_difference(true_motion, log.T_world_camera[i], &translation_m, &rotation_deg);
    printf("frame %d: moved %.2f mm, %.2f deg; pose error %.1f um, %.4f deg\n", i, moved_m * 1e3, turned_deg,
           translation_m * 1e6, rotation_deg);
    CHECK(turned_deg > 9.0 * i && turned_deg < 11.0 * i); /* the truth is what the test thinks */
    CHECK(translation_m < 0.25e-3);
    CHECK(rotation_deg < 0.1);
  }

  /* The model keeps the fused frames: summary and files. */
  sls_scan_summary_init(&summary);
  CHECK_OK(sls_scan_get_summary(scan, &summary, &error_));
  CHECK(summary.frames == kCancelAfter + 1 && summary.fused == kCancelAfter + 1);
  CHECK(summary.lost == 0 && summary.skipped == 0);
  CHECK(summary.cancelled == 1);
  CHECK(summary.voxel_size_m > 20e-6 && summary.voxel_size_m < 200e-6);
  CHECK_OK(sls_scan_write_cloud(scan, cloud, &error_));
  CHECK_OK(sls_scan_write_mesh(scan, mesh, &error_));
  CHECK_OK(sls_scan_write_trajectory(scan, trajectory, &error_));
  check_cloud_file(cloud);
  check_mesh_file(mesh);
  CHECK(count_tum_poses(trajectory) == kCancelAfter + 1);

  /* A cancel is final: a new run stops before reading anything and the results stay. */
  log.count = 0;
  CHECK_ERROR(sls_scan_run_recording(scan, recording, &error_), SLS_ERROR_CANCELLED, "cancelled");
  CHECK(log.count == 0);
  CHECK_OK(sls_scan_get_summary(scan, &summary, &error_));
  CHECK(summary.fused == kCancelAfter + 1);
  CHECK_ERROR(sls_scan_write_cloud(scan, "/nonexistent-folder/cloud.ply", &error_), SLS_ERROR_IO,
              "/nonexistent-folder/cloud.ply");
  sls_scan_destroy(scan);
  free(truth_path), free(cloud), free(mesh), free(trajectory);
}

/* 1 when two files can be read and their contents differ. */
static int files_differ(const char* a, const char* b) {
  int differ = 0;
  FILE* file_a = fopen(a, "rb");
  FILE* file_b = fopen(b, "rb");
  if (file_a != NULL && file_b != NULL) {
    int byte_a, byte_b;
    do {
      byte_a = fgetc(file_a);
      byte_b = fgetc(file_b);
    } while (byte_a == byte_b && byte_a != EOF);
    differ = byte_a != byte_b;
  }
  if (file_a != NULL) fclose(file_a);
  if (file_b != NULL) fclose(file_b);
  return differ;
}

/* The whole revolution (36 frames, 10 degrees apart, the turntable prior) with online
 * deformation, from a config of the size a caller compiled before online_deformation has (its
 * struct ends at max_voxels: the field past it is not read, deformation keeps its default, on),
 * then the loop closed: the last frame registers to the first, and the closed model and
 * trajectory are what the writes give afterwards. */
static void check_loop_closure(sls_context* context, const char* recording, const char* scratch) {
  enum { kFrames = 36 };
  static frame_log log;
  static double truth[kFrames][16], before[kFrames][16], after[kFrames][16];
  char* truth_path = path_join(recording, "groundtruth/trajectory.txt");
  char* cloud_before = path_join(scratch, "loop_open_cloud.ply");
  char* cloud_after = path_join(scratch, "loop_closed_cloud.ply");
  char* mesh_after = path_join(scratch, "loop_closed_mesh.ply");
  char* trajectory_before = path_join(scratch, "loop_open_trajectory.txt");
  char* trajectory_after = path_join(scratch, "loop_closed_trajectory.txt");
  sls_scan_config config;
  sls_scan_summary summary;
  sls_loop_closure loop;
  sls_scan* scan = NULL;
  sls_error* error = NULL;
  sls_status status;
  double true_motion[16], translation_m, rotation_deg, drift_m, drift_deg, closed_m, closed_deg;
  int i, last = kFrames - 1;
  sls_scan_config_init(&config);
  CHECK(config.online_deformation == 1);
  config.use_turntable_prior = 1;
  config.max_voxels = 2e6;
  config.online_deformation = 0; /* past the old struct's end: not read */
  config.struct_size = offsetof(sls_scan_config, max_voxels) + sizeof(double);
  if (!succeeded(sls_scan_create(context, &config, &scan, &error), error, __LINE__)) return;
  frame_log_init(&log, scan, -1);
  CHECK_OK(sls_scan_set_frame_callback(scan, on_frame, &log, &error_));
  CHECK_OK(sls_scan_run_recording(scan, recording, &error_));
  CHECK(log.count == kFrames && !log.out_of_order);
  for (i = 0; i < log.count; ++i) CHECK(log.sane[i] && log.status[i] == SLS_FRAME_FUSED);
  /* Deformation ran: keyframes as the turntable turned (a node every 5 degrees at most, so
   * about one a frame), the worker's graph growing behind them. */
  printf("online deformation: %d keyframes, up to %lu nodes seen by the frame loop, %.1f ms in the frame loop\n",
         log.keyframes, (unsigned long)log.max_deformation_nodes, log.deform_ms);
  CHECK(log.keyframes >= 4 && log.keyframes <= kFrames);
  CHECK(log.max_deformation_nodes > 0 && log.max_deformation_nodes <= (size_t)log.keyframes);

  sls_scan_summary_init(&summary);
  CHECK_OK(sls_scan_get_summary(scan, &summary, &error_));
  CHECK(summary.fused == kFrames && summary.cancelled == 0);
  CHECK(summary.deformation_nodes == (size_t)log.keyframes);
  CHECK(summary.loop_closed == 0);
  /* The open model written first (the scan keeps it extracted), then the loop closed. */
  CHECK_OK(sls_scan_write_cloud(scan, cloud_before, &error_));
  CHECK_OK(sls_scan_write_trajectory(scan, trajectory_before, &error_));

  sls_loop_closure_init(&loop);
  CHECK(loop.struct_size == sizeof(loop) && loop.constraints == 0);
  sls_loop_closure_init_sized(NULL, sizeof(sls_loop_closure)); /* the macro needs a struct */
  status = sls_scan_close_loop(scan, &loop, &error);
  if (!succeeded(status, error, __LINE__)) {
    sls_scan_destroy(scan);
    return;
  }
  printf("loop closure: frame %d to %d, registration %.3f inliers %.1f um rms, %lu constraints, %d iterations, "
         "last pose corrected %.1f um %.4f deg, %.0f ms\n",
         loop.first_frame, loop.last_frame, loop.registration_inlier_fraction, loop.registration_residual_rms_m * 1e6,
         (unsigned long)loop.constraints, loop.iterations, loop.last_pose_correction_m * 1e6,
         loop.last_pose_correction_deg, loop.ms);
  CHECK(loop.struct_size == sizeof(loop));
  CHECK(loop.first_frame == 0 && loop.last_frame == last);
  CHECK(loop.registration_inlier_fraction > 0.5 && loop.registration_inlier_fraction <= 1.0);
  CHECK(loop.registration_residual_rms_m > 0 && loop.registration_residual_rms_m < 100e-6);
  CHECK(loop.constraints > 100);
  CHECK(loop.iterations >= 1);
  /* Drift over a tracked revolution is well under a millimetre and a degree. */
  CHECK(loop.last_pose_correction_m >= 0 && loop.last_pose_correction_m < 1e-3);
  CHECK(loop.last_pose_correction_deg >= 0 && loop.last_pose_correction_deg < 1.0);
  CHECK(loop.ms > 0);

  CHECK_OK(sls_scan_get_summary(scan, &summary, &error_));
  CHECK(summary.loop_closed == 1);
  CHECK(summary.deformation_nodes == (size_t)log.keyframes);
  CHECK(summary.deformation_constraints >= loop.constraints);
  /* A summary of the size before the deformation fields: filled up to there, nothing past. */
  memset(&summary, 0x5a, sizeof(summary));
  summary.struct_size = offsetof(sls_scan_summary, volume_moves) + sizeof(size_t);
  CHECK_OK(sls_scan_get_summary(scan, &summary, &error_));
  CHECK(summary.struct_size == offsetof(sls_scan_summary, volume_moves) + sizeof(size_t));
  CHECK(summary.fused == kFrames && summary.cancelled == 0);
  {
    sls_scan_summary untouched;
    memset(&untouched, 0x5a, sizeof(untouched));
    CHECK(summary.deformation_nodes == untouched.deformation_nodes && summary.loop_closed == untouched.loop_closed);
  }

  /* The writes give the closed model: the cloud differs from the open one, and the last pose
   * of the trajectory is the tracked pose (the frame report's) moved by the correction. */
  CHECK_OK(sls_scan_write_cloud(scan, cloud_after, &error_));
  CHECK_OK(sls_scan_write_mesh(scan, mesh_after, &error_));
  CHECK_OK(sls_scan_write_trajectory(scan, trajectory_after, &error_));
  check_cloud_file(cloud_after);
  check_mesh_file(mesh_after);
  CHECK(files_differ(cloud_before, cloud_after));
  CHECK(read_tum(trajectory_before, before, kFrames) == kFrames);
  CHECK(read_tum(trajectory_after, after, kFrames) == kFrames);
  pose_difference(log.T_world_camera[last], after[last], &translation_m, &rotation_deg);
  CHECK(fabs(translation_m - loop.last_pose_correction_m) < 2e-6);
  CHECK(fabs(rotation_deg - loop.last_pose_correction_deg) < 1e-3);
  pose_difference(before[last], after[last], &translation_m, &rotation_deg);
  CHECK(translation_m > 0 || rotation_deg > 0);
  /* Against the truth (world = the first camera): the last pose as tracked and as closed. */
  CHECK(read_tum(truth_path, truth, kFrames) == kFrames);
  relative_pose(truth[0], truth[last], true_motion);
  pose_difference(true_motion, log.T_world_camera[last], &drift_m, &drift_deg);
  pose_difference(true_motion, after[last], &closed_m, &closed_deg);
  printf("last pose against the truth: tracked %.1f um %.4f deg, closed %.1f um %.4f deg\n", drift_m * 1e6, drift_deg,
         closed_m * 1e6, closed_deg);
  CHECK(closed_m < 0.5e-3 && closed_deg < 0.2);

  /* A result of a bad size is refused before anything is done, and left as it was. */
  loop.struct_size = 4;
  CHECK_ERROR(sls_scan_close_loop(scan, &loop, &error_), SLS_ERROR_INVALID_ARGUMENT, "sls_loop_closure_init");
  CHECK(loop.struct_size == 4);
  sls_scan_destroy(scan);
  free(truth_path), free(cloud_before), free(cloud_after), free(mesh_after), free(trajectory_before),
      free(trajectory_after);
}

/* The loop closure refused, clearly, the model kept: before a run, with online deformation
 * off, and a NULL scan. */
static void check_loop_closure_refused(sls_context* context, const char* recording, const char* scratch) {
  static frame_log log;
  char* cloud = path_join(scratch, "no_deformation_cloud.ply");
  char* trajectory = path_join(scratch, "no_deformation_trajectory.txt");
  sls_scan_config config;
  sls_scan_summary summary;
  sls_loop_closure loop;
  sls_scan* scan = NULL;
  sls_error* error = NULL;
  int i;
  sls_loop_closure_init(&loop);
  CHECK_ERROR(sls_scan_close_loop(NULL, &loop, &error_), SLS_ERROR_INVALID_ARGUMENT, "scan");

  sls_scan_config_init(&config);
  config.use_turntable_prior = 1;
  config.max_voxels = 2e6;
  config.online_deformation = 0;
  if (!succeeded(sls_scan_create(context, &config, &scan, &error), error, __LINE__)) return;
  CHECK_ERROR(sls_scan_close_loop(scan, &loop, &error_), SLS_ERROR_INVALID_ARGUMENT, "before any run");
  CHECK_ERROR(sls_scan_close_loop(scan, NULL, &error_), SLS_ERROR_INVALID_ARGUMENT, "before any run");
  CHECK(loop.struct_size == sizeof(loop) && loop.last_frame == 0); /* untouched */

  /* Deformation off: no keyframes, no graph; the loop cannot be closed, the model stays. */
  frame_log_init(&log, scan, 3);
  CHECK_OK(sls_scan_set_frame_callback(scan, on_frame, &log, &error_));
  CHECK_ERROR(sls_scan_run_recording(scan, recording, &error_), SLS_ERROR_CANCELLED, "cancelled");
  CHECK(log.count == 4);
  for (i = 0; i < log.count; ++i) CHECK(log.sane[i] && log.status[i] == SLS_FRAME_FUSED);
  printf("deformation off: %d keyframes, %lu nodes, %.4f ms in the frame loop\n", log.keyframes,
         (unsigned long)log.max_deformation_nodes, log.deform_ms);
  CHECK(log.keyframes == 0 && log.max_deformation_nodes == 0);
  CHECK(log.deform_ms == 0.0); /* nothing of deformation's runs in the frame loop */
  CHECK_ERROR(sls_scan_close_loop(scan, &loop, &error_), SLS_ERROR_INVALID_ARGUMENT, "online deformation");
  CHECK(loop.last_frame == 0);
  sls_scan_summary_init(&summary);
  CHECK_OK(sls_scan_get_summary(scan, &summary, &error_));
  CHECK(summary.fused == 4 && summary.deformation_nodes == 0 && summary.deformation_constraints == 0);
  CHECK(summary.loop_closed == 0);
  CHECK_OK(sls_scan_write_cloud(scan, cloud, &error_));
  CHECK_OK(sls_scan_write_trajectory(scan, trajectory, &error_));
  check_cloud_file(cloud);
  CHECK(count_tum_poses(trajectory) == 4);
  sls_scan_destroy(scan);
  free(cloud), free(trajectory);
}

/* Replaces a file's content; 1 when written. */
static int overwrite(const char* path, const char* content) {
  FILE* file = fopen(path, "wb");
  if (file == NULL) return 0;
  fputs(content, file);
  return fclose(file) == 0;
}

/* A run on a worker thread, cancelled from this one after its second frame: the worker's
 * callback waits there until the cancel is sent, so the frame it stops after is known. */
typedef struct threaded_run {
  pthread_mutex_t mutex;
  pthread_cond_t changed;
  int frames;      /* reported so far */
  int cancel_sent; /* by the main thread */
  sls_scan* scan;
  const char* recording;
  sls_status status;
} threaded_run;

static void count_frame(const sls_frame_report* report, void* user) {
  threaded_run* run = (threaded_run*)user;
  (void)report;
  pthread_mutex_lock(&run->mutex);
  ++run->frames;
  pthread_cond_broadcast(&run->changed);
  while (run->frames == 2 && !run->cancel_sent) pthread_cond_wait(&run->changed, &run->mutex);
  pthread_mutex_unlock(&run->mutex);
}

static void* run_scan(void* user) {
  threaded_run* run = (threaded_run*)user;
  run->status = sls_scan_run_recording(run->scan, run->recording, NULL);
  return NULL;
}

static void check_cancel_from_another_thread(sls_context* context, const char* recording, const char* scratch) {
  threaded_run run;
  pthread_t worker;
  sls_scan_summary summary;
  char* cloud = path_join(scratch, "thread_cancelled_cloud.ply");
  sls_scan* scan = make_scan(context, 1);
  if (scan == NULL) return;
  memset(&run, 0, sizeof(run));
  pthread_mutex_init(&run.mutex, NULL);
  pthread_cond_init(&run.changed, NULL);
  run.scan = scan;
  run.recording = recording;
  run.status = SLS_OK;
  CHECK_OK(sls_scan_set_frame_callback(scan, count_frame, &run, &error_));
  CHECK(pthread_create(&worker, NULL, run_scan, &run) == 0);
  pthread_mutex_lock(&run.mutex);
  while (run.frames < 2) pthread_cond_wait(&run.changed, &run.mutex);
  pthread_mutex_unlock(&run.mutex);
  /* Running: queries from this thread are refused, a cancel is taken. */
  sls_scan_summary_init(&summary);
  CHECK_ERROR(sls_scan_get_summary(scan, &summary, &error_), SLS_ERROR_BUSY, "running");
  CHECK_ERROR(sls_scan_write_cloud(scan, cloud, &error_), SLS_ERROR_BUSY, "running");
  CHECK_ERROR(sls_scan_set_frame_callback(scan, NULL, NULL, &error_), SLS_ERROR_BUSY, "running");
  CHECK_OK(sls_scan_cancel(scan, &error_));
  pthread_mutex_lock(&run.mutex);
  run.cancel_sent = 1;
  pthread_cond_broadcast(&run.changed);
  pthread_mutex_unlock(&run.mutex);
  pthread_join(worker, NULL);
  /* Stopped after the frame in progress (the second), the model kept. */
  CHECK(run.status == SLS_ERROR_CANCELLED);
  CHECK(run.frames == 2);
  CHECK_OK(sls_scan_get_summary(scan, &summary, &error_));
  CHECK(summary.frames == 2 && summary.fused == 2 && summary.cancelled == 1);
  CHECK_OK(sls_scan_write_cloud(scan, cloud, &error_));
  check_cloud_file(cloud);
  sls_scan_destroy(scan);
  pthread_cond_destroy(&run.changed);
  pthread_mutex_destroy(&run.mutex);
  free(cloud);
}

/* Keeps the first `bytes` bytes of a file; 1 when done. */
static int truncate_file(const char* path, size_t bytes) {
  char buffer[4096];
  size_t got;
  FILE* file = fopen(path, "rb");
  if (file == NULL || bytes > sizeof(buffer)) return 0;
  got = fread(buffer, 1, bytes, file);
  fclose(file);
  if (got != bytes) return 0;
  file = fopen(path, "wb");
  if (file == NULL) return 0;
  got = fwrite(buffer, 1, bytes, file);
  return fclose(file) == 0 && got == bytes;
}


/* A live scan cancelled: sim:// devices with a turntable, fused while they capture
 * (sls_scan_run_devices), cancelled from the callback after the second frame. The run says so;
 * the model fused so far is kept and written; the recording keeps every frame captured and
 * scans again on its own. */
static void check_live_scan_cancelled(sls_context* context, const char* recording, const char* scratch) {
  enum { kCancelAfter = 1, kPlanned = 36 };
  static frame_log log;
  const char* uri = "sim://knurled-knob?preset=ci";
  char* calibration = path_join(recording, "calibration.yml");
  char* captured = path_join(scratch, "captured_cancelled");
  char* cloud = path_join(scratch, "captured_cancelled_cloud.ply");
  char* mesh = path_join(scratch, "captured_cancelled_mesh.ply");
  sls_capture_config capture;
  sls_scan_summary summary;
  int fused;
  sls_scan* scan = make_scan(context, 1);
  if (scan == NULL) return;
  frame_log_init(&log, scan, kCancelAfter);
  CHECK_OK(sls_scan_set_frame_callback(scan, on_frame, &log, &error_));
  sim_capture(&capture, uri, uri, calibration, captured, kPlanned);
  CHECK_ERROR(sls_scan_run_devices(scan, &capture, &error_), SLS_ERROR_CANCELLED, "cancelled");
  /* Fused while captured: the frames up to the cancel, in order; the capture stopped soon after. */
  CHECK(log.count == kCancelAfter + 1 && !log.out_of_order && log.index[log.count - 1] == kCancelAfter);
  CHECK(log.status[0] == SLS_FRAME_FUSED && log.sane[0] && log.sane[1]);
  sls_scan_summary_init(&summary);
  CHECK_OK(sls_scan_get_summary(scan, &summary, &error_));
  CHECK(summary.cancelled == 1 && summary.fused >= 1 && summary.frames == kCancelAfter + 1);
  fused = (int)summary.fused;
  CHECK_OK(sls_scan_write_cloud(scan, cloud, &error_));
  CHECK_OK(sls_scan_write_mesh(scan, mesh, &error_));
  check_cloud_file(cloud);
  check_mesh_file(mesh);
  sls_scan_destroy(scan);

  /* The recording is whole: a new scan reads every frame it holds, the fused ones among them. */
  scan = make_scan(context, 1);
  if (scan == NULL) return;
  frame_log_init(&log, scan, -1);
  CHECK_OK(sls_scan_set_frame_callback(scan, on_frame, &log, &error_));
  CHECK_OK(sls_scan_run_recording(scan, captured, &error_));
  CHECK(log.count >= kCancelAfter + 1 && log.count < kPlanned && !log.out_of_order);
  CHECK_OK(sls_scan_get_summary(scan, &summary, &error_));
  CHECK((int)summary.fused >= fused);
  printf("live scan cancelled after frame %d: %d frame(s) fused, %d recorded of %d planned\n", kCancelAfter, fused,
         log.count, kPlanned);
  sls_scan_destroy(scan);
  free(calibration), free(captured), free(cloud), free(mesh);
}

/* sim:// devices: two stacks at one position (no turntable) captured into a recording, decoded
 * and fused: the run completes with SLS_OK; the camera did not move, so neither do the poses.
 * Then the same recording's stacks made unreadable, one and then both, and its manifest
 * corrupt: skipped frames, a run that fuses nothing, a corrupt recording, each clearly told. */
static void check_devices_scan(sls_context* context, const char* recording, const char* scratch) {
  static frame_log log;
  const char* uri = "sim://knurled-knob?preset=ci";
  char* calibration = path_join(recording, "calibration.yml");
  char* captured = path_join(scratch, "captured");
  char* trajectory = path_join(scratch, "captured_trajectory.txt");
  char* pattern0 = path_join(scratch, "captured/frames/000000/pattern_000.png");
  char* pattern1 = path_join(scratch, "captured/frames/000001/pattern_000.png");
  char* manifest = path_join(scratch, "captured/manifest.json");
  double identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  sls_capture_config capture;
  sls_scan_summary summary;
  int i;
  sls_scan* scan = make_scan(context, 0);
  if (scan == NULL) return;
  frame_log_init(&log, scan, -1);
  CHECK_OK(sls_scan_set_frame_callback(scan, on_frame, &log, &error_));
  sim_capture(&capture, uri, NULL, calibration, captured, 2);
  CHECK_OK(sls_scan_run_devices(scan, &capture, &error_));
  CHECK(log.count == 2 && !log.out_of_order && log.index[0] == 0);
  for (i = 0; i < log.count; ++i) {
    double translation_m, rotation_deg;
    CHECK(log.sane[i] && log.status[i] == SLS_FRAME_FUSED);
    pose_difference(identity, log.T_world_camera[i], &translation_m, &rotation_deg);
    CHECK(translation_m < 20e-6 && rotation_deg < 0.01);
  }
  sls_scan_summary_init(&summary);
  CHECK_OK(sls_scan_get_summary(scan, &summary, &error_));
  CHECK(summary.frames == 2 && summary.fused == 2 && summary.cancelled == 0);
  /* The camera never moved: one keyframe, no loop to close; said so, and the model is kept. */
  CHECK_ERROR(sls_scan_close_loop(scan, NULL, &error_), SLS_ERROR_INVALID_ARGUMENT, "too few keyframes");
  CHECK_OK(sls_scan_get_summary(scan, &summary, &error_));
  CHECK(summary.loop_closed == 0 && summary.fused == 2);
  CHECK_OK(sls_scan_write_trajectory(scan, trajectory, &error_));
  CHECK(count_tum_poses(trajectory) == 2);

  /* The recording exists now: capturing into it again is refused, naming it. */
  CHECK_ERROR(sls_scan_run_devices(scan, &capture, &error_), SLS_ERROR_INVALID_ARGUMENT, "captured");
  /* A capture needs its devices, a calibration and a folder; a URI nothing opens is named. */
  capture.recording_path = NULL;
  CHECK_ERROR(sls_scan_run_devices(scan, &capture, &error_), SLS_ERROR_INVALID_ARGUMENT, "recording_path");
  capture.recording_path = captured;
  capture.calibration_path = "";
  CHECK_ERROR(sls_scan_run_devices(scan, &capture, &error_), SLS_ERROR_INVALID_ARGUMENT, "calibration_path");
  capture.calibration_path = calibration;
  capture.camera_uri = "firewire://0";
  CHECK_ERROR(sls_scan_run_devices(scan, &capture, &error_), SLS_ERROR_UNSUPPORTED, "firewire://0");
  capture.camera_uri = uri;
  capture.frames = -1;
  CHECK_ERROR(sls_scan_run_devices(scan, &capture, &error_), SLS_ERROR_INVALID_ARGUMENT, "frames");
  capture.frames = 2;
  capture.struct_size = 1;
  CHECK_ERROR(sls_scan_run_devices(scan, &capture, &error_), SLS_ERROR_INVALID_ARGUMENT, "sls_capture_config_init");
  CHECK_ERROR(sls_scan_run_devices(scan, NULL, &error_), SLS_ERROR_INVALID_ARGUMENT, "capture");

  /* One stack unreadable (an image cut short: its header is whole, so the recording checks
   * out, but its pixels cannot be read): that frame is skipped with the reason, the other fused. */
  CHECK(truncate_file(pattern1, 100));
  frame_log_init(&log, scan, -1);
  CHECK_OK(sls_scan_run_recording(scan, captured, &error_));
  CHECK(log.count == 2 && log.status[0] == SLS_FRAME_FUSED && log.status[1] == SLS_FRAME_SKIPPED && log.sane[1]);
  CHECK_OK(sls_scan_get_summary(scan, &summary, &error_));
  CHECK(summary.frames == 2 && summary.fused == 1 && summary.skipped == 1);

  /* Both unreadable: no frame fused is an error naming the recording and the first frame's
   * problem; every frame was still reported. */
  CHECK(truncate_file(pattern0, 100));
  frame_log_init(&log, scan, -1);
  CHECK_ERROR(sls_scan_run_recording(scan, captured, &error_), SLS_ERROR_INVALID_ARGUMENT, "no frame could be fused");
  CHECK(log.count == 2 && log.status[0] == SLS_FRAME_SKIPPED && log.status[1] == SLS_FRAME_SKIPPED);
  CHECK(strstr(log.first_reason, "pattern_000.png") != NULL);
  CHECK_OK(sls_scan_get_summary(scan, &summary, &error_));
  CHECK(summary.frames == 2 && summary.skipped == 2 && summary.fused == 0);
  CHECK_ERROR(sls_scan_write_mesh(scan, "mesh.ply", &error_), SLS_ERROR_INVALID_ARGUMENT, "no frame");
  CHECK_ERROR(sls_scan_close_loop(scan, NULL, &error_), SLS_ERROR_INVALID_ARGUMENT, "before any frame was fused");

  /* An image that is no PNG at all is one more unreadable frame, skipped with the reason; a
   * corrupt manifest fails the recording before any frame, with FORMAT naming the file. */
  CHECK(overwrite(pattern0, "not a png"));
  frame_log_init(&log, scan, -1);
  CHECK_ERROR(sls_scan_run_recording(scan, captured, &error_), SLS_ERROR_INVALID_ARGUMENT, "not a PNG");
  CHECK(log.count == 2 && log.status[0] == SLS_FRAME_SKIPPED && log.status[1] == SLS_FRAME_SKIPPED);
  CHECK(strstr(log.first_reason, "000000/pattern_000.png") != NULL);
  frame_log_init(&log, scan, -1);
  CHECK(overwrite(manifest, "{\"format\": \"slscan-rec"));
  CHECK_ERROR(sls_scan_run_recording(scan, captured, &error_), SLS_ERROR_FORMAT, "manifest.json");
  CHECK_OK(sls_scan_get_summary(scan, &summary, &error_));
  CHECK(summary.frames == 0);
  CHECK_ERROR(sls_scan_write_cloud(scan, "cloud.ply", &error_), SLS_ERROR_INVALID_ARGUMENT, "no frame");
  sls_scan_destroy(scan);
  free(calibration), free(captured), free(trajectory), free(pattern0), free(pattern1), free(manifest);
}

static void check_mistakes(sls_context* context, const char* scratch) {
  sls_scan_config config;
  sls_scan_summary summary;
  sls_scan* scan = NULL;
  char* missing = path_join(scratch, "no-such-recording");
  sls_scan_config_init(&config);
  CHECK(config.struct_size == sizeof(config) && config.fusion == SLS_FUSION_GTSDF && config.max_voxels == 0.0);
  /* NULL to the functions behind the _init macros (which need a struct: sizeof *s). */
  sls_scan_config_init_sized(NULL, sizeof(sls_scan_config));
  sls_capture_config_init_sized(NULL, sizeof(sls_capture_config));
  sls_scan_summary_init_sized(NULL, sizeof(sls_scan_summary));

  CHECK_ERROR(sls_scan_create(NULL, NULL, &scan, &error_), SLS_ERROR_INVALID_ARGUMENT, "context");
  CHECK_ERROR(sls_scan_create(context, NULL, NULL, &error_), SLS_ERROR_INVALID_ARGUMENT, "scan");
  config.voxel_size_m = -1.0;
  CHECK_ERROR(sls_scan_create(context, &config, &scan, &error_), SLS_ERROR_INVALID_ARGUMENT, "voxel_size_m");
  sls_scan_config_init(&config);
  config.volume_size_m[0] = 0.01;
  CHECK_ERROR(sls_scan_create(context, &config, &scan, &error_), SLS_ERROR_INVALID_ARGUMENT, "volume_size_m");
  sls_scan_config_init(&config);
  config.fusion = (sls_fusion_method)7;
  CHECK_ERROR(sls_scan_create(context, &config, &scan, &error_), SLS_ERROR_INVALID_ARGUMENT, "fusion");
  sls_scan_config_init(&config);
  config.struct_size = 3;
  CHECK_ERROR(sls_scan_create(context, &config, &scan, &error_), SLS_ERROR_INVALID_ARGUMENT, "sls_scan_config_init");
  CHECK(scan == NULL);

  /* NULL handles: an error, never a crash. */
  sls_scan_destroy(NULL);
  sls_scan_summary_init(&summary);
  CHECK_ERROR(sls_scan_run_recording(NULL, missing, &error_), SLS_ERROR_INVALID_ARGUMENT, "scan");
  CHECK_ERROR(sls_scan_run_devices(NULL, NULL, &error_), SLS_ERROR_INVALID_ARGUMENT, "scan");
  CHECK_ERROR(sls_scan_set_frame_callback(NULL, on_frame, NULL, &error_), SLS_ERROR_INVALID_ARGUMENT, "scan");
  CHECK_ERROR(sls_scan_cancel(NULL, &error_), SLS_ERROR_INVALID_ARGUMENT, "scan");
  CHECK_ERROR(sls_scan_get_summary(NULL, &summary, &error_), SLS_ERROR_INVALID_ARGUMENT, "scan");
  CHECK_ERROR(sls_scan_write_cloud(NULL, "a.ply", &error_), SLS_ERROR_INVALID_ARGUMENT, "scan");
  CHECK_ERROR(sls_scan_write_mesh(NULL, "a.ply", &error_), SLS_ERROR_INVALID_ARGUMENT, "scan");
  CHECK_ERROR(sls_scan_write_trajectory(NULL, "a.txt", &error_), SLS_ERROR_INVALID_ARGUMENT, "scan");

  /* A scan with the defaults: nothing to write before a run; a missing recording is named. */
  CHECK_OK(sls_scan_create(context, NULL, &scan, &error_));
  if (scan == NULL) return;
  CHECK_ERROR(sls_scan_get_summary(scan, NULL, &error_), SLS_ERROR_INVALID_ARGUMENT, "summary");
  CHECK_OK(sls_scan_get_summary(scan, &summary, &error_));
  CHECK(summary.frames == 0 && summary.fused == 0 && summary.voxel_size_m == 0.0);
  summary.struct_size = 2;
  CHECK_ERROR(sls_scan_get_summary(scan, &summary, &error_), SLS_ERROR_INVALID_ARGUMENT, "sls_scan_summary_init");
  CHECK_ERROR(sls_scan_write_cloud(scan, "a.ply", &error_), SLS_ERROR_INVALID_ARGUMENT, "no frame");
  CHECK_ERROR(sls_scan_write_mesh(scan, "a.ply", &error_), SLS_ERROR_INVALID_ARGUMENT, "no frame");
  CHECK_ERROR(sls_scan_write_trajectory(scan, "a.txt", &error_), SLS_ERROR_INVALID_ARGUMENT, "no frame");
  CHECK_ERROR(sls_scan_write_cloud(scan, NULL, &error_), SLS_ERROR_INVALID_ARGUMENT, "path");
  CHECK_ERROR(sls_scan_run_recording(scan, missing, &error_), SLS_ERROR_NOT_FOUND, "no-such-recording");
  CHECK_ERROR(sls_scan_run_recording(scan, NULL, &error_), SLS_ERROR_INVALID_ARGUMENT, "recording_path");
  /* Cancelled before it runs: the run stops before reading anything, and creates nothing. */
  CHECK_OK(sls_scan_cancel(scan, &error_));
  CHECK_ERROR(sls_scan_run_recording(scan, missing, &error_), SLS_ERROR_CANCELLED, "cancelled");
  sls_scan_destroy(scan);
  free(missing);
}

int main(int argc, char** argv) {
  sls_context* context = NULL;
  sls_context_config config;
  if (argc != 3) {
    fprintf(stderr, "usage: test_c_scan RECORDING SCRATCH\n");
    return 2;
  }
  sls_context_config_init(&config);
  config.device = SLS_DEVICE_CPU;
  if (sls_context_create(SLS_API_VERSION, &config, &context, NULL) != SLS_OK) {
    fprintf(stderr, "no context\n");
    return 1;
  }
  check_mistakes(context, argv[2]);
  check_cancelled_turntable_scan(context, argv[1], argv[2]);
  check_cancel_from_another_thread(context, argv[1], argv[2]);
  check_loop_closure_refused(context, argv[1], argv[2]);
  check_loop_closure(context, argv[1], argv[2]);
  check_devices_scan(context, argv[1], argv[2]);
  check_live_scan_cancelled(context, argv[1], argv[2]);
  sls_context_destroy(context);
  if (failures != 0) fprintf(stderr, "%d check(s) failed\n", failures);
  else printf("all checks passed\n");
  return failures == 0 ? 0 : 1;
}
