#include "sdk/capi/capi_guard.h"

#include <new>
#include <stdexcept>

#include "sdk/core/error.h"

namespace sls::capi {

sls_status report(sls_status status, const char* function, const std::string& message, sls_error** error) {
  if (error != nullptr) {
    // Allocation of the error itself may fail; the status still reaches the caller.
    *error = new (std::nothrow) sls_error{status, message, function != nullptr ? function : ""};
  }
  return status;
}

sls_status status_from_current_exception(const char* function, sls_error** error) noexcept {
  try {
    throw;
  } catch (const sls::Error& e) {
    return report(static_cast<sls_status>(e.code()), function, e.what(), error);
  } catch (const std::bad_alloc&) {
    return report(SLS_ERROR_OUT_OF_MEMORY, function, "out of host memory", error);
  } catch (const std::exception& e) {
    return report(SLS_ERROR_INTERNAL, function, std::string("unexpected exception: ") + e.what(), error);
  } catch (...) {
    return report(SLS_ERROR_INTERNAL, function, "unexpected non-standard exception", error);
  }
}

}  // namespace sls::capi
