/* Scans: frames decoded, tracked and fused into a model, with a report per frame.
 *
 * A scan is made from a context (which says CPU or CUDA) and a config, then run on a source:
 *   sls_scan_run_recording()  a recording folder (written by `sls sim`, `sls scan` or
 *                             sls_scan_run_devices()); it carries its calibration
 *   sls_scan_run_devices()    a camera, a projector and optionally a turntable by URI
 *                             (sls_device.h: hardware or sim://), captured into a new recording
 *                             (one pattern stack per turntable position), each stack scanned
 *                             as it is recorded
 * Per frame: decode the pattern stack (or take the recording's depth map), track it against the
 * model (ICP from a constant-velocity guess, or with use_turntable_prior from the recorded
 * turntable angle about the calibrated axis), integrate it (GTSDF or TSDF), move the volume
 * when the camera leaves it, raycast the model for the next frame. A frame that cannot be read
 * or decoded is skipped, one the tracker cannot register is lost: neither touches the model,
 * and the scan goes on. With online_deformation (the default) a deformation graph, solved on a
 * worker thread of the scan beside the frame loop, corrects the drift of tracking (keyframes
 * are its nodes, surface seen again its constraints); after a run that went round the object
 * (a turntable revolution), sls_scan_close_loop() registers the last frame to the first and
 * closes the loop. After a run the model (cloud, mesh) and the trajectory of the fused frames
 * can be written, deformed by the graph. The world frame is the camera frame of the first
 * fused frame.
 *
 * Threads: a run blocks the thread that calls it; the frame callback runs on that thread.
 * sls_scan_cancel() may be called from any thread, the frame callback included, and the getters
 * of sls_results.h from the frame callback. Every other function on a scan returns
 * SLS_ERROR_BUSY while a run is in progress (from the callback too);
 * different scans are independent. Destroying a scan while it runs is the caller's bug. The
 * deformation worker is the scan's own thread, started by a run and stopped by the next run or
 * sls_scan_destroy() (after its current job); no callback runs on it, and the calls that read
 * the graph (sls_scan_close_loop, sls_scan_get_summary, the writes) wait for it to catch up.
 * The runs read or capture the next frames on a thread of their own while the calling thread
 * fuses (sls_scan_run_devices drives the devices from it); it ends before the run returns, and
 * no callback runs on it.
 *
 * Typical use:
 *   static void on_frame(const sls_frame_report* report, void* user) {
 *     printf("frame %d %s\n", report->index, report->status == SLS_FRAME_FUSED ? "fused" : report->reason);
 *   }
 *   ...
 *   sls_scan_config config;
 *   sls_scan* scan = NULL;
 *   sls_scan_config_init(&config);
 *   config.use_turntable_prior = 1;
 *   if (sls_scan_create(context, &config, &scan, NULL) == SLS_OK &&
 *       sls_scan_set_frame_callback(scan, on_frame, NULL, NULL) == SLS_OK) {
 *     sls_error* error = NULL;
 *     sls_status status = sls_scan_run_recording(scan, "scans/knob", &error);
 *     if (status == SLS_OK && sls_scan_close_loop(scan, NULL, NULL) != SLS_OK)
 *       fprintf(stderr, "loop not closed: the model as online deformation left it\n");
 *     if (status == SLS_OK || status == SLS_ERROR_CANCELLED) sls_scan_write_mesh(scan, "knob.ply", NULL);
 *     if (status != SLS_OK) fprintf(stderr, "%s\n", sls_error_message(error));
 *     sls_error_free(error);
 *   }
 *   sls_scan_destroy(scan);
 */
#ifndef SLS_SCAN_H
#define SLS_SCAN_H

#include <stddef.h>
#include <stdint.h>

#include "sls/sls_context.h"
#include "sls/sls_export.h"
#include "sls/sls_status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A scan: its configuration, its frame callback, and after a run its model. Opaque. */
typedef struct sls_scan sls_scan;

