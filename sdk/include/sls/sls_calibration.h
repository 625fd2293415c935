/* Calibration: camera and projector intrinsics, their relative pose and, when the capture
 * allows, the turntable's axis, from captures of a chessboard or (API 0.10) a ChArUco board
 * (the same solver as `sls calibrate`).
 *
 * sls_calibration_run() calibrates from what is on disk:
 *   - a recording (sdk recording folder with manifest.json) whose frames are board poses,
 *     those with a turntable angle also serving the axis (`sls sim --calibration` writes one,
 *     with its exact calibration as ground truth: the result is then compared with it);
 *   - or a folder of captures, one subfolder per board pose (sorted by name), each holding the
 *     pattern set's images in its order (PNG files sorted by name); the pattern set must then be
 *     named (config->pattern_set, e.g. "opencv-graycode:1024x768");
 *   - or (API 0.8) a head of several cameras: a folder with one such capture per camera in
 *     subfolders camera0, camera1, ... (the same board poses in the same order; `sls sim
 *     --calibration --cameras 2` writes one). Each camera is calibrated against the projector,
 *     then each camera's pose relative to camera 0 (docs/calibration.md, "Multi-camera heads").
 *     Every getter above sls_calibration_camera_count() then describes camera 0, the primary
 *     camera (the one scans use); the cameras are read with sls_calibration_get_camera().
 * Each view is loaded, decoded, the board's corners found in the camera and, through the decoded
 * patterns, in the projector (local homographies); a view that cannot be used (no board, too
 * few decoded corners, too oblique, unreadable) is rejected with its reason and the others go
 * on. Then camera, projector and their extrinsics are solved jointly (mislocated corners
 * dropped), then the turntable axis when at least 3 used views with recorded angles span 10
 * degrees. The result (an sls_calibration) is read with the getters below and written as
 * calibration.yml with sls_calibration_write().
 *
 * In a library built without OpenCV calibration is not available: every sls_calibration_*
 * function still exists (the same symbols and header everywhere) and returns
 * SLS_ERROR_UNSUPPORTED with the message "built without OpenCV: calibration is not available";
 * the _init() functions still fill their structs, and sls_calibration_destroy(NULL) is a no-op.
 *
 * Threads: sls_calibration_run() blocks the thread that calls it (seconds to minutes: every
 * view's images are read and decoded); its progress callback runs on that thread. A result is
 * never changed after the run that made it: every function taking a const sls_calibration* may
 * be called from several threads at once. Destroying a result while another thread reads it is
 * the caller's bug.
 *
 * Units: lengths in metres (the board's square size sets them), angles in degrees, image
 * coordinates in pixels (pixel (0,0) is the centre of the top-left pixel). The lens model is
 * OpenCV's: pinhole with Brown-Conrady distortion (k1 k2 k3 radial, p1 p2 tangential); the
 * projector is modelled as an inverse camera.
 *
 * Typical use:
 *   sls_calibration_config config;
 *   sls_calibration* calibration = NULL;
 *   sls_error* error = NULL;
 *   sls_calibration_config_init(&config);
 *   config.board_inner_cols = 9;
 *   config.board_inner_rows = 7;
 *   config.board_square_m = 0.075;
 *   config.pattern_set = "opencv-graycode:1024x768";
 *   (a ChArUco board of 12 x 9 squares: board_kind = SLS_CALIBRATION_BOARD_CHARUCO, 11 x 8 inner
 *   corners, board_marker_m = 0.056, board_dictionary NULL for DICT_5X5_100)
 *   if (sls_calibration_run(context, "captures", &config, NULL, NULL, &calibration, &error) == SLS_OK) {
 *     sls_calibration_summary summary;
 *     sls_calibration_summary_init(&summary);
 *     sls_calibration_get_summary(calibration, &summary, NULL);
 *     printf("stereo RMS %.3f px from %zu views\n", summary.stereo_rms_px, summary.views_used);
 *     if (sls_calibration_write(calibration, "calibration.yml", 0, &error) != SLS_OK)
 *       fprintf(stderr, "%s\n", sls_error_message(error));
 *   } else {
 *     fprintf(stderr, "%s\n", sls_error_message(error));
 *   }
 *   sls_error_free(error);
 *   sls_calibration_destroy(calibration);
 */
#ifndef SLS_CALIBRATION_H
#define SLS_CALIBRATION_H

