/* The library's log: warnings and diagnostics of every part of slscan (a recording that stores
 * depth it cannot represent, a camera whose control connection dropped, frames a scan skipped
 * or lost), at most one handler for the whole process, as libusb_set_log_cb(NULL, ...) and
 * rs2_log_to_callback do. Without a handler they go to stderr, one line each.
 *
 * The level is process-wide too: sls_set_log_level(), or the log_level of the last
 * sls_context_create() (sls_context.h). Messages below it are neither formatted nor delivered.
 *
 * Threads: the callback runs on the thread that logged, which may be a thread of the library
 * (a scan's deformation worker, a camera driver's heartbeat), never two calls at once. It must
 * return normally and quickly; it may call other slscan functions, but the messages they log on
 * that thread while inside the callback are dropped, and sls_set_log_callback() from inside the
 * callback returns SLS_ERROR_BUSY. sls_set_log_callback() and sls_set_log_level() may be called
 * from any thread; once sls_set_log_callback() returns, the previous callback is not called
 * again (a call to it in progress on another thread has finished).
 *
 * Typical use:
 *   static void on_log(sls_log_level level, const char* message, void* user) {
 *     fprintf((FILE*)user, "slscan %d: %s\n", (int)level, message);
 *   }
 *   sls_set_log_callback(on_log, my_log_file, NULL);
 *   ...
 *   sls_set_log_callback(NULL, NULL, NULL);   (back to stderr, before my_log_file is closed)
 */
#ifndef SLS_LOG_H
#define SLS_LOG_H

#include "sls/sls_context.h"
#include "sls/sls_export.h"
#include "sls/sls_status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* One message: its level (SLS_LOG_TRACE .. SLS_LOG_ERROR) and its text (no trailing newline,
 * valid during the call only). */
typedef void (*sls_log_callback)(sls_log_level level, const char* message, void* user);

/* Sends the library's messages to `callback` with `user` (NULL callback: back to stderr),
 * replacing the previous one. SLS_ERROR_BUSY from inside the callback. */
SLS_API sls_status sls_set_log_callback(sls_log_callback callback, void* user, sls_error** error);

/* The least level delivered (SLS_LOG_OFF: none); default SLS_LOG_WARNING.
 * SLS_ERROR_INVALID_ARGUMENT for a value that is not an sls_log_level. */
SLS_API sls_status sls_set_log_level(sls_log_level level, sls_error** error);

/* The level now in force. */
SLS_API sls_status sls_get_log_level(sls_log_level* level, sls_error** error);

#ifdef __cplusplus
}
#endif

#endif /* SLS_LOG_H */