typedef enum sls_fusion_method {
  SLS_FUSION_GTSDF = 0, /* the detail-preserving anisotropic TSDF (Sekkati et al.) */
  SLS_FUSION_TSDF = 1   /* the plain weighted TSDF */
} sls_fusion_method;

typedef enum sls_gtsdf_penalty {
  SLS_GTSDF_PENALTY_DEFAULT = 0,       /* the library's: Geman-McClure */
  SLS_GTSDF_PENALTY_PERONA_MALIK = 1,
  SLS_GTSDF_PENALTY_CHARBONNIER = 2,
  SLS_GTSDF_PENALTY_GEMAN_MCCLURE = 3
} sls_gtsdf_penalty;

typedef enum sls_pose_source {
  SLS_POSES_TRACK = 0,      /* ICP against the model, into a moving volume */
  SLS_POSES_GROUNDTRUTH = 1 /* a simulated recording's true poses (groundtruth/trajectory.txt), one
                             * fixed volume around its reference surface; no deformation */
} sls_pose_source;

typedef enum sls_icp_weights {
  SLS_ICP_WEIGHTS_CONFIDENCE = 0, /* the decoder's per-pixel confidence (an inverse predicted variance);
                                   * depth maps without one count equally */
  SLS_ICP_WEIGHTS_EQUAL = 1
} sls_icp_weights;

typedef enum sls_loop_closure_mode {
  SLS_LOOP_CLOSURE_CALLER = 0, /* a run leaves it to the caller's sls_scan_close_loop() */
  SLS_LOOP_CLOSURE_AUTO = 1,   /* a run ends by closing the loop when its recording is a full
                                * turntable revolution (`sls scan`'s default) */
  SLS_LOOP_CLOSURE_ON = 2      /* a run (not cancelled) always ends by closing the loop */
} sls_loop_closure_mode;

/* What the moving volume ships of surface it already shipped once (a long session circling the
 * object again and again fuses the same surface on every pass). */
typedef enum sls_revisit_policy {
  SLS_REVISITS_AUTO = 0,  /* every pass until the scan has turned one revolution and one volume
                           * move's rotation (15 degrees) more, then only surface no earlier move
                           * shipped: a single revolution is kept whole (its seam's second pass
                           * is what the loop closure aligns), a longer session's model stays
                           * bounded by the object's surface */
  SLS_REVISITS_KEEP = 1,  /* every pass: each revolution adds a copy */
  SLS_REVISITS_MERGE = 2  /* only surface no earlier move shipped, from the first move on */
} sls_revisit_policy;

/* Scan configuration. Versioned by its size: initialise with sls_scan_config_init(), which sets
 * struct_size and the defaults, then change fields. Later library versions only append fields.
 * The volume moves with the camera; it is sized at the first fused frame.
 *
 * Every option of `sls scan` that shapes the scan has its field, with `sls scan`'s default
 * (loop_closure aside: see there); the others are the tool's own choices or live elsewhere:
 *   --input REC                  sls_scan_run_recording(scan, REC)
 *   --camera/--projector/--turntable URI, --frames N
 *                                sls_capture_config (sls_scan_run_devices)
 *   --calibration FILE           with --camera: sls_capture_config.calibration_path; with
 *                                --input: calibration_path below
 *   --sim PRESET, --object NAME  a sim:// camera and projector URI, e.g.
 *                                "sim://knurled-knob?preset=ci", with sls_scan_run_devices
 *   --device cpu|cuda[:N]        sls_context_config.device and cuda_device_id
 *   --fusion                     fusion            --gtsdf-lambda      gtsdf_lambda
 *   --gtsdf-kappa                gtsdf_kappa       --gtsdf-penalty     gtsdf_penalty
 *   --gtsdf-iterations           gtsdf_iterations  --poses             poses
 *   --turntable-prior            use_turntable_prior
 *   --photometric-weight         photometric_weight
 *   --icp-weights                icp_weights       --icp-crease-deg    icp_crease_deg
 *   --deformation on|off         online_deformation
 *   --loop-closure on|off        loop_closure (SLS_LOOP_CLOSURE_ON, or _CALLER without calling
 *                                sls_scan_close_loop); unset: SLS_LOOP_CLOSURE_AUTO
 *   --loop-frames                loop_frames
 *   --voxel-um U                 voxel_size_m = U * 1e-6
 *   --max-voxels M               max_voxels = M * 1e6
 *   --max-gpu-memory B           max_gpu_bytes = B
 *   --revisits auto|keep|merge   revisits
 *   --no-record                  no_record (sls_scan_run_devices)
 *   --out, --resume, and the global --json, -q, -v: the tool's own (its output folder, its
 *   recovery of a cut-off capture, its printing); the library writes what the caller asks
 *   (sls_scan_write_*, sls_results.h) and logs through sls_log.h.
 * volume_size_m has no option: the tool always takes the automatic extent. */
