/* slscan: structured-light scanning and high-resolution fusion SDK — the C API.
 *
 * Include this one header. Conventions (all headers):
 * - Opaque handles come in create/destroy pairs; destroy(NULL) is a no-op. Each function's
 *   comment says who owns what it returns.
 * - Functions return sls_status (SLS_OK = 0, errors negative; sls_status_str()) and take an
 *   optional sls_error** for the message. No C++ exception ever leaves the library.
 * - Config structs carry their size (struct_size) and have an _init() function.
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

#endif /* SLS_SLS_H */