#include <stddef.h>

#include "sls/sls_context.h"
#include "sls/sls_export.h"
#include "sls/sls_status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The result of a calibration: intrinsics, extrinsics, axis, figures and views. Opaque;
 * immutable once made. */
typedef struct sls_calibration sls_calibration;

/* The calibration target (API 0.10). */
typedef enum sls_calibration_board_kind {
  SLS_CALIBRATION_BOARD_CHESSBOARD = 0, /* found whole in every view (OpenCV's findChessboardCorners) */
  SLS_CALIBRATION_BOARD_CHARUCO = 1     /* OpenCV's CharucoBoard: ArUco markers in the light
                                         * squares name each corner, so a view of part of the
                                         * board counts (docs/calibration.md, "ChArUco boards") */
} sls_calibration_board_kind;

/* Calibration configuration. Versioned by its size: initialise with
 * sls_calibration_config_init(), which sets struct_size and the defaults, then change fields.
 * Later library versions only append fields. The strings are read during sls_calibration_run()
 * only. */
typedef struct sls_calibration_config {
  size_t struct_size;
  int board_inner_cols;   /* inner corners along a row of the chessboard (OpenCV's pattern width) */
  int board_inner_rows;   /* and along a column */
  double board_square_m;  /* side of a square, metres. All three 0 (the default): from a
                           * simulated capture's ground truth (groundtruth/board.json); otherwise
                           * all three positive */
  const char* pattern_set; /* a built-in pattern set by name, e.g. "opencv-graycode:1024x768";
                            * NULL or "" (the default): the recording's own (a folder of captures
                            * has none: it must be named) */
  int estimate_k3;        /* 1: estimate the r^6 radial term; default 0: k3 fixed at 0 (poorly
                           * determined by a narrow field of view) */
  double max_obliquity_deg;             /* a view whose board normal is farther than this from
                                         * the camera's axis is rejected; default 65 */
  double min_projector_corner_fraction; /* a view whose projector sees fewer of the board's
                                         * corners than this fraction is rejected; default 0.5 */
  double max_rms_px;      /* sls_calibration_write() refuses a calibration whose stereo RMS is
                           * above this unless forced; default 1.0 */
  /* Appended in API 0.10: the board's kind (a struct of an older version, without these
   * fields, describes a chessboard). With the board from the ground truth (board_inner_cols,
   * board_inner_rows, board_square_m all 0) these keep their defaults: the ground truth's
   * board.json gives the kind too. */
  sls_calibration_board_kind board_kind; /* default SLS_CALIBRATION_BOARD_CHESSBOARD. For
                           * SLS_CALIBRATION_BOARD_CHARUCO (`sls calibrate --board charuco:COLSxROWS`)
                           * board_inner_cols and board_inner_rows are still its inner corners: its
                           * squares less one each way (charuco:12x9 is 11 x 8), at least 3 x 3 */
  double board_marker_m;  /* ChArUco only: the side of a marker, metres, positive and smaller than
                           * board_square_m (`--marker`); default 0 (a chessboard has none) */
  const char* board_dictionary; /* ChArUco only: the markers' ArUco dictionary, OpenCV's name as
                           * `--dictionary` takes it (e.g. "DICT_4X4_50", "DICT_6X6_250",
                           * "DICT_APRILTAG_36h11"; case-insensitive, "DICT_" optional), with at
                           * least as many markers as the board has light squares; NULL or ""
                           * (the default): "DICT_5X5_100" */
} sls_calibration_config;

/* Fills *config with the defaults. */
SLS_API void sls_calibration_config_init(sls_calibration_config* config);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_calibration_config_init_sized(sls_calibration_config* config, size_t struct_size);
#define sls_calibration_config_init(config) sls_calibration_config_init_sized((config), sizeof(*(config)))

/* Progress of sls_calibration_run() (and of sls_calibration_capture(), with its own stage and
 * units: sls_calibration_capture.h), handed to its callback. The library fills its own version
 * of the struct and sets struct_size to its size: a field added later is there only when
 * struct_size covers it. */
typedef struct sls_calibration_progress {
  size_t struct_size;
  const char* stage;  /* "calibrate" (sls_calibration_capture: "calibration capture") */
  size_t done;        /* views finished (the capture: poses) */
  size_t total;       /* views in all; done == total while solving */
  const char* detail; /* the view being read (its name), or "solve" */
} sls_calibration_progress;

