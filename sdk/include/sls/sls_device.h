/* Device enumeration: what is connected now, each device with the URI that opens it (in the
 * manner of librealsense's rs2_query_devices and libusb_get_device_list).
 *
 * Device URIs:
 *   sim://OBJECT?preset=ci|demo|paper   the built-in simulated scanner (always listed)
 *   gige://ADDRESS  usb3://SERIAL        GenICam cameras through Aravis
 *   dlpc350://BUS:ADDRESS                the DLPC350 projector over USB
 *   headctl://BUS:ADDRESS                the head controller (trigger outputs, turntable)
 * A URI a list reports opens with the functions its `roles` name (sls_camera_open,
 * sls_projector_open, sls_turntable_open), and a camera, projector and turntable together scan
 * with sls_scan_run_devices() (sls_scan.h); `sls devices` prints the same list.
 *
 * Threads: a list is immutable once created; the functions reading it may run concurrently.
 *
 * Typical use:
 *   sls_device_list* list = NULL;
 *   size_t count = 0;
 *   if (sls_device_list_create(context, &list, NULL) == SLS_OK &&
 *       sls_device_list_count(list, &count, NULL) == SLS_OK) {
 *     for (size_t i = 0; i < count; ++i) {
 *       sls_device_info info;
 *       sls_device_info_init(&info);
 *       if (sls_device_list_get_info(list, i, &info, NULL) == SLS_OK) puts(info.uri);
 *     }
 *   }
 *   sls_device_list_destroy(list);
 */
#ifndef SLS_DEVICE_H
#define SLS_DEVICE_H

#include <stddef.h>

#include "sls/sls_context.h"
#include "sls/sls_export.h"
#include "sls/sls_status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A snapshot of the devices found by sls_device_list_create(). Opaque. */
typedef struct sls_device_list sls_device_list;

typedef enum sls_device_kind {
  SLS_DEVICE_KIND_CAMERA = 0,     /* a GenICam camera */
  SLS_DEVICE_KIND_PROJECTOR = 1,  /* a pattern projector (DLPC350) */
  SLS_DEVICE_KIND_CONTROLLER = 2, /* the head controller board (triggers, turntable) */
  SLS_DEVICE_KIND_SCANNER = 3     /* a whole scanner behind one URI (the simulator) */
} sls_device_kind;

/* What a device's URI can be opened as: bits of sls_device_info.roles. */
typedef enum sls_device_role {
  SLS_DEVICE_ROLE_CAMERA = 1,    /* sls_camera_open */
  SLS_DEVICE_ROLE_PROJECTOR = 2, /* sls_projector_open */
  SLS_DEVICE_ROLE_TURNTABLE = 4  /* sls_turntable_open */
} sls_device_role;

/* One listed device. Versioned by its size: initialise with sls_device_info_init() before
 * sls_device_list_get_info(), which fills only the fields the caller's struct_size covers.
 * Later library versions only append fields. The strings are owned by the list: valid until
 * sls_device_list_destroy(); never NULL ("" when unknown). */
typedef struct sls_device_info {
  size_t struct_size;
  sls_device_kind kind;
  const char* uri;     /* what opens it, e.g. "gige://192.168.1.20" */
  const char* model;   /* vendor and model, e.g. "Basler acA1920-40gm" */
  const char* serial;  /* "" when the device reports none */
  const char* details; /* transport and address, for people, e.g. "GigE Vision at 192.168.1.20" */
  unsigned int roles;  /* sls_device_role bits */
} sls_device_info;

/* Sets struct_size and clears the other fields. */
SLS_API void sls_device_info_init(sls_device_info* info);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_device_info_init_sized(sls_device_info* info, size_t struct_size);
#define sls_device_info_init(info) sls_device_info_init_sized((info), sizeof(*(info)))

/* Lists the built-in simulator and every camera, projector and head controller the drivers
 * of this build find now. Blocks for GigE Vision discovery (about a second) when the library
 * has the Aravis driver. A transport that cannot be searched (no USB access, a driver not in
 * this build) does not fail the call: sls_device_list_problems() says which and why.
 *   context: the library context (not kept: it may be destroyed before the list).
 *   list:    receives the new list; the caller owns it and frees it with
 *            sls_device_list_destroy(). Left NULL on failure.
 *   error:   optional, see sls_status.h. */
SLS_API sls_status sls_device_list_create(sls_context* context, sls_device_list** list, sls_error** error);

/* Frees a list and the strings its infos point to. sls_device_list_destroy(NULL) is a no-op. */
SLS_API void sls_device_list_destroy(sls_device_list* list);

/* The number of devices in the list (at least 1: the simulator). */
SLS_API sls_status sls_device_list_count(const sls_device_list* list, size_t* count, sls_error** error);

/* The device at `index` (0 .. count - 1; the simulator is index 0). SLS_ERROR_INVALID_ARGUMENT
 * for an index out of range or an info whose struct_size is not from sls_device_info_init(). */
SLS_API sls_status sls_device_list_get_info(const sls_device_list* list, size_t index, sls_device_info* info,
                                            sls_error** error);

/* Whether hardware was found: 1 when the list holds any device besides the simulator. */
SLS_API sls_status sls_device_list_has_hardware(const sls_device_list* list, int* has_hardware, sls_error** error);

/* The transports that could not be searched and why, one per line (e.g. "USB: not in this
 * build ..."); "" when every one was. Owned by the list, valid until it is destroyed. */
SLS_API sls_status sls_device_list_problems(const sls_device_list* list, const char** problems, sls_error** error);

#ifdef __cplusplus
}
#endif

#endif /* SLS_DEVICE_H */
