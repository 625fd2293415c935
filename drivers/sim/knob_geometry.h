// The knurled knob's exact geometry for the scene's ground truth (scene.cpp): its side's
// half-tooth patches with their derivatives, and the exact signed distance (projected Newton
// on each patch near the point, bounded by the angle to the others). Internal to drivers/sim.
#pragma once

#include <Eigen/Core>

#include "drivers/sim/knurled_shared.h"

namespace sls::sim {

// Angular distance (in [0, pi]) from angle theta to the arc [lo, hi] (hi - lo < 2 pi).
double angular_distance_to_arc(double theta, double lo, double hi);

// Knob geometry on half-tooth patch j (j/2 <= u <= (j+1)/2, 0 <= z <= height), where R is
// linear in u: the side S(u, z) = (R cos theta, R sin theta, z) with
//   R = Ro - depth * tri(u),  theta = (2 pi u - A sin(omega z)) / N,
// and its first and second derivatives (for Newton on |p - S|^2).
struct KnobPatchPoint {
  Eigen::Vector3d s, su, sz, suu, suz, szz;
};
double knob_patch_tri(int j, double u);
KnobPatchPoint knob_patch_eval(const KnurledKnobT<double>& k, int j, double u, double z);

// The exact signed distance from p (object frame) to the knob (negative inside).
double knob_signed_distance(const KnurledKnobT<double>& k, const Eigen::Vector3d& p);

}  // namespace sls::sim