typedef struct sls_scan_config {
  size_t struct_size;
  sls_fusion_method fusion; /* --fusion; default SLS_FUSION_GTSDF */
  int use_turntable_prior;  /* --turntable-prior. 1: the recorded turntable angles about the
                             * calibrated axis guess each pose (needs a recording with angles and
                             * a calibrated axis); default 0: depth alone, from a constant-velocity
                             * guess */
  double voxel_size_m;      /* --voxel-um; default 0: two pixel footprints at the focus distance,
                             * grown until the volume fits max_voxels */
  double volume_size_m[3];  /* extent along the camera's x, y, z; default {0, 0, 0}: the camera's
                             * field of view at the focus distance across, half as deep. All
                             * three 0 or all three positive */
  double max_voxels;        /* --max-voxels; the largest volume (one of the moving volume's two
                             * buffers) the automatic voxel size is grown to fit; default 0:
                             * 256e6 with CUDA, 48e6 on the CPU */
  /* Appended later (a caller whose struct_size ends before a field gets its default): */
  int online_deformation;   /* --deformation; default 1: a deformation graph, solved on a worker
                             * thread beside the frame loop, corrects the tracked model's drift
                             * (keyframes as nodes, revisited surface as constraints); the model,
                             * trajectory and sls_scan_close_loop() use it. 0: off, the model as
                             * tracked, and no loop closure */
  /* Appended in API 0.5: */
  const char* calibration_path; /* --calibration with --input: decode a run's recording with this
                                 * calibration.yml instead of its own (e.g. a new calibration of
                                 * the head; its camera must have the recording's size). Read by
                                 * sls_scan_create(), which fails naming it when it cannot be
                                 * read. Default NULL: the recording's */
  double gtsdf_lambda;          /* --gtsdf-lambda, with SLS_FUSION_GTSDF: the anisotropic term's
                                 * weight (alpha = lambda * beta, beta = 1/6), 1e-3 .. 1e3;
                                 * default 0: the library's, 4 */
  double gtsdf_kappa;           /* --gtsdf-kappa, with SLS_FUSION_GTSDF: the penalty's edge-
                                 * stopping scale in units of the truncated SDF, 1e-4 .. 10;
                                 * default 0: the library's, 0.03 */
  sls_gtsdf_penalty gtsdf_penalty; /* --gtsdf-penalty, with SLS_FUSION_GTSDF; default
                                    * SLS_GTSDF_PENALTY_DEFAULT (Geman-McClure) */
  int gtsdf_iterations;         /* --gtsdf-iterations, with SLS_FUSION_GTSDF: Gauss-Seidel sweeps
                                 * per frame, 1 .. 100; default 0: the library's, 3 */
  sls_pose_source poses;        /* --poses; default SLS_POSES_TRACK. SLS_POSES_GROUNDTRUTH: runs
                                 * of simulated recordings only (not feeds); as in the tool, the
                                 * tracking fields, use_turntable_prior and online_deformation
                                 * are then not used */
  int loop_frames;              /* --loop-frames: how many of the last fused frames a loop
                                 * closure registers to the first, 1 .. 64; default 2 */
  double photometric_weight;    /* --photometric-weight, tracking: the photometric term's weight
                                 * on each stack's white - black texture, relative to ICP's,
                                 * 0 .. 1e6; default 0: off */
  double icp_crease_deg;        /* --icp-crease-deg, tracking: ICP sets aside matches near a model
                                 * crease turning by more than this, 0 (off) .. 179; default 15 */
  sls_icp_weights icp_weights;  /* --icp-weights, tracking; default SLS_ICP_WEIGHTS_CONFIDENCE */
  sls_loop_closure_mode loop_closure; /* --loop-closure; default SLS_LOOP_CLOSURE_CALLER, not the
                                 * tool's AUTO: a program older than this field closes the loop
                                 * itself, and a second closure would add its constraints twice.
                                 * A closure a run makes and that fails (no loop to close) is
                                 * logged as a warning, the run still SLS_OK: the summary's
                                 * loop_closed says whether it closed */
  double max_gpu_bytes;         /* --max-gpu-memory: a budget in bytes for what the scan allocates
                                 * on a CUDA GPU, e.g. 6e9 on an 8 GB Jetson Orin. The moving
                                 * volume is sized at the first fused frame to fit beside the
                                 * frames' buffers: an automatic voxel size grows, a given
                                 * voxel_size_m keeps its size and the volume's extent shrinks.
                                 * Under 64 voxels a side the run fails with
                                 * SLS_ERROR_OUT_OF_MEMORY saying what the budget leaves room for.
                                 * 0 .. 1e15; default 0: none. Not used on the CPU */
  /* Appended in API 0.6: */
  sls_revisit_policy revisits;  /* --revisits; default SLS_REVISITS_AUTO */
  /* Appended in API 0.7: */
  int padding_0_6;              /* not a setting: the 0.6 struct ended here in padding (a 0.6
                                 * caller's bytes are undefined), so the library never reads it */
  int no_record;                /* --no-record, since 0.7: sls_scan_run_devices fuses the capture
                                 * while it runs and writes none of it (capture.recording_path
                                 * must then be NULL or ""): nothing of the stacks touches the
                                 * disk. Lost with it: the recording (no rescan with
                                 * sls_scan_run_recording, no resume of a capture cut off).
                                 * Refused with SLS_POSES_GROUNDTRUTH (known poses come from a
                                 * recording). Not used by sls_scan_run_recording. Default 0: the
                                 * capture is recorded, on a writer thread beside it */
} sls_scan_config;

