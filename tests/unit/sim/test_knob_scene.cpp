// Tests of the simulator's knurled knob against its exact geometry and brute-force references
// (the other scenes: test_scene.cpp).
#include "drivers/sim/scene.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "tests/unit/sim/scene_test_support.h"

namespace sls::sim {
namespace {

using namespace scene_test;  // NOLINT(google-build-using-namespace): the shared helpers

// ------------------------------------------------------------------------------- knurled knob
class KnurledKnob : public ::testing::Test {
 protected:
  const Scene scene = make_scene("knurled-knob");
  const KnurledKnobT<double>& k = scene.shape().knob;

  double implicit(const Vec3& p) const {
    int part;
    double slope;
    return knurled_knob_implicit(k, v(p), Vec3d{0, 0, 0}, &part, &slope);
  }
  Vec3 surface(double u, double z) const {
    double sign;
    const double R = k.outer_radius - k.depth * knurled_knob_tri(u, &sign);
    const double theta = (2 * kPi * u - k.wave_phase * std::sin(k.omega * z)) / k.teeth;
    return {R * std::cos(theta), R * std::sin(theta), z};
  }
  // Brute force: the least distance over dense (u, z) samples of the side around p, refined
  // around the best sample in four rounds; every sample is an upper bound of the distance.
  // Sample grids include the creases (u = j/2) and the cap edges (z = 0, H) exactly.
  double brute_distance(const Vec3& p, double half_u = 1.5, double half_z = 0.8e-3, int n0 = 600) const {
    const double rho = std::hypot(p.x(), p.y());
    const double theta = std::atan2(p.y(), p.x());
    double best = 1e300;
    if (rho <= knurled_knob_radius(k, theta, 0.0)) best = std::min(best, std::abs(p.z()));
    if (rho <= knurled_knob_radius(k, theta, k.height)) best = std::min(best, std::abs(p.z() - k.height));
    const double zc = std::clamp(p.z(), 0.0, k.height);
    const double u_p = knurled_knob_phase(k, theta, zc);
    double bu = u_p, bz = zc;
    int n = 0;
    for (int round = 0; round < 6; ++round) {
      n = round == 0 ? n0 : 60;
      std::vector<double> us, zs;
      for (int i = 0; i <= n; ++i) {
        us.push_back(bu - half_u + 2 * half_u * i / n);
        zs.push_back(std::clamp(bz - half_z + 2 * half_z * i / n, 0.0, k.height));
      }
      for (double c = std::ceil(2 * (bu - half_u)); c <= 2 * (bu + half_u); c += 1) us.push_back(0.5 * c);
      zs.push_back(0.0);
      zs.push_back(k.height);
      double nbu = bu, nbz = bz;
      for (double u : us) {
        for (double z : zs) {
          if (z < bz - half_z || z > bz + half_z) continue;
          const double d = (surface(u, z) - p).norm();
          if (d < best) {
            best = d;
            nbu = u;
            nbz = z;
          }
        }
      }
      bu = nbu;
      bz = nbz;
      half_u *= 4.0 / n;
      half_z *= 4.0 / n;
    }
    return best;
  }
};

TEST_F(KnurledKnob, GeometryFollowsThePaper) {
  EXPECT_EQ(k.teeth, 107);  // round(pi * 34)
  EXPECT_DOUBLE_EQ(k.outer_radius, 0.017);
  EXPECT_DOUBLE_EQ(k.height, 0.00725);
  const double a = kPi / 107;
  EXPECT_NEAR(k.depth, 0.017 * (1 - std::cos(a) + std::sin(a)), 1e-18);
  EXPECT_NEAR(k.wave_phase, kPi, 1e-15);  // ridges swing +-half a pitch
  EXPECT_NEAR(k.wave_length, k.height, 1e-18);
  // Ridges at R, roots at R - depth.
  EXPECT_NEAR(knurled_knob_radius(k, 0.0, 0.0), k.outer_radius, 1e-18);
  EXPECT_NEAR(knurled_knob_radius(k, kPi / 107, 0.0), k.root_radius, 1e-17);
  // At z = wave_length / 4 the ridges have moved by half a pitch: roots at theta = 0.
  EXPECT_NEAR(knurled_knob_radius(k, 0.0, 0.25 * k.wave_length), k.root_radius, 1e-17);
}

TEST_F(KnurledKnob, LipschitzBoundHoldsAlongRays) {
  std::mt19937 rng(9);
  double worst_ratio = 0.0;
  for (int i = 0; i < 200000; ++i) {
    const double rho = uniform(rng, 0.0, k.outer_radius + 1e-3), a = uniform(rng, -kPi, kPi);
    const Vec3 p(rho * std::cos(a), rho * std::sin(a), uniform(rng, -1e-3, k.height + 1e-3));
    const Vec3 d = random_unit(rng);
    const double h = 1e-7;
    const double dxy = std::hypot(d.x(), d.y());
    const double L = std::max(k.lipschitz_horizontal * dxy + k.lipschitz_vertical * std::abs(d.z()), std::abs(d.z()));
    worst_ratio = std::max(worst_ratio, std::abs(implicit(p + h * d) - implicit(p)) / (h * L));
  }
  std::printf("knob: max |dF/dt| / L = %.6f\n", worst_ratio);
  EXPECT_LE(worst_ratio, 1.0 + 1e-6);
  EXPECT_GT(worst_ratio, 0.9);  // and the bound is not loose
}


TEST_F(KnurledKnob, HitsLieOnTheSurfaceAndMatchBruteForceMarching) {
  std::mt19937 rng(10);
  double worst_f = 0.0, worst_sdf = 0.0, worst_t = 0.0;
  int side = 0, caps = 0, misses = 0;
  long steps_total = 0;
  for (int i = 0; i < 600; ++i) {
    const Ray ray = random_knob_ray(rng, k);
    Hit hit;
    int steps = 0;
    const bool got = intersect_knurled_knob(k, ray, 0.0, 1.0, &hit, &steps);
    // Reference: fixed 0.5 um steps on F inside the bounding cylinder, then bisection.
    double lo = 0.0, hi = 0.0, c0 = 0.0, c1 = 0.0;
    double ref = std::numeric_limits<double>::infinity();
    if (clip_to_cylinder(k.outer_radius, k.height, ray, 0.0, 1.0, &lo, &hi, &c0, &c1)) {
      auto f = [&](double t) { return implicit(e(ray.origin + t * ray.direction)); };
      ref = brute_force_root(f, lo, hi, 0.5e-6);
    }
    ASSERT_EQ(got, std::isfinite(ref)) << i;
    if (!got) {
      ++misses;
      continue;
    }
    steps_total += steps;
    (hit.part == kPartSide ? side : caps) += 1;
    worst_t = std::max(worst_t, std::abs(hit.t - ref));
    worst_f = std::max(worst_f, std::abs(implicit(e(hit.point))));
    worst_sdf = std::max(worst_sdf, std::abs(scene.signed_distance(e(hit.point))));
    EXPECT_NEAR(e(hit.normal).norm(), 1.0, 1e-14);
    EXPECT_LT(e(hit.normal).dot(e(ray.direction)), 0.0);
  }
  std::printf("knob: %d side, %d cap hits, %d misses, %.1f march steps per hit; max |F(hit)| %.3g m, "
              "|sdf(hit)| %.3g m, |t - brute force| %.3g m\n", side, caps, misses,
              static_cast<double>(steps_total) / std::max(side + caps, 1), worst_f, worst_sdf, worst_t);
  EXPECT_GT(side, 200);
  EXPECT_GT(caps, 20);
  EXPECT_LE(worst_f, 1e-12);
  EXPECT_LE(worst_sdf, 1e-12);
  EXPECT_LE(worst_t, 1e-11);
}

TEST_F(KnurledKnob, MarchingNeverSkipsAThinRidge) {
  // Rays skimming the ridge tips: tangent to a circle 1 nm to 30 um inside the ridge radius,
  // so each crossing of a ridge is a chord of a few um or less. The reference steps 0.05 um.
  std::mt19937 rng(11);
  int ref_hits = 0, extra = 0;
  double worst = 0.0;
  for (int i = 0; i < 600; ++i) {
    const double a = uniform(rng, -kPi, kPi);
    const double depth = std::pow(10.0, uniform(rng, -9, -4.5));
    const Vec3 radial(std::cos(a), std::sin(a), 0.0), tangent(-std::sin(a), std::cos(a), 0.0);
    const Vec3 foot = (k.outer_radius - depth) * radial + Vec3(0, 0, uniform(rng, 0.2e-3, k.height - 0.2e-3));
    const Vec3 d = (tangent + Vec3(0, 0, uniform(rng, -0.05, 0.05))).normalized();
    const Ray ray = make_ray(foot - 0.02 * d, d);
    Hit hit;
    const bool got = scene.intersect(ray, 0.0, 1.0, &hit);
    double lo = 0.0, hi = 0.0, c0 = 0.0, c1 = 0.0;
    double ref = std::numeric_limits<double>::infinity();
    if (clip_to_cylinder(k.outer_radius, k.height, ray, 0.0, 1.0, &lo, &hi, &c0, &c1)) {
      auto f = [&](double t) { return implicit(e(ray.origin + t * ray.direction)); };
      ref = brute_force_root(f, lo, hi, 0.05e-6);
    }
    if (std::isfinite(ref)) {
      ++ref_hits;
      ASSERT_TRUE(got) << i << " depth " << depth;
      // Never later than the reference (it may find a sliver the reference stepped over).
      EXPECT_LE(hit.t, ref + 1e-12) << i;
      worst = std::max(worst, std::abs(hit.t - ref));
    } else if (got) {
      ++extra;
    }
    if (got) {
      EXPECT_LE(std::abs(implicit(e(hit.point))), 1e-12);
    }
  }
  std::printf("knob grazing: %d reference hits, %d hits the reference stepped over, max |dt| %.3g m\n", ref_hits,
              extra, worst);
  EXPECT_GT(ref_hits, 100);
}

TEST_F(KnurledKnob, RaysFromInsideFindTheExit) {
  Hit hit;
  ASSERT_TRUE(scene.intersect(make_ray(Vec3(0, 0, 0.5 * k.height), Vec3(0, 0, 1)), 0.0, 1.0, &hit));
  EXPECT_EQ(hit.part, kPartTopCap);
  EXPECT_NEAR(hit.t, 0.5 * k.height, 1e-13);
  ASSERT_TRUE(scene.intersect(make_ray(Vec3(0, 0, 0.3e-3), Vec3(1, 0, 0)), 0.0, 1.0, &hit));
  EXPECT_EQ(hit.part, kPartSide);
  EXPECT_NEAR(std::hypot(hit.point.x, hit.point.y), knurled_knob_radius(k, 0.0, 0.3e-3), 1e-12);
  // Random interior origins and directions against a brute-force march on -F.
  std::mt19937 rng(16);
  double worst = 0.0;
  int caps = 0;
  for (int i = 0; i < 300; ++i) {
    const double a = uniform(rng, -kPi, kPi), rho = uniform(rng, 0.0, k.root_radius);
    const Vec3 o(rho * std::cos(a), rho * std::sin(a), uniform(rng, 0.0, k.height));
    const Ray ray = make_ray(o, random_unit(rng));
    ASSERT_TRUE(scene.intersect(ray, 0.0, 1.0, &hit)) << i;
    double lo = 0.0, hi = 0.0, c0 = 0.0, c1 = 0.0;
    ASSERT_TRUE(clip_to_cylinder(k.outer_radius, k.height, ray, 0.0, 1.0, &lo, &hi, &c0, &c1));
    auto f = [&](double t) { return -implicit(e(ray.origin + t * ray.direction)); };
    const double ref = std::min(brute_force_root(f, 0.0, hi, 0.5e-6), hi);  // leaves by hi at the latest
    worst = std::max(worst, std::abs(hit.t - ref));
    EXPECT_GT(e(hit.normal).dot(e(ray.direction)), 0.0);  // leaving: along the outward normal
    caps += hit.part != kPartSide ? 1 : 0;
  }
  EXPECT_GT(caps, 30);
  EXPECT_LE(worst, 1e-11);
}

TEST_F(KnurledKnob, SignedDistanceMatchesBruteForceSampling) {
  std::mt19937 rng(12);
  double worst_above = 0.0, worst_below = 0.0;
  for (int i = 0; i < 40; ++i) {
    const double a = uniform(rng, -kPi, kPi);
    const double rho = uniform(rng, k.root_radius - 0.2e-3, k.outer_radius + 0.3e-3);
    // Most along the side, a quarter near the top cap edge.
    const double z = i % 4 == 0 ? uniform(rng, k.height - 0.2e-3, k.height + 0.2e-3) : uniform(rng, 0.3e-3, k.height - 0.3e-3);
    const Vec3 p(rho * std::cos(a), rho * std::sin(a), z);
    const double d = scene.signed_distance(p);
    const double ref = brute_distance(p);
    // |d| can never exceed a sampled distance; the sampling converges onto the minimum.
    worst_above = std::max(worst_above, std::abs(d) - ref);
    worst_below = std::max(worst_below, ref - std::abs(d));
    EXPECT_EQ(d < 0.0, implicit(p) < 0.0);
  }
  // Far points (0.4 to 1.5 mm off the surface, outside and inside), wider sampling windows.
  for (int i = 0; i < 6; ++i) {
    const double a = uniform(rng, -kPi, kPi);
    const double rho = i % 2 == 0 ? uniform(rng, k.outer_radius + 0.4e-3, k.outer_radius + 1.5e-3)
                                  : uniform(rng, k.root_radius - 1.5e-3, k.root_radius - 0.4e-3);
    const Vec3 p(rho * std::cos(a), rho * std::sin(a), uniform(rng, 1.5e-3, k.height - 1.5e-3));
    const double d = scene.signed_distance(p);
    const double ref = brute_distance(p, 3.0, 2.5e-3, 1000);
    worst_above = std::max(worst_above, std::abs(d) - ref);
    worst_below = std::max(worst_below, ref - std::abs(d));
    EXPECT_GT(std::abs(d), 0.3e-3);
    EXPECT_EQ(d < 0.0, implicit(p) < 0.0);
  }
  std::printf("knob sdf vs brute force: |d| - ref <= %.3g m, ref - |d| <= %.3g m\n", worst_above, worst_below);
  EXPECT_LE(worst_above, 1e-15);
  EXPECT_LE(worst_below, 1e-9);
  // Known values: above the top cap centre; beyond the top edge of a ridge at z = 0.
  EXPECT_NEAR(scene.signed_distance(Vec3(0, 0, k.height + 1e-3)), 1e-3, 1e-15);
  EXPECT_NEAR(scene.signed_distance(Vec3(0, 0, 0.5 * k.height)), -0.5 * k.height, 1e-15);
}

TEST_F(KnurledKnob, FloatAgreesWithDoubleAtTenCentimetres) {
  std::mt19937 rng(13);
  const FloatAgainstDouble r = float_against_double(scene, 2000, [&] { return random_knob_ray(rng, k, 0.1); });
  std::printf("knob float vs double at 0.1 m: max %.3g m over %d hits\n", r.worst_m, r.compared);
  EXPECT_TRUE(r.missed_by_float.empty()) << "ray " << r.missed_by_float.front();
  EXPECT_GT(r.compared, 300);
  EXPECT_LE(r.worst_m, 1e-7);
}

TEST_F(KnurledKnob, CreasePolylinesFollowTheCurvesAndDistanceMatchesBruteForce) {
  const auto& creases = scene.creases();
  ASSERT_EQ(creases.size(), 2u * 107 + 2);
  // Every ridge / groove polyline is within 0.1 um of its exact curve (checked between vertices).
  double worst_curve = 0.0;
  for (int c = 0; c < 2 * 107; c += 7) {
    const Polyline& line = creases[static_cast<std::size_t>(c)];
    const double u = 0.5 * c;  // ridge t at index 2t (u = t), groove at 2t + 1 (u = t + 1/2)
    const double rho = c % 2 == 0 ? k.outer_radius : k.root_radius;
    for (int i = 0; i <= 4000; ++i) {
      const double z = k.height * i / 4000.0;
      const double th = (2 * kPi * u - k.wave_phase * std::sin(k.omega * z)) / k.teeth;
      const Vec3 q(rho * std::cos(th), rho * std::sin(th), z);
      double best = 1e300;
      for (std::size_t j = 0; j + 1 < line.size(); ++j) {
        const Vec3 s = line[j + 1] - line[j];
        const double w = std::clamp((q - line[j]).dot(s) / s.squaredNorm(), 0.0, 1.0);
        best = std::min(best, (q - (line[j] + w * s)).norm());
      }
      worst_curve = std::max(worst_curve, best);
    }
  }
  std::printf("knob crease polylines: max distance from the curve %.3g m\n", worst_curve);
  EXPECT_LE(worst_curve, 1e-7);
  EXPECT_GT(worst_curve, 1e-9);  // (the check has teeth: the polylines are not the curves)

  std::mt19937 rng(14);
  double worst = 0.0;
  for (int i = 0; i < 200; ++i) {
    const double rho = i % 5 == 0 ? uniform(rng, 0.0, 0.04) : uniform(rng, k.root_radius - 5e-4, k.outer_radius + 5e-4);
    const double a = uniform(rng, -kPi, kPi);
    const Vec3 p(rho * std::cos(a), rho * std::sin(a), uniform(rng, -1e-3, k.height + 1e-3));
    double ref = 1e300;
    for (const Polyline& line : creases) {
      for (std::size_t j = 0; j + 1 < line.size(); ++j) {
        const Vec3 s = line[j + 1] - line[j];
        const double w = std::clamp((p - line[j]).dot(s) / s.squaredNorm(), 0.0, 1.0);
        ref = std::min(ref, (p - (line[j] + w * s)).norm());
      }
    }
    worst = std::max(worst, std::abs(scene.distance_to_creases(p) - ref));
  }
  EXPECT_LE(worst, 1e-15);
  // On a ridge curve.
  EXPECT_LE(scene.distance_to_creases(surface(3.0, 0.37 * k.height)), 1e-7);
}

TEST_F(KnurledKnob, ReferenceCloudLiesOnTheSurfaceWithUnitNormals) {
  const auto samples = scene.reference_samples(2.5e-4);
  ASSERT_GT(samples.size(), 20000u);
  double worst = 0.0, worst_f = 0.0, worst_normal = 0.0, worst_offset = 0.0;
  std::size_t i = 0;
  for (const SurfaceSample& s : samples) {
    worst_f = std::max(worst_f, std::abs(implicit(s.position)));
    worst_normal = std::max(worst_normal, std::abs(s.normal.norm() - 1.0));
    if (i++ % 10 != 0) continue;  // the numerical distance on a tenth of them
    worst = std::max(worst, std::abs(scene.signed_distance(s.position)));
    worst_offset = std::max(worst_offset, std::abs(scene.signed_distance(s.position + 1e-6 * s.normal) - 1e-6));
  }
  std::printf("knob reference cloud: max |F| %.3g, |sdf| %.3g, |sdf(p + 1um n) - 1um| %.3g m\n", worst_f, worst,
              worst_offset);
  EXPECT_LE(worst_f, 1e-15);
  EXPECT_LE(worst, 1e-12);
  EXPECT_LE(worst_normal, 1e-15);
  EXPECT_LE(worst_offset, 1e-11);
}

}  // namespace
}  // namespace sls::sim