/* Called by sls_calibration_run() before each view and before the solve, on the thread running
 * it. `progress` and its strings are valid during the call only. Return nonzero to go on, 0 to
 * stop: the run then returns SLS_ERROR_CANCELLED and makes no result. It must return normally
 * (no longjmp, no exceptions). */
typedef int (*sls_calibration_progress_callback)(const sls_calibration_progress* progress, void* user);

/* Calibrates from a recording or a folder of captures (see the top of this header).
 *   context:     decodes on its device (sls_context_uses_cuda). Not kept: it may be destroyed
 *                before the result.
 *   input_path:  the recording or the folder of captures.
 *   config:      NULL for the defaults, or a config from sls_calibration_config_init().
 *   progress:    NULL, or called before each view and before the solve (`user` handed to it).
 *   calibration: receives the result; the caller owns it and frees it with
 *                sls_calibration_destroy(). Left NULL on failure.
 * Blocks the calling thread. Fails with
 * SLS_ERROR_INVALID_ARGUMENT for a NULL argument, a bad config field (named: e.g. a board_kind
 * that is no sls_calibration_board_kind, a ChArUco marker not smaller than its square, an
 * unknown dictionary or one with too few markers, a marker or dictionary for a chessboard or for
 * the ground truth's board, a ChArUco board of fewer than 4 x 4 squares), a board not
 * described (no config board and no ground truth), a folder of captures without a pattern set,
 * a subfolder whose image count does not match the set, or fewer than 3 usable views (each
 * rejected view named with its reason);
 * SLS_ERROR_NOT_FOUND when input_path is not a folder (the message names it), or a folder with
 * no subfolder and no manifest; SLS_ERROR_FORMAT (or SLS_ERROR_VERSION_MISMATCH) for a corrupt
 * (or newer) recording manifest; SLS_ERROR_CANCELLED when the progress callback returned 0;
 * SLS_ERROR_UNSUPPORTED in a build without OpenCV. */
SLS_API sls_status sls_calibration_run(sls_context* context, const char* input_path,
                                       const sls_calibration_config* config,
                                       sls_calibration_progress_callback progress, void* user,
                                       sls_calibration** calibration, sls_error** error);

/* Frees a result and every string it handed out. sls_calibration_destroy(NULL) is a no-op. */
SLS_API void sls_calibration_destroy(sls_calibration* calibration);

/* The figures of a calibration. Versioned: initialise with sls_calibration_summary_init(); the
 * library fills only the fields the caller's struct_size covers. The string is owned by the
 * result: valid until sls_calibration_destroy(). */
typedef struct sls_calibration_summary {
  size_t struct_size;
  double camera_rms_px;          /* reprojection RMS of the camera calibrated alone */
  double projector_rms_px;       /* and of the projector alone */
  double stereo_rms_px;          /* of the joint refinement (both, with their extrinsics): the
                                  * figure sls_calibration_write() compares with max_rms_px */
  double joint_camera_rms_px;    /* under the final model, per device, over the used views */
  double joint_projector_rms_px;
  size_t views_total;            /* views in the input */
  size_t views_used;             /* in the solve */
  size_t views_rejected;         /* views_total - views_used */
  size_t camera_outliers;        /* board corners dropped as mislocated in the camera */
  size_t projector_outliers;     /* and in the projector */
  int turntable_axis_fitted;     /* 1: sls_calibration_get_turntable_axis() has an axis */
  double turntable_axis_rms_px;  /* the axis model's corner RMS; 0 without an axis */
  double seconds;                /* the run's wall time */
  int board_inner_cols;          /* the board used (the config's, or the ground truth's) */
  int board_inner_rows;
  double board_square_m;
  const char* pattern_set;       /* the pattern set's own name, e.g. "opencv_graycode_1024x768" */
  /* Against the exact calibration of a simulated capture (its ground truth). has_truth 0: all
   * of these are NaN; the axis errors are NaN also when either calibration has no axis. */
  int has_truth;
  double focal_rel_err;          /* the largest of |f - f exact| / f exact over fx, fy of camera and projector */
  double principal_point_err_px; /* the larger of camera's and projector's |(cx, cy) - exact| */
  double baseline_rel_err;       /* | |t| - |t exact| | / |t exact| */
  double rotation_err_deg;       /* angle between the estimated and exact camera-projector rotations */
  double axis_direction_err_deg; /* angle between the turntable axes */
  double axis_point_err_um;      /* distance of the exact axis from the estimated axis point, micrometres */
  /* Appended in API 0.10: the rest of the board used (the config's, or the ground truth's). */
  sls_calibration_board_kind board_kind;
  double board_marker_m;         /* a ChArUco board's marker side; 0 for a chessboard */
  const char* board_dictionary;  /* a ChArUco board's dictionary, e.g. "DICT_5X5_100"; "" for a chessboard */
} sls_calibration_summary;

