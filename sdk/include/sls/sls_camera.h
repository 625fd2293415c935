/* Cameras opened by device URI (see sls_device.h for the URIs and for enumeration): the
 * simulator's camera (sim://), GenICam cameras through Aravis (gige://, usb3://).
 *
 * sls_camera_grab() triggers one exposure in software and copies the image into the caller's
 * buffer: one call, one new image. A frame the transport delivered incomplete (lost GigE
 * Vision packets) is never handed out: the call fails with SLS_ERROR_DEVICE and the buffer is
 * left as it was.
 *
 * Threads: a camera is used by one thread at a time (calls on one camera must not overlap);
 * different cameras are independent.
 *
 * Typical use:
 *   sls_camera* camera = NULL;
 *   sls_camera_info info;
 *   sls_camera_info_init(&info);
 *   if (sls_camera_open(context, "gige://192.168.1.20", &camera, NULL) == SLS_OK &&
 *       sls_camera_get_info(camera, &info, NULL) == SLS_OK) {
 *     size_t count = (size_t)info.width * (size_t)info.height;
 *     uint16_t* pixels = malloc(count * sizeof(uint16_t));
 *     sls_status status = sls_camera_grab(camera, 1000, pixels, count, NULL, NULL);
 *     ...
 *   }
 *   sls_camera_close(camera);
 */
#ifndef SLS_CAMERA_H
#define SLS_CAMERA_H

#include <stddef.h>
#include <stdint.h>

#include "sls/sls_context.h"
#include "sls/sls_export.h"
#include "sls/sls_status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* An open camera. Opaque. */
typedef struct sls_camera sls_camera;

/* Opens the camera a device URI names and selects its software trigger.
 *   context: the library context; a sim:// camera renders on the context's device (CPU or
 *            CUDA) unless its URI says device=. Not kept: it may be destroyed first.
 *   uri:     e.g. "sim://knurled-screw?preset=ci", "gige://192.168.1.20",
 *            "gige://192.168.1.20?format=Mono12&width=1280&height=1024", "usb3://SERIAL".
 *   camera:  receives the camera; the caller owns it and frees it with sls_camera_close().
 *            Left NULL on failure.
 * Fails with SLS_ERROR_UNSUPPORTED for an unknown scheme or a driver this library was built
 * without, SLS_ERROR_INVALID_ARGUMENT for a malformed URI or one naming no camera
 * (e.g. dlpc350://), SLS_ERROR_NOT_FOUND when nothing answers, SLS_ERROR_DEVICE or
 * SLS_ERROR_TIMEOUT when the camera misbehaves; the error message names the URI. */
SLS_API sls_status sls_camera_open(sls_context* context, const char* uri, sls_camera** camera, sls_error** error);

/* Stops the camera and frees it. sls_camera_close(NULL) is a no-op. */
SLS_API void sls_camera_close(sls_camera* camera);

/* What an open camera is. Versioned by its size: initialise with sls_camera_info_init(); later
 * library versions only append fields. Strings are owned by the camera: valid until
 * sls_camera_close(). */
typedef struct sls_camera_info {
  size_t struct_size;
  const char* uri;    /* how it was opened */
  const char* model;
  const char* serial; /* "" when the camera reports none */
  int width;          /* image size in pixels */
  int height;
  int bit_depth;      /* significant bits per pixel: values are 0 .. 2^bit_depth - 1 */
} sls_camera_info;

/* Sets struct_size and clears the other fields. */
SLS_API void sls_camera_info_init(sls_camera_info* info);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_camera_info_init_sized(sls_camera_info* info, size_t struct_size);
#define sls_camera_info_init(info) sls_camera_info_init_sized((info), sizeof(*(info)))

SLS_API sls_status sls_camera_get_info(const sls_camera* camera, sls_camera_info* info, sls_error** error);

/* Exposure time in microseconds (> 0). SLS_ERROR_INVALID_ARGUMENT outside the camera's range,
 * SLS_ERROR_UNSUPPORTED when the camera has no exposure control. */
SLS_API sls_status sls_camera_set_exposure_us(sls_camera* camera, double exposure_us, sls_error** error);

/* About one grabbed image. Versioned like sls_camera_info (sls_frame_info_init()). */
typedef struct sls_frame_info {
  size_t struct_size;
  int width;
  int height;
  int bit_depth;
  int64_t timestamp_ns;   /* the device's clock when the exposure started */
  uint64_t frame_id;      /* the camera's own frame counter */
  uint64_t frames_missed; /* frames the camera counted since the previous grab that never arrived */
} sls_frame_info;

SLS_API void sls_frame_info_init(sls_frame_info* info);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_frame_info_init_sized(sls_frame_info* info, size_t struct_size);
#define sls_frame_info_init(info) sls_frame_info_init_sized((info), sizeof(*(info)))

/* Triggers one exposure and copies the image into `pixels`: width x height values, row after
 * row (no padding), each 0 .. 2^bit_depth - 1 (an 8-bit camera's values are not scaled).
 *   timeout_ms:  how long to wait for the image (>= 0); SLS_ERROR_TIMEOUT after that.
 *   pixels:      the caller's buffer of `pixel_count` values; it must hold width x height
 *                (sls_camera_get_info), else SLS_ERROR_INVALID_ARGUMENT and nothing is captured.
 *   frame:       optional (NULL): receives the image's size, timestamp and frame counters.
 * On failure `pixels` is left as it was; after a timeout or an incomplete frame the next grab
 * restarts acquisition, so a late image of an earlier trigger is never returned. */
SLS_API sls_status sls_camera_grab(sls_camera* camera, int timeout_ms, uint16_t* pixels, size_t pixel_count,
                                   sls_frame_info* frame, sls_error** error);

#ifdef __cplusplus
}
#endif

#endif /* SLS_CAMERA_H */
