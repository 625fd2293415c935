/* Quality figures and reports: a scan's result measured against a simulated recording's ground
 * truth (what `sls eval` prints) and the HTML report `sls scan` writes, for a result folder.
 *
 * A result folder holds the model as cloud.ply and, optionally, mesh.ply, trajectory.txt (TUM),
 * report.json and undeformed/ (the model and trajectory as tracked, before online deformation).
 * `sls scan --out DIR` writes one; a program that scans through sls_scan.h makes one with
 * sls_scan_write_cloud(scan, "DIR/cloud.ply", ...) and sls_scan_write_trajectory(scan,
 * "DIR/trajectory.txt", ...).
 *
 * The figures (definitions: sdk/eval/evaluate.h), all against the recording's exact scene:
 *   c2c          the distance of each model point from the exact surface: mean, RMS, 95th
 *                percentile, max; edge c2c the same within a few voxels of a crease;
 *   coverage     the fraction of the surface the recording saw that the model covers;
 *   ate          the absolute trajectory error (TUM's: rigid alignment, then the RMS and max of
 *                the camera positions' differences);
 *   loop closure the error of the relative motion from the first to the last frame.
 * The model is taken to be in the recording's object frame; with a trajectory.txt its first
 * pose is aligned to the true one (config->align_first_pose).
 *
 * Threads: sls_evaluate() and sls_report_write_html() block the calling thread (seconds: every
 * reference point is checked against the frames that saw it); their progress callback runs on
 * that thread. They may run on several threads at once, for different result folders. An
 * sls_evaluation is immutable: its getters may be called from several threads at once.
 *
 * Typical use:
 *   sls_evaluation* evaluation = NULL;
 *   sls_error* error = NULL;
 *   if (sls_evaluate(context, "out", "out/recording", NULL, NULL, NULL, &evaluation, &error) == SLS_OK) {
 *     sls_evaluation_summary summary;
 *     sls_evaluation_summary_init(&summary);
 *     sls_evaluation_get_summary(evaluation, 0, &summary, NULL);
 *     printf("C2C mean %.2f um, ATE %.2f um\n", summary.c2c_mean_m * 1e6, summary.ate_rmse_m * 1e6);
 *   } else {
 *     fprintf(stderr, "%s\n", sls_error_message(error));
 *   }
 *   sls_evaluation_destroy(evaluation);
 *   sls_error_free(error);
 */
#ifndef SLS_EVAL_H
#define SLS_EVAL_H

#include <stddef.h>

#include "sls/sls_context.h"
#include "sls/sls_export.h"
#include "sls/sls_status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A result's figures. Opaque; immutable once made. */
typedef struct sls_evaluation sls_evaluation;

/* How to measure. Versioned by its size: initialise with sls_eval_config_init(), which sets
 * struct_size and the defaults, then change fields. Later library versions only append fields. */
typedef struct sls_eval_config {
  size_t struct_size;
  double voxel_size_m;           /* the result's voxel size, which scales the bands below; default
                                  * 0: voxel_size_m of RESULT/report.json */
  double edge_band_voxels;       /* edge c2c: points within this many voxels of a crease; default 3 */
  double coverage_radius_voxels; /* a surface point is covered by a model point this close; default 2 */
  int visibility_stride;         /* test every n-th frame for what the recording saw; default 1 */
  int align_first_pose;          /* 1 (default): align trajectory.txt's first pose to the true one */
  int register_to_surface;       /* 1: then register the model rigidly onto the exact surface (the
                                  * shape's error alone); default 0 */
} sls_eval_config;

/* Fills *config with the defaults. */
SLS_API void sls_eval_config_init(sls_eval_config* config);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_eval_config_init_sized(sls_eval_config* config, size_t struct_size);
#define sls_eval_config_init(config) sls_eval_config_init_sized((config), sizeof(*(config)))

/* Progress of sls_evaluate() and sls_report_write_html(), handed to their callback. The library
 * fills its own version of the struct and sets struct_size to its size. */
typedef struct sls_eval_progress {
  size_t struct_size;
  const char* stage;  /* what runs: "register", "c2c", "visibility" (measuring), "report" (writing) */
  size_t done;        /* units finished (e.g. frames checked for what they saw) */
  size_t total;       /* units in all; 0 when unknown */
  const char* detail; /* optional, e.g. the file being written; "" when none */
} sls_eval_progress;

/* Called on the thread doing the work; `progress` and its strings are valid during the call
 * only. Return nonzero to go on, 0 to stop: the call then returns SLS_ERROR_CANCELLED and makes
 * nothing. It must return normally (no longjmp, no exceptions). */
typedef int (*sls_eval_progress_callback)(const sls_eval_progress* progress, void* user);

/* Measures the result folder `result_path` against the simulated recording `recording_path`
 * (a recording with groundtruth/, e.g. what `sls sim` or `sls scan --sim` wrote), and the model as
 * tracked too when the folder holds undeformed/cloud.ply.
 *   context:    not kept (it may be destroyed before the result).
 *   config:     NULL for the defaults, or a config from sls_eval_config_init().
 *   progress:   NULL, or called as the work goes on (`user` handed to it).
 *   evaluation: receives the result; the caller owns it and frees it with
 *               sls_evaluation_destroy(). Left NULL on failure.
 * Fails, naming the file, with SLS_ERROR_INVALID_ARGUMENT for a NULL argument, a bad config field,
 * a recording without ground truth, an empty model, or no voxel size (no config->voxel_size_m and
 * no report.json); SLS_ERROR_NOT_FOUND for a missing cloud.ply, recording or ground-truth file;
 * SLS_ERROR_FORMAT for a corrupt one; SLS_ERROR_CANCELLED when the callback returned 0. */
