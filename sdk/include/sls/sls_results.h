/* A scan's results in memory, beside the files sls_scan_write_*() writes: the model as a point
 * cloud and as a mesh, the trajectory of the fused frames, and a small shaded preview for a UI.
 * (Each frame's depth map and pose come in the frame callback's report: sls_scan.h.)
 *
 * Model snapshots: sls_scan_get_cloud() and sls_scan_get_mesh() return an opaque handle holding
 * the model as it is at the call, the same data sls_scan_write_cloud() and _mesh() would write
 * then (deformed by the graph, closed after sls_scan_close_loop()). The caller owns the handle
 * and frees it with sls_cloud_destroy() / sls_mesh_destroy(); its arrays (read with
 * sls_cloud_get_data() / sls_mesh_get_data(), no copy) stay valid and unchanged until then,
 * whatever the scan does meanwhile, and may outlive the scan. A handle is immutable: it may be
 * read from any number of threads at once.
 * Host memory only: the model is extracted to the host even on a CUDA context (a device copy
 * without a transfer is not offered; the frame's depth map is, in the frame report).
 *
 * The trajectory and the preview are copied into the caller's buffers (size queries below).
 *
 * Threads: the getters on a scan (sls_scan_get_*, sls_scan_render_preview) follow sls_scan.h:
 * SLS_ERROR_BUSY while another thread runs the scan, or calls into it. From inside the frame
 * callback (the run's own thread, between two frames) they are allowed: a live view of the
 * model as it grows. Getting a cloud or mesh extracts the whole model (milliseconds to seconds,
 * depending on the volume): for a live UI prefer sls_scan_render_preview().
 *
 * Typical use:
 *   sls_cloud* cloud = NULL;
 *   sls_cloud_data data;
 *   sls_cloud_data_init(&data);
 *   if (sls_scan_get_cloud(scan, &cloud, NULL) == SLS_OK && sls_cloud_get_data(cloud, &data, NULL) == SLS_OK)
 *     for (size_t i = 0; i < data.points; ++i) use(data.positions + 3 * i, data.normals + 3 * i);
 *   sls_cloud_destroy(cloud);
 */
#ifndef SLS_RESULTS_H
#define SLS_RESULTS_H

#include <stddef.h>
#include <stdint.h>

#include "sls/sls_export.h"
#include "sls/sls_scan.h"
#include "sls/sls_status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A snapshot of the model as a point cloud. Opaque, immutable. */
typedef struct sls_cloud sls_cloud;

/* A snapshot of the model as a triangle mesh. Opaque, immutable. */
typedef struct sls_mesh sls_mesh;

/* The model now as a point cloud (zero crossings of the volume with normals and confidence, world
 * frame, metres): what sls_scan_write_cloud() would write. `cloud` receives a new handle (left NULL
 * on failure). SLS_ERROR_INVALID_ARGUMENT when no frame has been fused. */
SLS_API sls_status sls_scan_get_cloud(const sls_scan* scan, sls_cloud** cloud, sls_error** error);

/* Frees a cloud; its arrays become invalid. sls_cloud_destroy(NULL) is a no-op. */
SLS_API void sls_cloud_destroy(sls_cloud* cloud);

/* A cloud's arrays, owned by the cloud (valid until sls_cloud_destroy). Versioned: initialise
 * with sls_cloud_data_init(); the library fills the fields the caller's struct_size covers. */
typedef struct sls_cloud_data {
  size_t struct_size;
  size_t points;
  const float* positions;  /* x, y, z per point (3 x points floats) */
  const float* normals;    /* unit normal per point (3 x points), or NULL */
  const float* confidence; /* in [0, 1] per point, or NULL */
  const float* correction; /* how far online deformation moved each point (metres), or NULL
                            * (online_deformation off): the PLY's "correction" property */
} sls_cloud_data;

/* Sets struct_size and clears the other fields. */
SLS_API void sls_cloud_data_init(sls_cloud_data* data);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_cloud_data_init_sized(sls_cloud_data* data, size_t struct_size);
#define sls_cloud_data_init(data) sls_cloud_data_init_sized((data), sizeof(*(data)))

SLS_API sls_status sls_cloud_get_data(const sls_cloud* cloud, sls_cloud_data* data, sls_error** error);

/* The model now as a triangle mesh (marching cubes): what sls_scan_write_mesh() would write.
 * Errors as sls_scan_get_cloud(). */
SLS_API sls_status sls_scan_get_mesh(const sls_scan* scan, sls_mesh** mesh, sls_error** error);

/* Frees a mesh; its arrays become invalid. sls_mesh_destroy(NULL) is a no-op. */
SLS_API void sls_mesh_destroy(sls_mesh* mesh);

/* A mesh's arrays, owned by the mesh. Versioned like sls_cloud_data (sls_mesh_data_init()). */
typedef struct sls_mesh_data {
  size_t struct_size;
  size_t vertices;
  size_t faces;
  const float* positions;   /* x, y, z per vertex */
  const float* normals;     /* per vertex, or NULL */
  const float* confidence;  /* per vertex, or NULL */
  const int32_t* indices;   /* 3 vertex indices per face, counter-clockwise seen from outside */
} sls_mesh_data;

SLS_API void sls_mesh_data_init(sls_mesh_data* data);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_mesh_data_init_sized(sls_mesh_data* data, size_t struct_size);
#define sls_mesh_data_init(data) sls_mesh_data_init_sized((data), sizeof(*(data)))

SLS_API sls_status sls_mesh_get_data(const sls_mesh* mesh, sls_mesh_data* data, sls_error** error);

/* The poses of the fused frames as sls_scan_write_trajectory() writes them (deformed by the
 * graph with online deformation), oldest first.
 *   timestamps_s:   `capacity` doubles, or NULL: seconds from the frames' timestamps.
 *   T_world_camera: 16 x `capacity` doubles, or NULL: each pose 4x4 row-major, metres.
 *   count:          required; receives the number of poses.
 * Call with capacity 0 (and NULL buffers) for the count. With capacity < count nothing is copied
 * and SLS_ERROR_INVALID_ARGUMENT is returned (count still set): grow the buffers and call again.
 * SLS_ERROR_INVALID_ARGUMENT when no frame has been fused. */
SLS_API sls_status sls_scan_get_trajectory(const sls_scan* scan, double* timestamps_s, double* T_world_camera,
                                           size_t capacity, size_t* count, sls_error** error);

/* A shaded grey picture of the model in the scan's current volume (the surface near the camera;
 * parts the moving volume shipped away are not drawn), raycast from a viewpoint through the
 * calibrated camera at its resolution, then resampled to width x height (each 16 .. 4096; an area
 * average when smaller; another aspect ratio than the camera's stretches it). Background 0. The
 * raycast is the cost: about one frame's raycast stage (sls_frame_report.raycast_ms).
 *   T_world_camera: the viewpoint, 4x4 row-major (16 doubles), or NULL: the last fused frame's.
 *   pixels:         the caller's buffer of `pixel_count` bytes, width x height, rows unpadded;
 *                   untouched on failure.
 * SLS_ERROR_INVALID_ARGUMENT for a size outside the range, pixel_count < width x height, a pose
 * that is not a rigid transform, or no frame fused yet. */
SLS_API sls_status sls_scan_render_preview(const sls_scan* scan, const double* T_world_camera, int width, int height,
                                           uint8_t* pixels, size_t pixel_count, sls_error** error);

#ifdef __cplusplus
}
#endif

#endif /* SLS_RESULTS_H */
