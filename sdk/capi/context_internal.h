// The context's state, for the C API's other files (device enumeration and opening use the
// context's compute device).
#pragma once

#include "sdk/core/device.h"
#include "sls/sls_context.h"

struct sls_context {
  sls_context_config config;
  sls::Device device;  // resolved from config.device at creation
};
