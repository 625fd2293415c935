// The C API's log level as the SDK's logger's, for sls_set_log_level and the context's config.
#pragma once

#include <spdlog/common.h>

#include "sls/sls_context.h"

namespace sls::capi {

// Throws sls::Error(kInvalidArgument) for a value that is not an sls_log_level.
spdlog::level::level_enum log_level_from_c(const sls_log_level& field);

}  // namespace sls::capi
