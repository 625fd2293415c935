/* Frames the caller feeds a scan, from its own capture code, as librealsense's software device:
 * depth maps (float metres) or pattern stacks (8- or 16-bit images of the scan's pattern set),
 * each decoded when needed, tracked and fused exactly as a run's frames are.
 *
 *   sls_feed_config feed;
 *   sls_feed_config_init(&feed);
 *   feed.calibration_path = "head/calibration.yml";
 *   sls_scan_start_feed(scan, &feed, NULL);           (a new, empty model)
 *   for each capture:
 *     sls_depth_frame frame;
 *     sls_depth_frame_init(&frame);
 *     frame.depth_m = depth; frame.width = w; frame.height = h;
 *     frame.has_turntable_angle = 1; frame.turntable_angle_deg = angle;
 *     sls_scan_add_depth(scan, &frame, NULL, NULL);   (the frame callback runs, then it returns)
 *     ... sls_scan_render_preview(), sls_scan_get_cloud() (sls_results.h) between frames
 *   sls_scan_close_loop(scan, NULL, NULL); sls_scan_write_cloud(scan, "model.ply", NULL);
 *
 * A feed is the scan's model as a run's is: after sls_scan_start_feed() the summary, loop
 * closure, writes and getters work on the fed frames; a run, or another start, discards it.
 * Frames are numbered 0, 1, ... in the order added (the reports' index; recording_frames 0).
 *
 * Threads: each call holds the scan for its length, as sls_scan.h's functions do (a call from
 * another thread meanwhile, or from the frame callback, gets SLS_ERROR_BUSY); frames may come
 * from any thread, one call at a time. The caller's arrays are read during the call only: the
 * library keeps no pointer to them.
 */
#ifndef SLS_FEED_H
#define SLS_FEED_H

#include <stddef.h>
#include <stdint.h>

#include "sls/sls_export.h"
#include "sls/sls_scan.h"
#include "sls/sls_status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* How the fed frames were captured. Versioned by its size (sls_feed_config_init()). */
typedef struct sls_feed_config {
  size_t struct_size;
  const char* calibration_path; /* required: calibration.yml of the head (sls_calibration.h or
                                 * `sls calibrate`): the camera's size, which every frame must
                                 * have, and the projector's, which sizes the pattern set */
  int bit_depth;                /* significant bits of pattern-stack pixels, 8 .. 16; default 12.
                                 * Unused for depth maps */
} sls_feed_config;

SLS_API void sls_feed_config_init(sls_feed_config* config);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_feed_config_init_sized(sls_feed_config* config, size_t struct_size);
#define sls_feed_config_init(config) sls_feed_config_init_sized((config), sizeof(*(config)))

/* Starts a feed: discards the scan's previous model (as a run does) and reads the calibration.
 * patterns_per_stack: optional (NULL); receives the images a pattern stack must have: the set
 * sls_projector_load_scan_patterns() loads into a projector of the calibration's size, in its order.
 * SLS_ERROR_INVALID_ARGUMENT for a missing path or a bad bit_depth or config.struct_size;
 * SLS_ERROR_NOT_FOUND / SLS_ERROR_FORMAT for a calibration that cannot be read; the config's
 * errors of sls_scan_create() (e.g. use_turntable_prior with a calibration without an axis), and
 * a scan whose config.poses is SLS_POSES_GROUNDTRUTH (fed frames have no ground truth);
 * SLS_ERROR_CANCELLED for a cancelled scan; SLS_ERROR_BUSY during a run. */
SLS_API sls_status sls_scan_start_feed(sls_scan* scan, const sls_feed_config* config, int* patterns_per_stack,
                                       sls_error** error);

/* What a frame carries besides its pixels. */
typedef struct sls_depth_frame {
  size_t struct_size;
  const float* depth_m;        /* camera-frame z in metres, 0 (or NaN) where there is none */
  int width, height;           /* the calibration's camera size */
  size_t stride_bytes;         /* from one row to the next; 0: width x sizeof(float) */
  int64_t timestamp_ns;        /* for the trajectory's stamps; default 0 */
  int has_turntable_angle;     /* 1: turntable_angle_deg is the table's reading at this frame */
  double turntable_angle_deg;  /* (with use_turntable_prior, the pose guess) */
} sls_depth_frame;

SLS_API void sls_depth_frame_init(sls_depth_frame* frame);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_depth_frame_init_sized(sls_depth_frame* frame, size_t struct_size);
#define sls_depth_frame_init(frame) sls_depth_frame_init_sized((frame), sizeof(*(frame)))

typedef struct sls_stack_frame {
  size_t struct_size;
  const void* const* images;   /* image_count pointers, one image per pattern, in the set's order */
  size_t image_count;          /* patterns_per_stack of sls_scan_start_feed() */
  int width, height;           /* the calibration's camera size */
  int bytes_per_pixel;         /* 1 (uint8_t) or 2 (uint16_t, host byte order) */
  size_t stride_bytes;         /* from one row to the next; 0: width x bytes_per_pixel */
  int64_t timestamp_ns;
  int has_turntable_angle;
  double turntable_angle_deg;
} sls_stack_frame;

SLS_API void sls_stack_frame_init(sls_stack_frame* frame);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_stack_frame_init_sized(sls_stack_frame* frame, size_t struct_size);
#define sls_stack_frame_init(frame) sls_stack_frame_init_sized((frame), sizeof(*(frame)))

/* Adds one frame: tracks and fuses it (a stack decoded first), calls the frame callback with its
 * report (and its depth map, sls_scan.h), then returns.
 *   report: optional (NULL), from sls_frame_report_init(): receives the same report (its reason
 *           valid until the next call on the scan; depth_m NULL).
 * SLS_OK for a frame processed, also one lost or skipped (the report says so and why: the
 * scan goes on). SLS_ERROR_INVALID_ARGUMENT, the scan unchanged, for a NULL or short array, a
 * size other than the camera's, a stride smaller than a row, a stack of another length or
 * pixel size, a bad struct_size; before sls_scan_start_feed() (or after a run replaced the
 * feed). SLS_ERROR_CANCELLED for a cancelled scan; SLS_ERROR_BUSY during another call. */
SLS_API sls_status sls_scan_add_depth(sls_scan* scan, const sls_depth_frame* frame, sls_frame_report* report,
                                      sls_error** error);

SLS_API sls_status sls_scan_add_stack(sls_scan* scan, const sls_stack_frame* frame, sls_frame_report* report,
                                      sls_error** error);

#ifdef __cplusplus
}
#endif

#endif /* SLS_FEED_H */
