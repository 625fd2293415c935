/* Pattern projectors opened by device URI (see sls_device.h for the URIs and for enumeration):
 * the simulator's projector (sim://), the DLPC350 over USB (dlpc350://).
 *
 * A projector shows the patterns of a loaded set: sls_projector_load_scan_patterns() loads the
 * Gray code + phase-shift set that sls_scan_run_devices() projects, sized to the projector;
 * sls_projector_show_pattern() puts one on the DMD (and fires the trigger output for the
 * cameras), e.g. to check focus and framing before a scan. A sim:// projector and a sim://
 * camera opened with the same URI are one simulated scanner: the camera sees what it shows.
 *
 * Threads: a projector is used by one thread at a time (calls on one projector must not
 * overlap); different projectors are independent. A projector used by a running scan
 * (sls_scan_run_devices) is the scan's own: open it here only while no scan uses it.
 *
 * Typical use:
 *   sls_projector* projector = NULL;
 *   int count = 0;
 *   if (sls_projector_open(context, "dlpc350://", &projector, &error) == SLS_OK &&
 *       sls_projector_load_scan_patterns(projector, &count, &error) == SLS_OK)
 *     sls_projector_show_pattern(projector, 0, &error);  (pattern 0: white)
 *   sls_projector_close(projector);
 */
#ifndef SLS_PROJECTOR_H
#define SLS_PROJECTOR_H

#include <stddef.h>

#include "sls/sls_context.h"
#include "sls/sls_export.h"
#include "sls/sls_status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* An open projector. Opaque. */
typedef struct sls_projector sls_projector;

/* Opens the projector a device URI names.
 *   context:   the library context; a sim:// projector renders on the context's device unless
 *              its URI says device=. Not kept: it may be destroyed first.
 *   uri:       e.g. "dlpc350://", "dlpc350://1:7", "sim://knurled-screw?preset=ci".
 *   projector: receives the projector; the caller owns it and frees it with
 *              sls_projector_close(). Left NULL on failure.
 * Fails with SLS_ERROR_UNSUPPORTED for an unknown scheme or a driver this library was built
 * without, SLS_ERROR_INVALID_ARGUMENT for a malformed URI or one naming no projector
 * (e.g. gige://), SLS_ERROR_NOT_FOUND when nothing answers, SLS_ERROR_DEVICE or
 * SLS_ERROR_TIMEOUT when the projector misbehaves; the error message names the URI. */
SLS_API sls_status sls_projector_open(sls_context* context, const char* uri, sls_projector** projector,
                                      sls_error** error);

/* Turns the projector dark (best effort) and frees it. sls_projector_close(NULL) is a no-op. */
SLS_API void sls_projector_close(sls_projector* projector);

/* What an open projector is. Versioned by its size: initialise with sls_projector_info_init();
 * later library versions only append fields. Strings are owned by the projector: valid until
 * sls_projector_close(). */
typedef struct sls_projector_info {
  size_t struct_size;
  const char* uri;      /* how it was opened */
  const char* model;
  const char* firmware; /* "" when the projector reports none */
  int width;            /* DMD columns */
  int height;           /* DMD rows */
} sls_projector_info;

/* Sets struct_size and clears the other fields. */
SLS_API void sls_projector_info_init(sls_projector_info* info);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_projector_info_init_sized(sls_projector_info* info, size_t struct_size);
#define sls_projector_info_init(info) sls_projector_info_init_sized((info), sizeof(*(info)))

SLS_API sls_status sls_projector_get_info(const sls_projector* projector, sls_projector_info* info,
                                          sls_error** error);

/* Loads the scan's pattern set into the projector (the DLPC350's pattern LUT) and says how many
 * patterns it holds (pattern_count, optional: NULL). Pattern 0 is all white, 1 all black. */
SLS_API sls_status sls_projector_load_scan_patterns(sls_projector* projector, int* pattern_count, sls_error** error);

/* Shows pattern `index` (0 .. pattern_count - 1) of the loaded set and fires the trigger output;
 * returns once it is on the DMD. SLS_ERROR_INVALID_ARGUMENT for an index outside the loaded set
 * (a DLPC350 holds none until a set is loaded; the simulator's holds the scan's from the start);
 * SLS_ERROR_TIMEOUT or SLS_ERROR_DEVICE when the projector stalls. */
SLS_API sls_status sls_projector_show_pattern(sls_projector* projector, int index, sls_error** error);

/* The pattern on the DMD now, or -1 when dark. */
SLS_API sls_status sls_projector_get_current_pattern(const sls_projector* projector, int* index, sls_error** error);

/* Turns the projector dark. */
SLS_API sls_status sls_projector_go_dark(sls_projector* projector, sls_error** error);

#ifdef __cplusplus
}
#endif

#endif /* SLS_PROJECTOR_H */
