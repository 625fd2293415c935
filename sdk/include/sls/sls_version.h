/* API version of the slscan C API.
 *
 * SLS_API_VERSION is the version of the headers a program was compiled against; pass it to
 * sls_context_create(), which refuses headers of another major version, or of a newer minor
 * version than the library (a newer header may declare what this library lacks). */
#ifndef SLS_VERSION_H
#define SLS_VERSION_H

#include "sls/sls_export.h"

#define SLS_API_VERSION_MAJOR 0
#define SLS_API_VERSION_MINOR 10
#define SLS_API_VERSION_PATCH 0

/* One integer: major * 10000 + minor * 100 + patch. */
#define SLS_MAKE_VERSION(major, minor, patch) ((major) * 10000 + (minor) * 100 + (patch))
#define SLS_API_VERSION SLS_MAKE_VERSION(SLS_API_VERSION_MAJOR, SLS_API_VERSION_MINOR, SLS_API_VERSION_PATCH)

#ifdef __cplusplus
extern "C" {
#endif

/* The API version of the library loaded at run time. Thread-safe. */
SLS_API int sls_get_api_version(void);

/* A static, NUL-terminated description of the build: library version, compiler, and
 * whether the CUDA backends are compiled in, e.g. "slscan 0.1.0 (CUDA 13.0, sm_90)".
 * Owned by the library; never freed by the caller. Thread-safe. */
SLS_API const char* sls_get_build_info(void);

#ifdef __cplusplus
}
#endif

#endif /* SLS_VERSION_H */
