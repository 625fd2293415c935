/* Status codes and error objects of the slscan C API.
 *
 * Every function that can fail returns an sls_status: SLS_OK (0) or a negative code.
 * Functions also take an optional `sls_error** error`: pass NULL to ignore details, or the
 * address of an sls_error* initialised to NULL; on failure it receives a new error object
 * (message, failing function, status) that the caller frees with sls_error_free().
 * On success *error is left untouched. */
#ifndef SLS_STATUS_H
#define SLS_STATUS_H

#include "sls/sls_export.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum sls_status {
  SLS_OK = 0,
  SLS_ERROR_INVALID_ARGUMENT = -1, /* a NULL pointer, an out-of-range value, a bad config */
  SLS_ERROR_IO = -2,               /* a file or stream could not be read or written */
  SLS_ERROR_FORMAT = -3,           /* a file's content is corrupt or unsupported */
  SLS_ERROR_NOT_FOUND = -4,        /* a file, device or key does not exist */
  SLS_ERROR_OUT_OF_MEMORY = -5,    /* host or GPU memory exhausted (e.g. volume too large) */
  SLS_ERROR_UNSUPPORTED = -6,      /* not built in (e.g. CUDA) or not available yet */
  SLS_ERROR_VERSION_MISMATCH = -7, /* API or file-format version not spoken by this library */
  SLS_ERROR_DEVICE = -8,           /* a device misbehaved (protocol error, disconnect, GPU) */
  SLS_ERROR_TIMEOUT = -9,          /* a device did not answer in time */
  SLS_ERROR_CANCELLED = -10,       /* the caller cancelled long work */
  SLS_ERROR_BUSY = -11,            /* the resource is in use */
  SLS_ERROR_INTERNAL = -99         /* a bug in slscan: please report it with the message */
} sls_status;

/* A static English name for a status ("invalid argument"); never NULL, also for unknown
 * values. Thread-safe. */
SLS_API const char* sls_status_str(sls_status status);

/* Details of a failure. Opaque; created by the library, freed by the caller. */
typedef struct sls_error sls_error;

/* The human-readable message: what failed and why, naming files and devices involved.
 * Owned by the error object; valid until sls_error_free(). NULL error gives "". */
SLS_API const char* sls_error_message(const sls_error* error);

/* The C API function that failed, e.g. "sls_context_create". Owned by the error object. */
SLS_API const char* sls_error_function(const sls_error* error);

/* The status the failing call returned. SLS_OK for a NULL error. */
SLS_API sls_status sls_error_status(const sls_error* error);

/* Frees an error object. sls_error_free(NULL) is a no-op. */
SLS_API void sls_error_free(sls_error* error);

#ifdef __cplusplus
}
#endif

#endif /* SLS_STATUS_H */
