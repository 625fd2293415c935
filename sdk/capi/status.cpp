// sls_status strings and sls_error accessors.
#include "sdk/capi/capi_guard.h"
#include "sdk/core/error.h"
#include "sls/sls_status.h"

// The C codes and the C++ codes are one list: keep them equal.
static_assert(SLS_ERROR_INVALID_ARGUMENT == static_cast<int>(sls::ErrorCode::kInvalidArgument));
static_assert(SLS_ERROR_IO == static_cast<int>(sls::ErrorCode::kIo));
static_assert(SLS_ERROR_FORMAT == static_cast<int>(sls::ErrorCode::kFormat));
static_assert(SLS_ERROR_NOT_FOUND == static_cast<int>(sls::ErrorCode::kNotFound));
static_assert(SLS_ERROR_OUT_OF_MEMORY == static_cast<int>(sls::ErrorCode::kOutOfMemory));
static_assert(SLS_ERROR_UNSUPPORTED == static_cast<int>(sls::ErrorCode::kUnsupported));
static_assert(SLS_ERROR_VERSION_MISMATCH == static_cast<int>(sls::ErrorCode::kVersionMismatch));
static_assert(SLS_ERROR_DEVICE == static_cast<int>(sls::ErrorCode::kDevice));
static_assert(SLS_ERROR_TIMEOUT == static_cast<int>(sls::ErrorCode::kTimeout));
static_assert(SLS_ERROR_CANCELLED == static_cast<int>(sls::ErrorCode::kCancelled));
static_assert(SLS_ERROR_BUSY == static_cast<int>(sls::ErrorCode::kBusy));
static_assert(SLS_ERROR_INTERNAL == static_cast<int>(sls::ErrorCode::kInternal));

extern "C" {

SLS_API const char* sls_status_str(sls_status status) {
  if (status == SLS_OK) return "ok";
  switch (status) {
    case SLS_ERROR_INVALID_ARGUMENT:
    case SLS_ERROR_IO:
    case SLS_ERROR_FORMAT:
    case SLS_ERROR_NOT_FOUND:
    case SLS_ERROR_OUT_OF_MEMORY:
    case SLS_ERROR_UNSUPPORTED:
    case SLS_ERROR_VERSION_MISMATCH:
    case SLS_ERROR_DEVICE:
    case SLS_ERROR_TIMEOUT:
    case SLS_ERROR_CANCELLED:
    case SLS_ERROR_BUSY:
    case SLS_ERROR_INTERNAL:
      return sls::error_code_name(static_cast<sls::ErrorCode>(status));
    case SLS_OK:
      break;
  }
  return "unknown status";
}

SLS_API const char* sls_error_message(const sls_error* error) { return error != nullptr ? error->message.c_str() : ""; }

SLS_API const char* sls_error_function(const sls_error* error) { return error != nullptr ? error->function.c_str() : ""; }

SLS_API sls_status sls_error_status(const sls_error* error) { return error != nullptr ? error->status : SLS_OK; }

SLS_API void sls_error_free(sls_error* error) { delete error; }

}  // extern "C"