/* Fills *config with the defaults. */
SLS_API void sls_scan_config_init(sls_scan_config* config);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_scan_config_init_sized(sls_scan_config* config, size_t struct_size);
#define sls_scan_config_init(config) sls_scan_config_init_sized((config), sizeof(*(config)))

/* Creates a scan.
 *   context: where it runs (sls_context_uses_cuda: the CUDA GPU or the CPU); sim:// devices of
 *            sls_scan_run_devices() render there too. Not kept: it may be destroyed first.
 *   config:  NULL for the defaults, or a config from sls_scan_config_init().
 *   scan:    receives the scan; the caller owns it and frees it with sls_scan_destroy(). Left
 *            NULL on failure.
 * Fails with SLS_ERROR_INVALID_ARGUMENT naming the bad config field (a value out of its range,
 * gtsdf_* set with SLS_FUSION_TSDF), and with the reader's SLS_ERROR_NOT_FOUND / SLS_ERROR_FORMAT
 * naming config->calibration_path when that cannot be read. Memory for the volume is
 * taken at the first fused frame of a run, not here. */
SLS_API sls_status sls_scan_create(sls_context* context, const sls_scan_config* config, sls_scan** scan,
                                   sls_error** error);

/* Frees a scan and its model. sls_scan_destroy(NULL) is a no-op. */
SLS_API void sls_scan_destroy(sls_scan* scan);

