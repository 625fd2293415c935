// Wall-clock milliseconds for the per-stage timings that reports carry (steady clock: immune
// to the system clock being set).
#pragma once

#include <chrono>

namespace sls {

using SteadyClock = std::chrono::steady_clock;

inline double ms_since(SteadyClock::time_point start) {
  return std::chrono::duration<double, std::milli>(SteadyClock::now() - start).count();
}

}  // namespace sls
