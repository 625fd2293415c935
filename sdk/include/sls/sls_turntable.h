/* Turntables opened by device URI (see sls_device.h for the URIs and for enumeration): the
 * simulator's turntable (sim://), the head controller's stepper over USB (headctl://).
 *
 * Angles are in degrees, 0 at the home (index) position. Moves block until the table reports
 * the position reached, or fail with SLS_ERROR_TIMEOUT after timeout_ms.
 *
 * Threads: a turntable is used by one thread at a time (calls on one turntable must not
 * overlap); different turntables are independent. A turntable used by a running scan
 * (sls_scan_run_devices) is the scan's own: open it here only while no scan uses it.
 *
 * Typical use:
 *   sls_turntable* table = NULL;
 *   double angle = 0.0;
 *   if (sls_turntable_open(context, "headctl://", &table, &error) == SLS_OK &&
 *       sls_turntable_home(table, 20000, &error) == SLS_OK &&
 *       sls_turntable_move_to_deg(table, 90.0, 10000, &error) == SLS_OK)
 *     sls_turntable_get_position_deg(table, &angle, &error);
 *   sls_turntable_close(table);
 */
#ifndef SLS_TURNTABLE_H
#define SLS_TURNTABLE_H

#include "sls/sls_context.h"
#include "sls/sls_export.h"
#include "sls/sls_status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* An open turntable. Opaque. */
typedef struct sls_turntable sls_turntable;

/* Opens the turntable a device URI names.
 *   context:   the library context. Not kept: it may be destroyed first.
 *   uri:       e.g. "headctl://", "headctl://1:9", "sim://knurled-screw?preset=ci".
 *   turntable: receives the turntable; the caller owns it and frees it with
 *              sls_turntable_close(). Left NULL on failure.
 * Fails with SLS_ERROR_UNSUPPORTED for an unknown scheme, a driver this library was built
 * without, or a head controller without a turntable; SLS_ERROR_INVALID_ARGUMENT for a malformed
 * URI or one naming no turntable (e.g. gige://); SLS_ERROR_NOT_FOUND when nothing answers;
 * SLS_ERROR_DEVICE or SLS_ERROR_TIMEOUT when the board misbehaves. The message names the URI. */
SLS_API sls_status sls_turntable_open(sls_context* context, const char* uri, sls_turntable** turntable,
                                      sls_error** error);

/* Frees the turntable; it stays where it is. sls_turntable_close(NULL) is a no-op. */
SLS_API void sls_turntable_close(sls_turntable* turntable);

/* Finds the home (index) position and calls it 0 degrees. Home once after opening: a table
 * that has not been homed may refuse to move. timeout_ms > 0. */
SLS_API sls_status sls_turntable_home(sls_turntable* turntable, int timeout_ms, sls_error** error);

/* Moves to `angle_deg` in [0, 360) (the nearest whole step) and waits until it is there.
 * timeout_ms > 0; SLS_ERROR_TIMEOUT naming the device when it is not reached in time. */
SLS_API sls_status sls_turntable_move_to_deg(sls_turntable* turntable, double angle_deg, int timeout_ms,
                                             sls_error** error);

/* The angle the table reports, in degrees (its commanded step: what a recording stores). */
SLS_API sls_status sls_turntable_get_position_deg(const sls_turntable* turntable, double* angle_deg,
                                                  sls_error** error);

/* Steps per revolution of the table: the finest angle it can take is 360 / steps degrees. */
SLS_API sls_status sls_turntable_get_steps_per_revolution(const sls_turntable* turntable, int* steps,
                                                          sls_error** error);

#ifdef __cplusplus
}
#endif

#endif /* SLS_TURNTABLE_H */