typedef enum sls_frame_status {
  SLS_FRAME_FUSED = 0,  /* tracked (or the first frame) and integrated into the model */
  SLS_FRAME_LOST = 1,   /* decoded, but the tracker could not register it: not fused */
  SLS_FRAME_SKIPPED = 2 /* could not be read or decoded (corrupt, incomplete): not fused */
} sls_frame_status;

/* One frame's outcome, handed to the frame callback. The library fills its own version of the
 * struct and sets struct_size to its size: a field added in a later version is there only when
 * struct_size covers it. */
typedef struct sls_frame_report {
  size_t struct_size;
  int index;                 /* the frame's index in the recording (frames come in order) */
  size_t recording_frames;   /* frames in the recording: index + 1 of recording_frames done */
  int64_t timestamp_ns;      /* the recording's timestamp of the frame */
  sls_frame_status status;
  const char* reason;        /* why lost or skipped, "" when fused (except `unverified` frames:
                              * why tracking could not verify them); valid during the callback only */
  double T_world_camera[16]; /* 4x4 row-major, metres: the fused pose (a lost frame: the guess it
                              * was tracked from; a skipped frame: identity) */
  size_t depth_pixels;       /* valid depth pixels of the decoded frame */
  int tracked;               /* 1: registered by ICP, the next two fields are its; 0: the first
                              * fused frame, or not decoded */
  double inlier_fraction;    /* of the frame's depth pixels whose match is not on a model crease
                              * (those are set aside), matched to the model */
  double residual_rms_m;     /* point-to-plane residual of the inliers */
  double read_ms;            /* milliseconds per stage */
  double decode_ms;
  double track_ms;
  double integrate_ms;
  double move_ms;
  double raycast_ms;
  double total_ms;           /* the sum of the stages above, deform_ms included */
  /* Appended later (there when struct_size covers them): online deformation as this frame saw
   * it, 0 with online_deformation off. The graph is
   * solved on a worker thread a little behind the frame loop, so the counts are the worker's
   * at this frame, not final. */
  int keyframe;                   /* 1: this fused frame made a keyframe, a node of the graph */
  size_t deformation_nodes;       /* the graph's nodes (keyframes the worker has added) */
  size_t deformation_constraints; /* its constraints (matches of revisited surface) */
  double deformation_solve_ms;    /* the worker's last keyframe job (matching + Gauss-Newton),
                                   * in its own thread: not part of total_ms */
  double deform_ms;               /* the frame loop's share of online deformation (surface
                                   * samples, queueing for the worker), part of total_ms */
  /* Appended later: 1 when the frame was fused at the turntable prior because tracking could
   * not verify its pose (too little of the view overlaps the model, e.g. after a skipped
   * frame); `reason` says why. */
  int unverified;
  /* Appended later: the depth map the frame was fused from (or, lost, tracked from), camera-frame
   * z in metres (0: no depth), depth_width x depth_height floats with rows depth_stride_bytes
   * apart: the decoded one for a pattern stack, the caller's for a depth map. NULL (sizes 0) when
   * the frame had none (skipped before decoding). In the callback only, valid during the call:
   * copy what you keep. The report sls_scan_add_depth()/_add_stack() fill for the caller has
   * NULL here (sls_feed.h). */
  const float* depth_m;
  int depth_width;
  int depth_height;
  size_t depth_stride_bytes;
  /* The same depth map in CUDA device memory, rows depth_stride_bytes apart, when the scan runs
   * on a CUDA context and the frame's depth is on the GPU (else NULL): read-only, its content
   * final (the host copy above was made from it, or it was uploaded and synchronised), valid
   * during the call only. No copy is made for it. Not exercised by the tests of a machine
   * without a GPU. */
  const void* depth_device;
} sls_frame_report;

/* Sets struct_size and clears the other fields (for sls_scan_add_depth()/_add_stack()). */
SLS_API void sls_frame_report_init(sls_frame_report* report);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_frame_report_init_sized(sls_frame_report* report, size_t struct_size);
#define sls_frame_report_init(report) sls_frame_report_init_sized((report), sizeof(*(report)))

