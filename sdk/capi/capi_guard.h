// The C boundary: runs a C++ body, turns any exception into an sls_status and an optional
// sls_error, so no exception crosses into C callers (DESIGN.md section 7).
#pragma once

#include <string>

#include "sls/sls_status.h"

struct sls_error {
  sls_status status;
  std::string message;
  std::string function;
};

namespace sls::capi {

// Fills *error (when error != NULL) with a new error object; returns status.
sls_status report(sls_status status, const char* function, const std::string& message, sls_error** error);

// Calls body(); returns SLS_OK, or the status of the exception it threw.
template <typename Body>
sls_status guarded(const char* function, sls_error** error, Body&& body) noexcept;

sls_status status_from_current_exception(const char* function, sls_error** error) noexcept;

template <typename Body>
sls_status guarded(const char* function, sls_error** error, Body&& body) noexcept {
  try {
    body();
    return SLS_OK;
  } catch (...) {
    return status_from_current_exception(function, error);
  }
}

}  // namespace sls::capi

// For argument checks at the top of an API function.
#define SLS_CAPI_REQUIRE(condition, error, message)                                            \
  do {                                                                                          \
    if (!(condition)) return ::sls::capi::report(SLS_ERROR_INVALID_ARGUMENT, __func__, message, error); \
  } while (0)