/* Sets struct_size and clears the other fields. */
SLS_API void sls_calibration_summary_init(sls_calibration_summary* summary);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_calibration_summary_init_sized(sls_calibration_summary* summary, size_t struct_size);
#define sls_calibration_summary_init(summary) sls_calibration_summary_init_sized((summary), sizeof(*(summary)))

/* Fills *summary (from sls_calibration_summary_init()). */
SLS_API sls_status sls_calibration_get_summary(const sls_calibration* calibration, sls_calibration_summary* summary,
                                               sls_error** error);

/* A pinhole lens with Brown-Conrady distortion, as OpenCV's calibrateCamera gives it. Versioned:
 * initialise with sls_intrinsics_init(); the library fills only the fields struct_size covers. */
typedef struct sls_intrinsics {
  size_t struct_size;
  int width;     /* image size in pixels */
  int height;
  double fx, fy; /* focal lengths in pixels */
  double cx, cy; /* principal point in pixels */
  double k1, k2, k3; /* radial distortion */
  double p1, p2;     /* tangential distortion */
} sls_intrinsics;

/* Sets struct_size and clears the other fields. */
SLS_API void sls_intrinsics_init(sls_intrinsics* intrinsics);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_intrinsics_init_sized(sls_intrinsics* intrinsics, size_t struct_size);
#define sls_intrinsics_init(intrinsics) sls_intrinsics_init_sized((intrinsics), sizeof(*(intrinsics)))

/* Which lens of the rig. */
typedef enum sls_calibration_device {
  SLS_CALIBRATION_CAMERA = 0,
  SLS_CALIBRATION_PROJECTOR = 1
} sls_calibration_device;

/* The camera's or the projector's intrinsics (a struct from sls_intrinsics_init()).
 * SLS_ERROR_INVALID_ARGUMENT for another `device` value. */
SLS_API sls_status sls_calibration_get_intrinsics(const sls_calibration* calibration, sls_calibration_device device,
                                                  sls_intrinsics* intrinsics, sls_error** error);

/* The projector's pose in the camera frame: the 4x4 rigid transform taking projector
 * coordinates to camera coordinates, row-major, metres, written to T_camera_projector[16]. */
SLS_API sls_status sls_calibration_get_extrinsics(const sls_calibration* calibration, double T_camera_projector[16],
                                                  sls_error** error);

/* The turntable's rotation axis in the camera frame: point[3], the axis' point nearest the
 * board (metres), and direction[3], a unit vector (the table turns right-handed about it).
 * SLS_ERROR_NOT_FOUND when no axis was fitted (turntable_axis_fitted 0: a capture without
 * turntable angles, or too few of them); the message says why; point and direction are left as
 * they were. */
SLS_API sls_status sls_calibration_get_turntable_axis(const sls_calibration* calibration, double point[3],
                                                      double direction[3], sls_error** error);

/* The number of views in the input, used and rejected: indices 0 .. count - 1 of
 * sls_calibration_get_view(), in the input's order. */
SLS_API sls_status sls_calibration_view_count(const sls_calibration* calibration, size_t* count, sls_error** error);

/* One view (board pose). Versioned like sls_calibration_summary (sls_calibration_view_init()).
 * Strings are owned by the result: valid until sls_calibration_destroy(); never NULL. */