/* Called after each frame of a run (or of sls_scan_add_depth/_add_stack, sls_feed.h), in frame
 * order, on the thread running it. `report`, its strings and its depth map are valid during the
 * call only. It must return normally and must not call functions on the same scan except
 * sls_scan_cancel() and the getters of sls_results.h (a live view of the model; the others
 * return SLS_ERROR_BUSY). The run waits for it: a slow callback slows the scan. */
typedef void (*sls_frame_callback)(const sls_frame_report* report, void* user);

/* Sets the callback later runs call after each frame (NULL: none), and the `user` pointer
 * handed to it. Replaces the previous one. SLS_ERROR_BUSY while a run is in progress. */
SLS_API sls_status sls_scan_set_frame_callback(sls_scan* scan, sls_frame_callback callback, void* user,
                                               sls_error** error);

/* Scans a recording: opens `recording_path` (its manifest and calibration are checked first),
 * then decodes, tracks and fuses every frame, calling the frame callback after each. A run
 * starts by discarding the model and summary of the scan's previous run (one that fails early
 * leaves none).
 * Returns SLS_OK when every frame was processed and at least one fused;
 * SLS_ERROR_CANCELLED when sls_scan_cancel() stopped it: after the frame in progress, the model
 * keeps every frame fused before;
 * SLS_ERROR_NOT_FOUND for a missing folder or manifest, SLS_ERROR_FORMAT (or
 * SLS_ERROR_VERSION_MISMATCH) for a corrupt (or newer) manifest: these are found before any
 * frame;
 * SLS_ERROR_INVALID_ARGUMENT for a recording without calibration, or when no frame could be
 * fused (the summary and the callback's reasons say why);
 * SLS_ERROR_OUT_OF_MEMORY when the volume does not fit; SLS_ERROR_BUSY when the scan is already
 * running. A frame that cannot be read (an image missing, empty, cut short, no PNG at all or of
 * another size), an incomplete stack and a frame that cannot be decoded (a stack whose images do
 * not behave as the pattern set says: a pattern stuck) do not fail the run: they are reported as
 * skipped, with the reason. */
SLS_API sls_status sls_scan_run_recording(sls_scan* scan, const char* recording_path, sls_error** error);

/* What sls_scan_run_devices() captures. Versioned like sls_scan_config
 * (sls_capture_config_init()). The strings are read during the call only. */
typedef struct sls_capture_config {
  size_t struct_size;
  const char* camera_uri;       /* required, e.g. "gige://192.168.1.20", "sim://knurled-knob?preset=ci" */
  const char* projector_uri;    /* required, e.g. "dlpc350://" */
  const char* turntable_uri;    /* NULL or "": none, every stack at one position; e.g. "headctl://" */
  const char* calibration_path; /* required (the stacks cannot be decoded without it):
                                 * calibration.yml of these devices, stored in the recording;
                                 * with a replay:// camera NULL or "" takes the replayed
                                 * recording's */
  const char* recording_path;   /* required: the recording folder to create; it must not exist
                                 * or be empty. It is kept: scan it again with sls_scan_run_recording.
                                 * With sls_scan_config.no_record (since 0.7): NULL or "" */
  int frames;                   /* frames per revolution, one revolution captured; default 0:
                                 * 36 with a turntable, else 1; with a replay:// camera the
                                 * replayed recording's frames */
} sls_capture_config;

/* Sets struct_size and the defaults (NULL strings, frames 0). */
SLS_API void sls_capture_config_init(sls_capture_config* config);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_capture_config_init_sized(sls_capture_config* config, size_t struct_size);
#define sls_capture_config_init(config) sls_capture_config_init_sized((config), sizeof(*(config)))

