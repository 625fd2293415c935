/* Calibration capture through the devices (API 0.7; heads of several cameras 0.9): the chessboard views that
 * sls_calibration_run() calibrates from, captured pose by pose through an open camera,
 * projector and (optionally) turntable into an ordinary recording, as `sls calibrate --camera
 * ... --record DIR` captures them.
 *
 * sls_calibration_capture() does, in this order:
 *  1. the hand poses (config->hand_poses): before each, the pose callback is asked — the
 *     operator places the board and answers SLS_CALIBRATION_POSE_CAPTURE, or skips the pose
 *     (SLS_CALIBRATION_POSE_SKIP), or ends the capture (SLS_CALIBRATION_POSE_STOP: the poses
 *     captured are kept and the call succeeds) — then one full pattern stack (white and black
 *     included) is captured; the frame's turntable angle is null in the recording;
 *  2. the turntable poses (config->turntable_angles_deg, in that order; a turntable needed):
 *     the callback is asked likewise, the table homed before the first one
 *     (config->home_turntable), moved to the angle, and one stack captured; the frame carries
 *     the angle the table reports.
 * Every stack goes through the capture sequencer's checks and re-captures and is appended and
 * flushed to the recording as it arrives. The recording is made uncalibrated; calibrate it with
 * sls_calibration_run(context, recording_folder, ...), or continue it with config->resume.
 *
 * Resume (config->resume = 1): the recording at recording_folder, cut off by a cancel, a
 * device error, a signal or a kill, is continued with the same devices and pattern set (another
 * set or camera is refused, naming the difference). Its frames say what was done: without a
 * turntable frame, the hand poses go on at pose h + 1 (h = its hand frames; a pose skipped
 * before the cut is asked again), else they are over; the turntable angles it holds (to half a
 * table step) are not captured again. Without resume the folder must not exist or be empty.
 *
 * A head (API 0.9: config->more_cameras): a projector and several cameras, calibrated as one
 * (sls_calibration_run on the folder, then sls_calibration_camera_count/_get_camera). Every pose
 * is one pattern stack that all cameras take together: the projector shows each pattern once and
 * every camera is triggered on it, as a real head triggers its cameras from the projector, so all
 * of them see the board at the same instant (a board held by hand does not wait for a second
 * projection). recording_folder is then the head's folder: one recording per camera in
 * recording_folder/camera0 (the `camera` argument), camera1, ... (frame k of each the same
 * pose), the layout sls_calibration_run() and `sls calibrate --input` read as a head. A resume
 * continues every camera's recording; recordings that disagree (another pose count, as a kill
 * between two cameras' writes leaves them) or a head of another camera count are refused,
 * naming the folder. Errors name the camera by index and URI: "camera 1 (gige://...)".
 *
 * Errors name the pose and the device, and the frames kept, e.g. "calibration hand pose 3 of
 * 12: capture frame 2 of 3, pattern 5 of 42: camera gige://...: no image within 2000 ms; 2
 * frame(s) are in calib-rec". A cancel, a device that stops answering or an odd answer from the
 * pose callback ends the capture after the last whole pose: the recording stays valid (it reads
 * back, sls_calibration_run() calibrates it) and config->resume continues it.
 *
 * Available in every build (the capture needs no OpenCV; calibrating the recording does).
 *
 * Threads: sls_calibration_capture() blocks the calling thread (seconds per pose, plus the
 * operator's time) and drives the devices from it; both callbacks run on that thread. The
 * camera, projector and turntable belong to the call while it runs: no other call may use them,
 * from another thread or from the callbacks (a device's calls must not overlap, and a sim://
 * board's simulated operator moves the board at each acquisition). Captures with different
 * devices are independent.
 *
 * Typical use:
 *   static int confirm(const sls_calibration_pose* pose, void* user) {
 *     (void)user;
 *     printf("place the board for %s, then press Enter (s: skip, q: stop)\n", pose->description);
 *     switch (getchar()) {
 *       case 's': return SLS_CALIBRATION_POSE_SKIP;
 *       case 'q': return SLS_CALIBRATION_POSE_STOP;
 *       default: return SLS_CALIBRATION_POSE_CAPTURE;
 *     }
 *   }
 *   ...
 *   static const double angles[] = {350.0, 355.0, 0.0, 5.0, 10.0};
 *   sls_calibration_capture_config config;
 *   sls_calibration_capture_result result;
 *   sls_error* error = NULL;
 *   sls_calibration_capture_config_init(&config);
 *   sls_calibration_capture_result_init(&result);
 *   config.hand_poses = 12;
 *   config.turntable_angles_deg = angles;
 *   config.turntable_angle_count = 5;
 *   if (sls_calibration_capture(camera, projector, turntable, "calib-rec", &config, confirm, NULL, NULL,
 *                               &result, &error) == SLS_OK)
 *     printf("%zu poses captured, %zu skipped\n", result.poses_captured, result.poses_skipped);
 *   else
 *     fprintf(stderr, "%s (%zu frames kept: set config.resume to continue)\n", sls_error_message(error),
 *             result.frames);
 *   sls_error_free(error);
 */