SLS_API sls_status sls_evaluate(sls_context* context, const char* result_path, const char* recording_path,
                                const sls_eval_config* config, sls_eval_progress_callback progress, void* user,
                                sls_evaluation** evaluation, sls_error** error);

/* Frees a result and every string it handed out. sls_evaluation_destroy(NULL) is a no-op. */
SLS_API void sls_evaluation_destroy(sls_evaluation* evaluation);

/* The figures of one model, metres and degrees. Versioned: initialise with
 * sls_evaluation_summary_init(); the library fills only the fields struct_size covers. A figure
 * with nothing to measure is NaN. */
typedef struct sls_evaluation_summary {
  size_t struct_size;
  double voxel_size_m;     /* the voxel size used (the config's or report.json's) */
  size_t points;           /* points of cloud.ply */
  double c2c_mean_m;       /* distance from the exact surface over all points */
  double c2c_rms_m;
  double c2c_p95_m;
  double c2c_max_m;
  size_t edge_points;      /* points near a crease; 0 (and NaN below) for a scene without creases */
  double edge_c2c_mean_m;
  double edge_c2c_rms_m;
  double coverage;         /* in [0, 1]; NaN when no reference point counted */
  int has_trajectory;      /* 1: the trajectory figures below are measured (trajectory.txt and the
                            * true trajectory share at least two frames); 0: they are NaN */
  size_t trajectory_frames; /* frames matched to a true pose */
  double ate_rmse_m;
  double ate_max_m;
  double loop_closure_error_m;
  double loop_closure_error_deg;
  int has_undeformed;      /* 1: the result holds the model as tracked, measured too (ask for it
                            * with sls_evaluation_get_summary(..., 1, ...)) */
} sls_evaluation_summary;

/* Sets struct_size and clears the other fields. */
SLS_API void sls_evaluation_summary_init(sls_evaluation_summary* summary);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_evaluation_summary_init_sized(sls_evaluation_summary* summary, size_t struct_size);
#define sls_evaluation_summary_init(summary) sls_evaluation_summary_init_sized((summary), sizeof(*(summary)))

/* Fills *summary with the figures of the model (undeformed 0) or of the model as tracked
 * (undeformed 1: SLS_ERROR_NOT_FOUND when the result has none). */
SLS_API sls_status sls_evaluation_get_summary(const sls_evaluation* evaluation, int undeformed,
                                              sls_evaluation_summary* summary, sls_error** error);

/* Every figure as one JSON object: the keys `sls eval --json` prints (micrometres and degrees,
 * null where there is nothing to measure; the model as tracked under "undeformed"). *json is
 * owned by the evaluation: valid until sls_evaluation_destroy(). */
SLS_API sls_status sls_evaluation_json(const sls_evaluation* evaluation, const char** json, sls_error** error);

/* Each model point's distance from the exact surface (metres, cloud.ply's point order), for a
 * heat map. Copies min(capacity, points) values into errors_m (which may be NULL when capacity
 * is 0) and sets *count to the number of points, so a first call with capacity 0 sizes the
 * buffer. */
SLS_API sls_status sls_evaluation_get_point_errors(const sls_evaluation* evaluation, float* errors_m,
                                                   size_t capacity, size_t* count, sls_error** error);

/* How to draw a report. Versioned: initialise with sls_report_config_init(). The strings are
 * read during sls_report_write_html() only. */
typedef struct sls_report_config {
  size_t struct_size;
  const char* recording_path; /* a simulated recording to measure against (quality table, error
                               * heat map, true trajectory); default NULL: none */
  const char* title;          /* default NULL: "Scan of RESULT" */
  int image_size_px;          /* longer side of each render, 64 to 4096; default 800 */
  double voxel_size_m;        /* the result's voxel size, for measuring against the recording;
                               * default 0: voxel_size_m of RESULT/report.json */
} sls_report_config;

/* Fills *config with the defaults. */
SLS_API void sls_report_config_init(sls_report_config* config);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_report_config_init_sized(sls_report_config* config, size_t struct_size);
#define sls_report_config_init(config) sls_report_config_init_sized((config), sizeof(*(config)))

/* Writes RESULT/report.html (self-contained, with its PNG figures beside it: shaded renders of
 * the model, the trajectory, with a recording the quality figures and an error heat map, with
 * undeformed/ the correction online deformation made), as `sls scan` does. RESULT's report.json,
 * when there, gives the summary (frames, lost frames, times); the report is drawn without it
 * otherwise. Each file is written atomically. Fails as sls_evaluate() (with a recording), and with
 * SLS_ERROR_IO, naming the path, when RESULT cannot be written. */
SLS_API sls_status sls_report_write_html(sls_context* context, const char* result_path,
                                         const sls_report_config* config, sls_eval_progress_callback progress,
                                         void* user, sls_error** error);

#ifdef __cplusplus
}
#endif

#endif /* SLS_EVAL_H */