/* Captures from devices by URI and scans each stack as it is recorded: opens the projector,
 * camera and turntable (sls_device.h's URIs; sim:// devices render on the context's device),
 * homes the turntable, and per turntable position projects the scan's Gray code + phase-shift
 * patterns and captures one stack (a spoiled stack is captured again, up to twice), appending
 * each to the recording at capture->recording_path as it arrives; the scan fuses each frame as
 * it is captured, on the calling thread, while the next is captured (on a thread of the
 * library's: a bounded queue of two frames between them; the capture waits when fusion falls
 * behind, and never drops a frame), and a writer thread writes it to the recording meanwhile
 * (its own bounded queue of two stacks, shared with the scan, not copied: the capture waits when
 * the disk falls behind). Every stack captured is written, also after a cancel or a fusion
 * error; a write that fails (a full disk) ends the run with its code (SLS_ERROR_IO) and a
 * message naming the folder and the frame, the frames before it kept in the recording and the
 * model. With sls_scan_config.no_record nothing is written. The results and codes are sls_scan_run_recording()'s on that
 * recording, and the model is the same. The frame callback reports each frame as it is fused,
 * during the capture. On a CUDA context the camera delivers its images into page-locked host
 * memory (since 0.7), which the GPU uploads without staging them.
 * Also fails with SLS_ERROR_INVALID_ARGUMENT for a missing URI or path, the device registry's
 * codes for a URI that opens nothing (SLS_ERROR_UNSUPPORTED, SLS_ERROR_NOT_FOUND, ... naming
 * the URI), SLS_ERROR_DEVICE or SLS_ERROR_TIMEOUT for a device that stops answering (the frames
 * recorded before it are fused and kept in the model, as in the recording), and
 * SLS_ERROR_CANCELLED for a cancel (sls_scan_cancel: the capture stops after the stack in
 * progress; the recording keeps the stacks captured and the model what was fused), and
 * SLS_ERROR_OUT_OF_MEMORY, before any device moves, when the host's memory (MemAvailable, the
 * cgroup's limit, ulimit -v) cannot hold the stacks the run may hold at once: the one being
 * captured and up to three the writer and the scan still hold (~0.5 GB each at 12 MP). */
SLS_API sls_status sls_scan_run_devices(sls_scan* scan, const sls_capture_config* capture, sls_error** error);

/* Asks the run in progress to stop after its current frame (or its current stack, while
 * capturing); the run then returns SLS_ERROR_CANCELLED and the model keeps what was fused. Safe
 * from any thread and from the frame callback; returns at once. A cancel is final: a run started
 * on a cancelled scan returns SLS_ERROR_CANCELLED before reading anything, and the results of
 * the cancelled run stay. */
SLS_API sls_status sls_scan_cancel(sls_scan* scan, sls_error** error);

/* What the last run did. Versioned like sls_frame_report: initialise with
 * sls_scan_summary_init(); the library fills only the fields the caller's struct_size covers. */
typedef struct sls_scan_summary {
  size_t struct_size;
  size_t frames;        /* frames processed (reported to the callback) */
  size_t fused;
  size_t lost;
  size_t skipped;
  int cancelled;        /* 1: the run was cancelled before its end */
  double voxel_size_m;  /* the volume's voxel size; 0 before the first fused frame */
  size_t volume_moves;  /* times the volume moved with the camera */
  /* Appended later (filled when struct_size covers them): */
  size_t deformation_nodes;       /* the deformation graph's nodes (keyframes) once the worker is
                                   * done; 0 with online_deformation off */
  size_t deformation_constraints; /* its constraints, those of the loop closure included */
  int loop_closed;                /* 1: sls_scan_close_loop() succeeded on this run's model */
} sls_scan_summary;

/* Sets struct_size and clears the other fields. */
SLS_API void sls_scan_summary_init(sls_scan_summary* summary);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_scan_summary_init_sized(sls_scan_summary* summary, size_t struct_size);
#define sls_scan_summary_init(summary) sls_scan_summary_init_sized((summary), sizeof(*(summary)))

/* The last run's summary; all zero before the first run. */
SLS_API sls_status sls_scan_get_summary(const sls_scan* scan, sls_scan_summary* summary, sls_error** error);

/* What sls_scan_close_loop() did. Versioned like sls_scan_summary: initialise with
 * sls_loop_closure_init(); the library fills only the fields the caller's struct_size covers. */
