// The pattern projector driver interface: the simulated projector (drivers/sim) and the
// DLPC350 over USB (drivers/dlpc350, issue #7).
#pragma once

#include <string>

#include "sdk/decode/pattern_set.h"

namespace sls::drivers {

struct ProjectorInfo {
  std::string uri;
  std::string model;
  std::string firmware;
  int width = 0;   // DMD columns
  int height = 0;  // DMD rows
};

class Projector {
 public:
  virtual ~Projector() = default;

  virtual ProjectorInfo info() const = 0;
  // Loads a pattern set into the projector (the DLPC350's pattern LUT). Throws
  // kInvalidArgument when the set does not fit the projector (size, count).
  virtual void load_patterns(const PatternSet& patterns) = 0;
  virtual const PatternSet& patterns() const = 0;
  // Shows pattern `index` of the loaded set and fires the trigger output for the cameras.
  // Blocks until the pattern is on the DMD; kTimeout / kDevice when the projector stalls.
  virtual void show_pattern(int index) = 0;
  // The pattern on the DMD now, or −1 when dark.
  virtual int current_pattern() const = 0;
  virtual void go_dark() = 0;
};

}  // namespace sls::drivers
