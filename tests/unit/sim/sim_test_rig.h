// A small rig for renderer tests: the ci preset at a given camera width, 8 frames.
#pragma once

#include "drivers/sim/rig.h"

namespace sls::sim {

inline SimRig small_rig(const Scene& scene, int width = 160) {
  RigOptions options;
  options.preset = "ci";
  options.camera_width = width;
  options.frames = 8;
  return make_rig(options, scene);
}

}  // namespace sls::sim
