// What a depth map's pixel says, for every fusion stage on both backends (DESIGN.md
// section 6): one test of a measurement.
#pragma once

#include "sdk/core/host_device.h"

namespace sls::fusion {

// A measured depth: positive and finite (0 is "no measurement"; NaN and inf are not depths).
SLS_HOST_DEVICE inline bool is_measured_depth(float depth_m) { return depth_m > 0.0f && depth_m < 3.0e38f; }

}  // namespace sls::fusion