#ifndef SLS_CALIBRATION_CAPTURE_H
#define SLS_CALIBRATION_CAPTURE_H

#include <stddef.h>

#include "sls/sls_calibration.h"
#include "sls/sls_camera.h"
#include "sls/sls_export.h"
#include "sls/sls_projector.h"
#include "sls/sls_status.h"
#include "sls/sls_turntable.h"

#ifdef __cplusplus
extern "C" {
#endif

/* What sls_calibration_capture() captures. Versioned (sls.h): initialise with
 * sls_calibration_capture_config_init(), which sets struct_size and the defaults, then change
 * fields. The array and the string are the caller's, read during the call only. */
typedef struct sls_calibration_capture_config {
  size_t struct_size;
  int hand_poses;                     /* board poses placed by hand, 0 .. 1000; default 12 */
  const double* turntable_angles_deg; /* table angles in degrees, each in [0, 360), captured in
                                       * this order; default NULL: no turntable poses */
  size_t turntable_angle_count;       /* of them, at most 1000 (not 0: a turntable is needed);
                                       * default 0 */
  int home_turntable;                 /* 1 (default): home the table before its first pose */
  int resume;                         /* 1: continue the recording at the folder (see above);
                                       * default 0: a new recording */
  const char* pattern_set;            /* the set to project by name, as `sls calibrate
                                       * --patterns`: "gray-phase:WxH" or "opencv-graycode:WxH";
                                       * NULL or "" (the default): gray-phase over columns and
                                       * rows at the projector's size (the DLP4500's diamond
                                       * rows taken into account) */
  double exposure_us;                 /* the camera's exposure; default 0: left as it is */
  int image_timeout_ms;               /* wait per image before it counts as lost; default 2000 */
  int turntable_timeout_ms;           /* per home or move; default 10000 */
  int max_retries;                    /* a spoiled stack is captured again up to this many times,
                                       * then written incomplete; default 2 */
  /* API 0.9: a head of several cameras (see "A head" above). */
  sls_camera* const* more_cameras;    /* cameras 1 .. K-1 of the head (the `camera` argument is
                                       * camera 0), open and each a different camera; the caller's
                                       * array, read during the call; default NULL: one camera */
  size_t more_camera_count;           /* of them, at most 15; default 0 */
} sls_calibration_capture_config;

/* Fills *config with the defaults. */
SLS_API void sls_calibration_capture_config_init(sls_calibration_capture_config* config);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_calibration_capture_config_init_sized(sls_calibration_capture_config* config, size_t struct_size);
#define sls_calibration_capture_config_init(config) \
  sls_calibration_capture_config_init_sized((config), sizeof(*(config)))

/* Which kind of pose the pose callback is asked about. */
typedef enum sls_calibration_pose_kind {
  SLS_CALIBRATION_POSE_HAND = 0,     /* the operator places the board */
  SLS_CALIBRATION_POSE_TURNTABLE = 1 /* the board is fixed on the table; the table turns */
} sls_calibration_pose_kind;

/* The pose the pose callback is asked about. The library fills its own version of the struct
 * and sets struct_size to its size (like sls_calibration_progress). */
typedef struct sls_calibration_pose {
  size_t struct_size;
  sls_calibration_pose_kind kind;
  int index;                  /* among the poses of its kind, from 0 */
  int count;                  /* poses of its kind in the capture */
  double turntable_angle_deg; /* turntable poses: the angle the table is moved to; 0 by hand */
  const char* description;    /* "hand pose 3 of 12", "turntable pose 2 of 5 (355.000 deg)" */
} sls_calibration_pose;

/* What the pose callback answers. */
typedef enum sls_calibration_pose_decision {
  SLS_CALIBRATION_POSE_CAPTURE = 0, /* the board is in place: capture this pose */
  SLS_CALIBRATION_POSE_SKIP = 1,    /* leave this pose out; go on with the next */
  SLS_CALIBRATION_POSE_STOP = 2     /* capture nothing more; the call succeeds with what it has */
} sls_calibration_pose_decision;

/* Asked before every pose, on the thread running the capture; for a hand pose it returns once
 * the operator has placed the board. Returns an sls_calibration_pose_decision; any other value
 * ends the capture with SLS_ERROR_INVALID_ARGUMENT naming the pose (the recording kept).
 * `pose` and its string are valid during the call only. It must return normally (no longjmp,
 * no exceptions) and must not use the capture's devices. */
typedef int (*sls_calibration_pose_callback)(const sls_calibration_pose* pose, void* user);

/* What a capture did. Versioned: initialise with sls_calibration_capture_result_init(); the
 * library fills only the fields the caller's struct_size covers. */
typedef struct sls_calibration_capture_result {
  size_t struct_size;
  size_t poses_captured;    /* by this call */
  size_t poses_skipped;     /* by this call (SLS_CALIBRATION_POSE_SKIP) */
  int stopped;              /* 1: the pose callback answered SLS_CALIBRATION_POSE_STOP */
  size_t frames;            /* frames in the recording now (the earlier ones of a resume included) */
  size_t hand_frames;       /* of those, by hand */
  size_t turntable_frames;  /* and on the turntable */
  size_t resumed_from;      /* with resume: the frames the recording held before; else 0 */
  size_t images_per_frame;  /* the pattern set's images (white and black included) */
  size_t incomplete_frames; /* written incomplete after the re-captures ran out */
  size_t retries;           /* stacks captured again */
  double seconds;           /* the whole call, the callbacks' time included */
  double capture_seconds;   /* capturing only: table moves, stacks and recording */
  size_t cameras;           /* API 0.9: the cameras that captured each pose (1 + more_camera_count) */
} sls_calibration_capture_result;

/* Sets struct_size and clears the other fields. */
SLS_API void sls_calibration_capture_result_init(sls_calibration_capture_result* result);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_calibration_capture_result_init_sized(sls_calibration_capture_result* result, size_t struct_size);
#define sls_calibration_capture_result_init(result) \
  sls_calibration_capture_result_init_sized((result), sizeof(*(result)))

/* Captures a calibration through the devices into a recording (see the top of this header).
 *   camera, projector: open devices (sls_camera_open, sls_projector_open); required. Not kept,
 *                      not closed. The camera is stopped first if a grab left it running; the
 *                      projector holds the calibration's pattern set afterwards.
 *   turntable:         NULL (then no turntable angles) or an open turntable.
 *   recording_folder:  the recording to create (the folder must not exist or be empty), or with
 *                      config->resume the one to continue.
 *   config:            NULL for the defaults, or a config from sls_calibration_capture_config_init().
 *   pose_callback:     NULL captures every pose without asking (a fixture that moves the board);
 *                      else asked before each pose (`user` handed to it).
 *   progress:          NULL, or called after each pose, captured or skipped, with stage
 *                      "calibration capture", done/total poses of this call and the pose as
 *                      detail ("hand pose 3 of 12", "... skipped"); 0 from it stops the capture
 *                      there: SLS_ERROR_CANCELLED, the recording kept.
 *   result:            NULL, or a struct from sls_calibration_capture_result_init(), filled on
 *                      SLS_OK; on a failure only `frames` is set (what the recording at the
 *                      folder holds, a head's per camera: what a resume starts from; 0
 *                      without one), the rest 0.
 * Fails, with nothing captured, with SLS_ERROR_INVALID_ARGUMENT for a NULL camera, projector or
 * folder, a struct_size not from its _init(), a bad config field (named: a NULL more_cameras
 * with a count, a NULL or repeated camera in it, more than 15), turntable angles
 * without a turntable or with a NULL array, a folder that is not empty without config->resume
 * or that holds no recording with it, or a recording that another pattern set or camera made;
 * SLS_ERROR_FORMAT for a corrupt recording to resume. Then, the poses before kept in the
 * recording: SLS_ERROR_TIMEOUT or SLS_ERROR_DEVICE (or the driver's code) for a device that
 * stops answering, SLS_ERROR_IO when the recording cannot be written, SLS_ERROR_CANCELLED when
 * the progress callback returned 0, SLS_ERROR_INVALID_ARGUMENT for a pose callback's answer that
 * is no decision. */
SLS_API sls_status sls_calibration_capture(sls_camera* camera, sls_projector* projector, sls_turntable* turntable,
                                           const char* recording_folder, const sls_calibration_capture_config* config,
                                           sls_calibration_pose_callback pose_callback,
                                           sls_calibration_progress_callback progress, void* user,
                                           sls_calibration_capture_result* result, sls_error** error);

#ifdef __cplusplus
}
#endif

#endif /* SLS_CALIBRATION_CAPTURE_H */