typedef struct sls_loop_closure {
  size_t struct_size;
  int first_frame;                     /* recording index of the first fused frame */
  int last_frame;                      /* and of the last, registered to the first's surface */
  double registration_inlier_fraction; /* the last frame's ICP registration to the first frame's
                                        * surface: matched fraction of its depth pixels */
  double registration_residual_rms_m;  /* and its point-to-plane residual */
  size_t constraints;                  /* constraints added to the graph (the last frame's samples) */
  int iterations;                      /* Gauss-Newton steps of the graph's solve */
  double last_pose_correction_m;       /* the last fused pose after the closure against the pose
                                        * as tracked: translation, metres */
  double last_pose_correction_deg;     /* and rotation, degrees */
  double ms;                           /* the whole closure, registration and solve, milliseconds */
} sls_loop_closure;

/* Sets struct_size and clears the other fields. */
SLS_API void sls_loop_closure_init(sls_loop_closure* result);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_loop_closure_init_sized(sls_loop_closure* result, size_t struct_size);
#define sls_loop_closure_init(result) sls_loop_closure_init_sized((result), sizeof(*(result)))

/* Closes the loop of the last run, after it (e.g. a full turntable revolution): waits for the
 * deformation worker, registers the last fused frame to the first frame's surface (ICP from the
 * deformed estimate of its pose, or from the turntable angle with use_turntable_prior), adds
 * the points of the last frame as constraints to where that registration puts them, and solves
 * the deformation graph. Afterwards sls_scan_write_cloud(), _mesh() and _trajectory() write the
 * closed model, and sls_scan_get_summary() says loop_closed 1. May be called on the results of
 * a cancelled run; called again, it adds a second set of constraints and solves again. Blocks
 * the calling thread (a registration and a solve: tens of milliseconds to about a second).
 *   result: NULL, or a struct from sls_loop_closure_init() the library fills (caller-owned).
 * SLS_ERROR_INVALID_ARGUMENT, the model kept as it was and `result` untouched, when no frame has
 * been fused (before any run, or a run that fused none), online_deformation is 0, the scan has
 * too few keyframes (it moved too little for a loop), or the last frame does not register to
 * the first frame's surface (not a closed loop, or drift beyond the tracker's reach): the
 * message says which; a bad result->struct_size, checked first. SLS_ERROR_BUSY during a run. */
SLS_API sls_status sls_scan_close_loop(sls_scan* scan, sls_loop_closure* result, sls_error** error);

/* The model as a point cloud (zero crossings of the volume with normals and confidence), in the
 * world frame, written as binary PLY to `path` (atomically: a temporary file renamed). The parts
 * the moving volume shipped and the current volume's surface, so a cancelled or interrupted
 * run writes what it fused. With online_deformation, the model deformed by the graph (each part
 * by the nodes of its time; the cloud then has a float property "correction": how far each
 * point moved, metres), closed after sls_scan_close_loop(). SLS_ERROR_INVALID_ARGUMENT when no
 * frame has been fused, SLS_ERROR_IO when the file cannot be written. */
SLS_API sls_status sls_scan_write_cloud(const sls_scan* scan, const char* path, sls_error** error);

/* The model as a triangle mesh (marching cubes), binary PLY, as sls_scan_write_cloud(). */
SLS_API sls_status sls_scan_write_mesh(const sls_scan* scan, const char* path, sls_error** error);

/* The poses of the fused frames, T_world_camera, as a TUM trajectory
 * (`timestamp tx ty tz qx qy qz qw`, seconds from the recording's timestamps); with
 * online_deformation deformed by the graph (so they can differ from the frame reports' poses,
 * which are as tracked), closed after sls_scan_close_loop(). Errors as sls_scan_write_cloud(). */
SLS_API sls_status sls_scan_write_trajectory(const sls_scan* scan, const char* path, sls_error** error);

#ifdef __cplusplus
}
#endif

#endif /* SLS_SCAN_H */
