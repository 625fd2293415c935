/* slscan: structured-light scanning and high-resolution fusion SDK — the C API.
 *
 * Include this one header. Conventions (all headers):
 * - Opaque handles come in create/destroy pairs; destroy(NULL) is a no-op. Each function's
 *   comment says who owns what it returns.
 * - Functions return sls_status (SLS_OK = 0, errors negative; sls_status_str()) and take an
 *   optional sls_error** for the message. No C++ exception ever leaves the library.
 * - Versioned structs (configs the caller fills, results the library fills) carry their size in
 *   their first field, struct_size, and later versions only append fields. Initialise one with
 *   its NAME_init(&s), a macro for NAME_init_sized(&s, sizeof s) (so it takes a pointer to the
 *   struct, not NULL): the size is the caller's, as
 *   compiled, so a newer library writes no byte past an older program's struct (it fills the
 *   fields that fit, sets struct_size to the caller's size), and reading the struct it gives
 *   the fields past struct_size their defaults. The exported function NAME_init (which the macro
 *   hides; a program built against the 0.4 headers calls it) writes the struct as the 0.4
 *   headers declared it. Fields are appended only past the previous version's sizeof, never
 *   into its padding.
 * - Callbacks are a function pointer plus a `void* user`; each says on which thread it runs,
 *   and must return normally (no longjmp, no exceptions).
 *
 * Thread safety: functions on different handles may run concurrently; a handle's own
 * thread-safety is stated in its header. Lengths are in metres, angles in radians unless a
 * name says otherwise (_deg, _um, _mm).
 */
#ifndef SLS_SLS_H
#define SLS_SLS_H

#include "sls/sls_export.h"
#include "sls/sls_version.h"
#include "sls/sls_status.h"
#include "sls/sls_context.h"
#include "sls/sls_log.h"
#include "sls/sls_device.h"
#include "sls/sls_camera.h"
#include "sls/sls_projector.h"
#include "sls/sls_turntable.h"
#include "sls/sls_scan.h"
#include "sls/sls_results.h"
#include "sls/sls_feed.h"
#include "sls/sls_calibration.h"
#include "sls/sls_calibration_capture.h"
#include "sls/sls_eval.h"

#endif /* SLS_SLS_H */
