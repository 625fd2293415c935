// The simulator scene tests' shared helpers (test_scene.cpp, test_knob_scene.cpp) and the
// random rays at the knurled objects that bench_sim_scene also casts.
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <vector>

#include <Eigen/Core>

#include "drivers/sim/scene.h"

namespace sls::sim::scene_test {

constexpr double kPi = 3.14159265358979323846;
using Vec3 = Eigen::Vector3d;

inline Vec3d v(const Vec3& p) { return {p.x(), p.y(), p.z()}; }
inline Vec3 e(const Vec3d& p) { return {p.x, p.y, p.z}; }
// A double ray rounded to float, for the float-vs-double comparisons.
inline RayT<float> to_float(const Ray& ray) {
  return {{static_cast<float>(ray.origin.x), static_cast<float>(ray.origin.y), static_cast<float>(ray.origin.z)},
          {static_cast<float>(ray.direction.x), static_cast<float>(ray.direction.y), static_cast<float>(ray.direction.z)}};
}
inline Ray make_ray(const Vec3& origin, const Vec3& direction) { return {v(origin), v(direction.normalized())}; }

inline Vec3 random_unit(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Vec3 d;
  do d = Vec3(n(rng), n(rng), n(rng)); while (d.norm() < 1e-6);
  return d.normalized();
}

inline double uniform(std::mt19937& rng, double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); }

// Finds the first sign change of f along the ray in [t0, t1] by steps of at most `step` (or
// `distance_step`(t) when given, which must be a lower bound of the distance to a root), then
// bisects to 1e-14. Returns infinity when f stays positive.
inline double brute_force_root(const std::function<double(double)>& f, double t0, double t1, double step,
                        const std::function<double(double)>& distance_step = nullptr) {
  double a = t0;
  double fa = f(a);
  if (fa <= 0.0) return a;
  while (a < t1) {
    double s = step;
    if (distance_step) s = std::max(distance_step(a), step);
    const double b = std::min(a + s, t1);
    const double fb = f(b);
    if (fb <= 0.0) {
      double lo = a, hi = b;
      while (hi - lo > 1e-14) {
        const double m = 0.5 * (lo + hi);
        if (m <= lo || m >= hi) break;
        (f(m) <= 0.0 ? hi : lo) = m;
      }
      return hi;
    }
    if (b >= t1) break;
    a = b;
  }
  return std::numeric_limits<double>::infinity();
}

// A random ray aimed at a point of the cylinder shell [inner - 1 mm, outer + 0.5 mm] x
// [-1 mm, height + 1 mm] around a knurled object's axis, from `range` away (0: 5-10 cm).
inline Ray random_ray_near(std::mt19937& rng, double inner_radius, double outer_radius, double height, double range) {
  const double a = uniform(rng, -kPi, kPi);
  const double rho = uniform(rng, inner_radius - 1e-3, outer_radius + 5e-4);
  const Vec3 target(rho * std::cos(a), rho * std::sin(a), uniform(rng, -1e-3, height + 1e-3));
  const Vec3 o = target + (range > 0.0 ? range : uniform(rng, 0.05, 0.1)) * random_unit(rng);
  return make_ray(o, target - o);
}
inline Ray random_screw_ray(std::mt19937& rng, const KnurledScrewT<double>& k, double range = 0.0) {
  return random_ray_near(rng, k.root_radius, k.ridge_radius, k.height, range);
}
inline Ray random_knob_ray(std::mt19937& rng, const KnurledKnobT<double>& k, double range = 0.0) {
  return random_ray_near(rng, k.root_radius, k.outer_radius, k.height, range);
}

// The scene's hits in float (the GPU's path) against double, for the rays `next_ray()` gives,
// away from grazing incidence (where float's t is ill-conditioned): the largest distance
// between the two hits, how many were compared, and which rays float missed.
struct FloatAgainstDouble {
  double worst_m = 0.0;
  int compared = 0;
  std::vector<int> missed_by_float;
};
template <typename NextRay>
FloatAgainstDouble float_against_double(const Scene& scene, int rays, NextRay next_ray) {
  const SceneShapeT<float> shape = scene.shape_float();
  FloatAgainstDouble result;
  for (int i = 0; i < rays; ++i) {
    const Ray ray = next_ray();
    Hit hit;
    if (!scene.intersect(ray, 0.0, 1.0, &hit)) continue;
    if (std::abs(e(hit.normal).dot(e(ray.direction))) < 0.2) continue;
    HitT<float> hit_float;
    if (!intersect(shape, to_float(ray), 0.0f, 1.0f, &hit_float)) {
      result.missed_by_float.push_back(i);
      continue;
    }
    const Vec3 point(hit_float.point.x, hit_float.point.y, hit_float.point.z);
    result.worst_m = std::max(result.worst_m, (point - e(hit.point)).norm());
    ++result.compared;
  }
  return result;
}

}  // namespace sls::sim::scene_test