typedef struct sls_calibration_view {
  size_t struct_size;
  const char* name;            /* "frame 3" (a recording) or the capture's subfolder name */
  int used;                    /* 1: in the solve */
  const char* rejected_reason; /* why not, "" when used */
  int board_found;             /* 1: the chessboard was detected in the camera image */
  int has_turntable_angle;     /* 1: the recording gave this view a turntable angle */
  double turntable_angle_deg;  /* that angle; 0 without */
  double camera_rms_px;        /* the view's corner residual RMS under the final model (0 when unused) */
  double projector_rms_px;
  double obliquity_deg;        /* the board normal's angle from the camera's axis (0 when not solved) */
  size_t corners;              /* the board's inner corners (cols x rows) */
  size_t projector_corners_valid; /* of them, located in the projector through the decoded patterns */
  double decoded_fraction;     /* of the camera pixels around the board's corners (the local
                                  homographies' windows), decoded */
} sls_calibration_view;

/* Sets struct_size and clears the other fields. */
SLS_API void sls_calibration_view_init(sls_calibration_view* view);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_calibration_view_init_sized(sls_calibration_view* view, size_t struct_size);
#define sls_calibration_view_init(view) sls_calibration_view_init_sized((view), sizeof(*(view)))

/* Fills *view (from sls_calibration_view_init()) with view `index`; SLS_ERROR_INVALID_ARGUMENT
 * when index >= sls_calibration_view_count(). */
SLS_API sls_status sls_calibration_get_view(const sls_calibration* calibration, size_t index,
                                            sls_calibration_view* view, sls_error** error);

/* The cameras of the head: 1 for a one-camera capture, N for a folder camera0 .. camera(N-1). */
SLS_API sls_status sls_calibration_camera_count(const sls_calibration* calibration, size_t* count, sls_error** error);

/* One camera of the head (API 0.8). Versioned like sls_calibration_summary
 * (sls_calibration_camera_init()). Camera 0 is the primary camera, the frame of everything
 * else. */
typedef struct sls_calibration_camera {
  size_t struct_size;
  double camera_rms_px;          /* this camera calibrated alone */
  double projector_rms_px;       /* the projector calibrated alone from this camera's views */
  double stereo_rms_px;          /* this camera's joint refinement with the projector */
  size_t views_used;             /* of this camera's views, in its solve */
  double T_camera0_camera[16];   /* this camera's frame -> camera 0's, row-major, metres
                                  * (identity for camera 0) */
  double camera_camera_rms_px;   /* the camera-camera solve's RMS (both images); 0 for camera 0 */
  size_t camera_camera_views;    /* board poses both this camera and camera 0 used; 0 for camera 0 */
  /* Against a simulated capture's exact calibration. has_truth 0: these are NaN; the
   * camera-camera ones are NaN for camera 0 too. */
  int has_truth;
  double focal_rel_err;          /* this camera's, the larger over fx, fy */
  double principal_point_err_px;
  double camera_camera_baseline_rel_err;
  double camera_camera_rotation_err_deg;
} sls_calibration_camera;

/* Sets struct_size and clears the other fields. */
SLS_API void sls_calibration_camera_init(sls_calibration_camera* camera);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_calibration_camera_init_sized(sls_calibration_camera* camera, size_t struct_size);
#define sls_calibration_camera_init(camera) sls_calibration_camera_init_sized((camera), sizeof(*(camera)))

/* Camera `index` of the head: its figures and pose into *camera and its lens into *intrinsics
 * (either may be NULL, not both; each from its _init()). SLS_ERROR_INVALID_ARGUMENT when index
 * >= sls_calibration_camera_count(). */
SLS_API sls_status sls_calibration_get_camera(const sls_calibration* calibration, size_t index,
                                              sls_calibration_camera* camera, sls_intrinsics* intrinsics,
                                              sls_error** error);

/* Writes the calibration (camera, projector, extrinsics, the axis when fitted, the RMS figures,
 * the time and a description; a head's other cameras with their poses against camera 0) as calibration.yml to `path`: OpenCV FileStorage YAML, readable by
 * cv::FileStorage, by sls_scan_run_devices' calibration_path and by `sls`; written to a
 * temporary name and renamed, so a failure never leaves half a file.
 * Refuses (SLS_ERROR_INVALID_ARGUMENT, nothing written, the message giving both figures) when
 * the stereo RMS (of a head: any camera's, or any camera-camera RMS) is above the config's
 * max_rms_px, unless `force` is nonzero.
 * SLS_ERROR_IO naming the path when it cannot be written. */
SLS_API sls_status sls_calibration_write(const sls_calibration* calibration, const char* path, int force,
                                         sls_error** error);

#ifdef __cplusplus
}
#endif

#endif /* SLS_CALIBRATION_H */
