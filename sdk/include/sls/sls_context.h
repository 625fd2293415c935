/* The library context: the root object every other slscan handle is made from.
 *
 * Threads: a context may be used from several threads at once; the functions here are
 * thread-safe. Destroying a context while another thread uses it is the caller's bug. */
#ifndef SLS_CONTEXT_H
#define SLS_CONTEXT_H

#include <stddef.h>

#include "sls/sls_export.h"
#include "sls/sls_status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sls_context sls_context;

typedef enum sls_log_level {
  SLS_LOG_TRACE = 0,
  SLS_LOG_DEBUG = 1,
  SLS_LOG_INFO = 2,
  SLS_LOG_WARNING = 3,
  SLS_LOG_ERROR = 4,
  SLS_LOG_OFF = 5
} sls_log_level;

typedef enum sls_device_preference {
  SLS_DEVICE_AUTO = 0, /* the first CUDA GPU when one is usable, else the CPU */
  SLS_DEVICE_CPU = 1,  /* CPU backends only */
  SLS_DEVICE_CUDA = 2  /* CUDA backends; sls_context_create fails if none is usable */
} sls_device_preference;

/* Context configuration. Versioned by its size: always initialise with
 * sls_context_config_init(), which sets struct_size and the defaults, then change fields.
 * Later library versions only append fields. */
typedef struct sls_context_config {
  size_t struct_size;
  sls_log_level log_level;          /* default SLS_LOG_WARNING; process-wide: to stderr or the
                                     * log callback (sls_log.h), as sls_set_log_level() */
  sls_device_preference device;    /* default SLS_DEVICE_AUTO */
  int cuda_device_id;               /* CUDA ordinal with SLS_DEVICE_CUDA/AUTO; default 0 */
} sls_context_config;

/* Fills *config with the defaults of the headers compiled against. */
SLS_API void sls_context_config_init(sls_context_config* config);
/* The caller's struct_size, which the macro gives (sls.h: versioned structs): */
SLS_API void sls_context_config_init_sized(sls_context_config* config, size_t struct_size);
#define sls_context_config_init(config) sls_context_config_init_sized((config), sizeof(*(config)))

/* Creates a context.
 *   api_version: pass SLS_API_VERSION; a header of another major version, or of a newer
 *                minor version than the library, gives SLS_ERROR_VERSION_MISMATCH.
 *   config:      NULL for the defaults, or a config from sls_context_config_init().
 *   context:     receives the new context; the caller owns it and frees it with
 *                sls_context_destroy(). Left NULL on failure.
 *   error:       optional, see sls_status.h. */
SLS_API sls_status sls_context_create(int api_version, const sls_context_config* config,
                                      sls_context** context, sls_error** error);

/* Destroys a context. sls_context_destroy(NULL) is a no-op. */
SLS_API void sls_context_destroy(sls_context* context);

/* Whether the context runs hot stages on a CUDA GPU (1) or on the CPU (0), as resolved
 * from its config at creation. */
SLS_API sls_status sls_context_uses_cuda(const sls_context* context, int* uses_cuda, sls_error** error);

/* Number of CUDA devices usable by this library build on this machine (0 without CUDA
 * support compiled in, without a driver, or without a GPU). */
SLS_API sls_status sls_get_cuda_device_count(int* count, sls_error** error);

#ifdef __cplusplus
}
#endif

#endif /* SLS_CONTEXT_H */
