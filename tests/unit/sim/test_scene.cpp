// Tests of the simulator's scenes against closed forms and independent brute-force references:
// the factory and JSON, plane, sphere, chessboard and the knurled screw (the knob: test_knob_scene.cpp).
#include "drivers/sim/scene.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "sdk/core/error.h"
#include "sdk/core/ply.h"
#include "tests/support/test_support.h"
#include "tests/unit/sim/scene_test_support.h"

namespace sls::sim {
namespace {

using namespace scene_test;  // NOLINT(google-build-using-namespace): the shared helpers

// ------------------------------------------------------------------------------- factory, JSON
TEST(SimScene, FactoryKnowsEveryNameAndRejectsOthers) {
  for (const std::string& name : scene_names()) {
    const Scene s = make_scene(name);
    EXPECT_EQ(s.name(), name);
  }
  try {
    make_scene("knurled-bolt");
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("knurled-bolt"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("knurled-screw"), std::string::npos);
  }
}

TEST(SimScene, JsonRoundTripsEveryScene) {
  for (const std::string& name : scene_names()) {
    const Scene s = make_scene(name);
    const std::string json = s.to_json();
    const Scene back = scene_from_json(json);
    EXPECT_EQ(back.to_json(), json) << name;
    EXPECT_EQ(back.kind(), s.kind());
  }
}

TEST(SimScene, JsonParametersOverrideDefaultsAndErrorsAreClear) {
  const Scene s = scene_from_json(R"({"name": "knurled-screw", "parameters": {"diameter_m": 0.02, "albedo": 0.3}})");
  EXPECT_EQ(s.shape().screw.teeth, 63);  // round(pi * 20)
  EXPECT_DOUBLE_EQ(s.shape().screw.ridge_radius, 0.01);
  EXPECT_DOUBLE_EQ(s.shape().screw.albedo.base, 0.3);
  EXPECT_NE(s.to_json().find("\"teeth\": 63"), std::string::npos);
  const Scene board = scene_from_json(R"({"name": "chessboard", "parameters": {"inner_corners_x": 4, "inner_corners_y": 3}})");
  EXPECT_EQ(board.chessboard_corners().size(), 12u);

  auto code_of = [](const std::string& json) {
    try {
      scene_from_json(json);
    } catch (const Error& e) {
      return e.code();
    }
    return ErrorCode::kInternal;
  };
  EXPECT_EQ(code_of(R"({"name": "teapot"})"), ErrorCode::kInvalidArgument);
  EXPECT_EQ(code_of(R"({"name": "sphere", "parameters": {"radius": 1}})"), ErrorCode::kInvalidArgument);
  EXPECT_EQ(code_of(R"({"name": "sphere", "parameters": {"radius_m": "big"}})"), ErrorCode::kFormat);
  EXPECT_EQ(code_of(R"({"name": "sphere", "parameters": {"radius_m": -1}})"), ErrorCode::kInvalidArgument);
  EXPECT_EQ(code_of(R"({"name": "knurled-screw", "parameters": {"groove_angle_deg": 2}})"), ErrorCode::kInvalidArgument);
  EXPECT_EQ(code_of("{not json"), ErrorCode::kFormat);
  EXPECT_EQ(code_of(R"({"parameters": {}})"), ErrorCode::kFormat);
}

// ------------------------------------------------------------------------------- plane
TEST(SimPlane, IntersectionAndDistanceMatchClosedForm) {
  const Scene s = make_scene("plane");
  std::mt19937 rng(1);
  double worst = 0.0;
  for (int i = 0; i < 2000; ++i) {
    const Vec3 o(uniform(rng, -0.1, 0.1), uniform(rng, -0.1, 0.1), uniform(rng, 0.01, 0.2));
    Vec3 d = random_unit(rng);
    if (d.z() > -0.05) d.z() = -0.05 - std::abs(d.z());
    d.normalize();
    Hit hit;
    ASSERT_TRUE(s.intersect(make_ray(o, d), 0.0, 10.0, &hit));
    const double t = -o.z() / d.z();
    worst = std::max({worst, std::abs(hit.t - t), (e(hit.point) - (o + t * d)).norm()});
    EXPECT_EQ(hit.point.z, 0.0);
    EXPECT_EQ(hit.normal.z, 1.0);
    // Signed distance of a point is its z.
    const Vec3 p(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
    EXPECT_EQ(s.signed_distance(p), p.z());
  }
  EXPECT_LE(worst, 1e-12);
  // t_max, parallel rays.
  Hit hit;
  EXPECT_FALSE(s.intersect(make_ray(Vec3(0, 0, 1), Vec3(0, 0, -1)), 0.0, 0.5, &hit));
  EXPECT_FALSE(s.intersect(make_ray(Vec3(0, 0, 1), Vec3(1, 0, 0)), 0.0, 5.0, &hit));

  PlaneParameters finite;
  finite.half_extent_x = 0.01;
  finite.half_extent_y = 0.02;
  const Scene f = make_plane_scene(finite);
  EXPECT_FALSE(f.intersect(make_ray(Vec3(0.011, 0, 1), Vec3(0, 0, -1)), 0.0, 5.0, &hit));
  EXPECT_TRUE(f.intersect(make_ray(Vec3(0.009, -0.019, 1), Vec3(0, 0, -1)), 0.0, 5.0, &hit));
  EXPECT_NEAR(f.signed_distance(Vec3(0.013, 0.0, 0.004)), 0.005, 1e-15);     // 3-4-5 beyond the edge
  EXPECT_NEAR(f.signed_distance(Vec3(0.013, 0.0, -0.004)), -0.005, 1e-15);
  EXPECT_NEAR(f.signed_distance(Vec3(0.005, 0.01, 0.002)), 0.002, 1e-15);
}

// ------------------------------------------------------------------------------- sphere
TEST(SimSphere, IntersectionAndDistanceMatchClosedForm) {
  SphereParameters params;
  params.center = Vec3(0.01, -0.02, 0.3);
  params.radius = 0.015;
  const Scene s = make_sphere_scene(params);
  std::mt19937 rng(2);
  double worst_t = 0.0, worst_normal = 0.0, worst_sdf = 0.0;
  int hits = 0;
  for (int i = 0; i < 5000; ++i) {
    const Vec3 o = params.center + uniform(rng, 0.05, 0.3) * random_unit(rng);
    const Vec3 target = params.center + uniform(rng, 0.0, 1.3 * params.radius) * random_unit(rng);
    const Vec3 d = (target - o).normalized();
    // Closed form: foot of the perpendicular from the centre, then back by the half chord.
    const double tf = (params.center - o).dot(d);
    const double h2 = (o + tf * d - params.center).squaredNorm();
    Hit hit;
    const bool got = s.intersect(make_ray(o, d), 0.0, 1.0, &hit);
    ASSERT_EQ(got, h2 <= params.radius * params.radius) << i;
    if (!got) continue;
    ++hits;
    const double t = tf - std::sqrt(params.radius * params.radius - h2);
    worst_t = std::max(worst_t, std::abs(hit.t - t));
    worst_normal = std::max(worst_normal, (e(hit.normal) - (e(hit.point) - params.center) / params.radius).norm());
    worst_sdf = std::max(worst_sdf, std::abs(s.signed_distance(e(hit.point))));
    const Vec3 p = params.center + uniform(rng, 0.0, 0.1) * random_unit(rng);
    EXPECT_NEAR(s.signed_distance(p), (p - params.center).norm() - params.radius, 1e-15);
  }
  EXPECT_GT(hits, 1000);
  EXPECT_LE(worst_t, 1e-9);
  EXPECT_LE(worst_normal, 1e-9);
  EXPECT_LE(worst_sdf, 1e-9);
  std::printf("sphere: max |dt| %.3g m, normal %.3g, |sdf(hit)| %.3g m over %d hits\n", worst_t, worst_normal,
              worst_sdf, hits);
  // From inside: the exit.
  Hit hit;
  ASSERT_TRUE(s.intersect(make_ray(params.center, Vec3(0, 0, 1)), 0.0, 1.0, &hit));
  EXPECT_NEAR(hit.t, params.radius, 1e-15);
}

// ------------------------------------------------------------------------------- chessboard
TEST(SimChessboard, CornersAlbedoAndIntersection) {
  const Scene s = make_scene("chessboard");
  const ChessboardT<double>& c = s.shape().chessboard;
  EXPECT_EQ(c.squares_x, 10);
  EXPECT_EQ(c.squares_y, 8);
  const auto corners = s.chessboard_corners();
  ASSERT_EQ(corners.size(), 63u);
  EXPECT_NEAR(corners.front().x(), -4 * c.square, 1e-15);
  EXPECT_NEAR(corners.front().y(), -3 * c.square, 1e-15);
  EXPECT_NEAR(corners[1].x() - corners[0].x(), c.square, 1e-15);  // x fastest
  EXPECT_NEAR(corners.back().x(), 4 * c.square, 1e-15);
  EXPECT_NEAR(corners.back().y(), 3 * c.square, 1e-15);
  // Around each inner corner the four squares alternate dark / light.
  for (const Vec3& q : corners) {
    const double h = 0.25 * c.square;
    const double a = chessboard_albedo(c, q.x() - h, q.y() - h), b = chessboard_albedo(c, q.x() + h, q.y() - h);
    EXPECT_EQ(a, chessboard_albedo(c, q.x() + h, q.y() + h));
    EXPECT_EQ(b, chessboard_albedo(c, q.x() - h, q.y() + h));
    EXPECT_NE(a, b);
  }
  EXPECT_EQ(chessboard_albedo(c, -4.5 * c.square - 0.0, -3.5 * c.square), 0.1);  // square (0, 0) is dark
  EXPECT_EQ(chessboard_albedo(c, -5.2 * c.square, 0.0), 0.9);                    // margin
  Hit hit;
  ASSERT_TRUE(s.intersect(make_ray(Vec3(-4.5 * c.square, -3.5 * c.square, 0.1), Vec3(0, 0, -1)), 0.0, 1.0, &hit));
  EXPECT_EQ(hit.albedo, 0.1);
  EXPECT_EQ(hit.feature, 0);
  EXPECT_FALSE(s.intersect(make_ray(Vec3(c.half_width() + 1e-6, 0, 0.1), Vec3(0, 0, -1)), 0.0, 1.0, &hit));
  EXPECT_THROW(make_scene("sphere").chessboard_corners(), Error);
}

// ------------------------------------------------------------------------------- knurled screw
class KnurledScrew : public ::testing::Test {
 protected:
  const Scene scene = make_scene("knurled-screw");
  const KnurledScrewT<double>& k = scene.shape().screw;

  // The 2N polygon vertices, ridge k at index 2k.
  Vec3 vertex(int i) const {
    const double rho = i % 2 == 0 ? k.ridge_radius : k.root_radius;
    const double a = 0.5 * i * k.sector;
    return {rho * std::cos(a), rho * std::sin(a), 0.0};
  }
  // 2D distance to the polygon by brute force over all 2N edges.
  double brute_polygon_distance(double x, double y) const {
    double best = 1e300;
    const Vec3 p(x, y, 0.0);
    for (int i = 0; i < 2 * k.teeth; ++i) {
      const Vec3 a = vertex(i), b = vertex(i + 1);
      const double u = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
      best = std::min(best, (p - (a + u * (b - a))).norm());
    }
    return best;
  }
  // Even-odd rule: edges crossed by the half-line from (x, y) towards +x.
  bool brute_inside(double x, double y) const {
    bool inside = false;
    for (int i = 0; i < 2 * k.teeth; ++i) {
      const Vec3 a = vertex(i), b = vertex(i + 1);
      if ((a.y() > y) != (b.y() > y)) {
        const double xc = a.x() + (y - a.y()) * (b.x() - a.x()) / (b.y() - a.y());
        if (xc > x) inside = !inside;
      }
    }
    return inside;
  }
};

TEST_F(KnurledScrew, GeometryFollowsThePaperAndA90DegreeV) {
  EXPECT_EQ(k.teeth, 101);  // round(pi * 32.2)
  EXPECT_DOUBLE_EQ(k.ridge_radius, 0.0161);
  EXPECT_DOUBLE_EQ(k.height, 0.0148);
  const double a = kPi / 101;
  EXPECT_NEAR(k.root_radius, 0.0161 * (std::cos(a) - std::sin(a)), 1e-18);
  EXPECT_NEAR(k.ridge_radius - k.root_radius, 0.50850e-3, 1e-8);  // the documented depth
  // Groove: the flanks meeting at root 0 (between ridges 0 and 1) form 90 degrees.
  const Vec3 root = vertex(1), r0 = vertex(0), r1 = vertex(2);
  EXPECT_NEAR((r0 - root).normalized().dot((r1 - root).normalized()), 0.0, 1e-14);
  EXPECT_NEAR(root.norm(), k.root_radius, 1e-18);
}

TEST_F(KnurledScrew, PolygonDistanceMatchesBruteForce) {
  std::mt19937 rng(3);
  double worst = 0.0;
  for (int i = 0; i < 3000; ++i) {
    // Mostly near the knurl, some far inside and outside, some on the axis.
    const double rho = i % 10 == 0 ? uniform(rng, 0.0, 0.05) : uniform(rng, k.root_radius - 1e-3, k.ridge_radius + 1e-3);
    const double a = uniform(rng, -kPi, kPi);
    const double x = rho * std::cos(a), y = rho * std::sin(a);
    const double d = knurled_screw_polygon_distance(k, x, y);
    const double ref = brute_polygon_distance(x, y);
    worst = std::max(worst, std::abs(std::abs(d) - ref));
    // The sign by an independent test: the crossing number along +x from the point.
    EXPECT_EQ(d < 0.0, brute_inside(x, y)) << x << " " << y;
  }
  EXPECT_LE(worst, 1e-15);
  EXPECT_NEAR(knurled_screw_polygon_distance(k, 0.0, 0.0), -brute_polygon_distance(0.0, 0.0), 1e-16);
}

TEST_F(KnurledScrew, SignedDistanceAtKnownPoints) {
  const double R = k.ridge_radius, r = k.root_radius, H = k.height;
  const double half = 0.5 * k.sector;
  auto at = [](double rho, double a, double z) { return Vec3(rho * std::cos(a), rho * std::sin(a), z); };
  // On a ridge line, a root line, a cap.
  EXPECT_NEAR(scene.signed_distance(at(R, 7 * k.sector, 0.3 * H)), 0.0, 1e-16);
  EXPECT_NEAR(scene.signed_distance(at(r, 7 * k.sector + half, 0.3 * H)), 0.0, 1e-16);
  EXPECT_EQ(scene.signed_distance(Vec3(0.001, 0.002, H)), 0.0);
  // Radially outside a ridge: the ridge line is nearest.
  EXPECT_NEAR(scene.signed_distance(at(R + 1e-3, 3 * k.sector, 0.5 * H)), 1e-3, 1e-15);
  // Above the top cap, inside the outline; below the bottom cap.
  EXPECT_NEAR(scene.signed_distance(Vec3(0.001, -0.003, H + 2e-3)), 2e-3, 1e-15);
  EXPECT_NEAR(scene.signed_distance(Vec3(0.001, -0.003, -5e-4)), 5e-4, 1e-15);
  // Beyond the corner where a ridge meets the top cap.
  EXPECT_NEAR(scene.signed_distance(at(R + 3e-4, 0.0, H + 4e-4)), 5e-4, 1e-15);
  // Outside in a groove on its bisector: the flanks are at 45 degrees to it.
  EXPECT_NEAR(scene.signed_distance(at(r + 1e-4, half, 0.5 * H)), 1e-4 / std::sqrt(2.0), 1e-15);
  // Inside below a root on the bisector: the root line (a reflex corner) is nearest.
  EXPECT_NEAR(scene.signed_distance(at(r - 1e-4, half, 0.5 * H)), -1e-4, 1e-15);
  // Inside near the centre: the caps (7.4 mm) are nearer than the roots (15.6 mm).
  EXPECT_NEAR(scene.signed_distance(Vec3(0, 0, 0.5 * H)), -0.5 * H, 1e-15);
  // Off a flank's midpoint along its normal.
  const Vec3 mid = 0.5 * (vertex(4) + vertex(5)) + Vec3(0, 0, 0.5 * H);
  const Vec3 n = Vec3((vertex(5) - vertex(4)).y(), -(vertex(5) - vertex(4)).x(), 0).normalized();  // outward
  EXPECT_NEAR(scene.signed_distance(mid + 5e-5 * n), 5e-5, 1e-15);
  EXPECT_NEAR(scene.signed_distance(mid - 5e-5 * n), -5e-5, 1e-15);
}

TEST_F(KnurledScrew, RaysDownGroovesAndOntoRidgesHitAtExactRadii) {
  for (int i = 0; i < 101; ++i) {
    const double a_root = (i + 0.5) * k.sector, a_ridge = i * k.sector;
    const Vec3 dir_root(std::cos(a_root), std::sin(a_root), 0.0), dir_ridge(std::cos(a_ridge), std::sin(a_ridge), 0.0);
    Hit hit;
    ASSERT_TRUE(scene.intersect(make_ray(0.05 * dir_root + Vec3(0, 0, 0.004), -dir_root), 0.0, 1.0, &hit));
    EXPECT_NEAR(std::hypot(hit.point.x, hit.point.y), k.root_radius, 1e-15) << i;
    EXPECT_NEAR(hit.t, 0.05 - k.root_radius, 1e-15);
    ASSERT_TRUE(scene.intersect(make_ray(0.05 * dir_ridge + Vec3(0, 0, 0.01), -dir_ridge), 0.0, 1.0, &hit));
    EXPECT_NEAR(std::hypot(hit.point.x, hit.point.y), k.ridge_radius, 1e-15) << i;
  }
}


TEST_F(KnurledScrew, HitsLieOnTheSurfaceWithFlankNormalsAndMatchBruteForce) {
  std::mt19937 rng(4);
  double worst_sdf = 0.0, worst_t = 0.0, worst_perp = 0.0;
  int side_hits = 0, cap_hits = 0, misses = 0;
  for (int i = 0; i < 3000; ++i) {
    const Ray ray = random_screw_ray(rng, k);
    Hit hit;
    const bool got = scene.intersect(ray, 0.0, 1.0, &hit);
    // Reference: march on the exact signed distance (steps of sdf never pass the surface).
    auto f = [&](double t) { return knurled_screw_sdf(k, ray.origin + t * ray.direction); };
    const double ref = brute_force_root(f, 0.0, 1.0, 1e-9, f);
    ASSERT_EQ(got, std::isfinite(ref)) << i;
    if (!got) {
      ++misses;
      continue;
    }
    worst_t = std::max(worst_t, std::abs(hit.t - ref));
    worst_sdf = std::max(worst_sdf, std::abs(scene.signed_distance(e(hit.point))));
    EXPECT_NEAR(e(hit.normal).norm(), 1.0, 1e-15);
    EXPECT_LT(e(hit.normal).dot(e(ray.direction)), 0.0);  // from outside, the ray meets the outward normal
    if (hit.part == kPartSide) {
      ++side_hits;
      // Flank f joins vertices f and f+1; the normal is perpendicular to it, horizontal, outward.
      const Vec3 a = vertex(hit.feature), b = vertex(hit.feature + 1);
      worst_perp = std::max(worst_perp, std::abs(e(hit.normal).dot((b - a).normalized())));
      EXPECT_EQ(hit.normal.z, 0.0);
      EXPECT_GT(e(hit.normal).dot(0.5 * (a + b)), 0.0);
      const Vec3 p(hit.point.x, hit.point.y, 0.0);
      EXPECT_LE(std::abs((p - a).dot(e(hit.normal))), 1e-15);  // on that flank's line
    } else {
      ++cap_hits;
      EXPECT_EQ(hit.point.z, hit.part == kPartTopCap ? k.height : 0.0);
      EXPECT_EQ(hit.normal.z, hit.part == kPartTopCap ? 1.0 : -1.0);
    }
  }
  std::printf("screw: %d side, %d cap hits, %d misses; max |sdf(hit)| %.3g m, |t - brute force| %.3g m, "
              "|n . flank| %.3g\n", side_hits, cap_hits, misses, worst_sdf, worst_t, worst_perp);
  EXPECT_GT(side_hits, 1000);
  EXPECT_GT(cap_hits, 100);
  EXPECT_GT(misses, 100);
  EXPECT_LE(worst_sdf, 1e-12);
  EXPECT_LE(worst_t, 1e-12);
  EXPECT_LE(worst_perp, 1e-13);  // rounding of the reference vertices dominates
}

TEST_F(KnurledScrew, GrazingRaysAgreeWithBruteForce) {
  // Rays skimming the ridge tips (tangent to a circle just inside the ridge radius).
  std::mt19937 rng(5);
  int hits = 0;
  double worst = 0.0;
  for (int i = 0; i < 2000; ++i) {
    const double a = uniform(rng, -kPi, kPi);
    const double depth = std::pow(10.0, uniform(rng, -9, -3.5));
    const Vec3 radial(std::cos(a), std::sin(a), 0.0), tangent(-std::sin(a), std::cos(a), 0.0);
    const Vec3 foot = (k.ridge_radius - depth) * radial + Vec3(0, 0, uniform(rng, 0.0, k.height));
    const Vec3 d = (tangent + Vec3(0, 0, uniform(rng, -0.01, 0.01))).normalized();
    const Ray ray = make_ray(foot - 0.02 * d, d);
    Hit hit;
    const bool got = scene.intersect(ray, 0.0, 1.0, &hit);
    auto f = [&](double t) { return knurled_screw_sdf(k, ray.origin + t * ray.direction); };
    const double ref = brute_force_root(f, 0.0, 0.04, 1e-10, f);
    ASSERT_EQ(got, std::isfinite(ref)) << i << " depth " << depth;
    if (got) {
      ++hits;
      worst = std::max(worst, std::abs(hit.t - ref));
    }
  }
  EXPECT_GT(hits, 500);
  EXPECT_LE(worst, 1e-12);
}

TEST_F(KnurledScrew, RaysFromInsideFindTheExit) {
  Hit hit;
  ASSERT_TRUE(scene.intersect(make_ray(Vec3(0, 0, 0.5 * k.height), Vec3(1, 0, 0)), 0.0, 1.0, &hit));
  EXPECT_NEAR(hit.t, k.ridge_radius, 1e-15);  // out through ridge 0
  ASSERT_TRUE(scene.intersect(make_ray(Vec3(0.001, 0, 0.5 * k.height), Vec3(0, 0, 1)), 0.0, 1.0, &hit));
  EXPECT_EQ(hit.part, kPartTopCap);
  EXPECT_NEAR(hit.t, 0.5 * k.height, 1e-15);
  // Along the x axis across the whole screw: with 101 teeth a root lies at 180 degrees (root
  // 50.5), so the ray enters at x = -r; with t_min past that it leaves through ridge 0 at x = R.
  const Ray across = make_ray(Vec3(-0.05, 0, 0.003), Vec3(1, 0, 0));
  ASSERT_TRUE(scene.intersect(across, 0.0, 1.0, &hit));
  EXPECT_NEAR(hit.t, 0.05 - k.root_radius, 1e-15);
  ASSERT_TRUE(scene.intersect(across, hit.t + 1e-9, 1.0, &hit));
  EXPECT_NEAR(hit.t, 0.05 + k.ridge_radius, 1e-15);
  EXPECT_NEAR(hit.normal.x, k.flank_nx, 1e-15);  // a ridge's normal is one of its flanks'
  EXPECT_NEAR(std::abs(hit.normal.y), k.flank_ny, 1e-15);
  // Random interior origins and directions against a march on -sdf (exact distance steps).
  std::mt19937 rng(17);
  double worst = 0.0;
  int caps = 0;
  for (int i = 0; i < 1000; ++i) {
    const double a = uniform(rng, -kPi, kPi), rho = uniform(rng, 0.0, k.root_radius);
    const Vec3 o(rho * std::cos(a), rho * std::sin(a), uniform(rng, 0.0, k.height));
    const Ray ray = make_ray(o, random_unit(rng));
    ASSERT_TRUE(scene.intersect(ray, 0.0, 1.0, &hit)) << i;
    auto f = [&](double t) { return -knurled_screw_sdf(k, ray.origin + t * ray.direction); };
    worst = std::max(worst, std::abs(hit.t - brute_force_root(f, 0.0, 1.0, 1e-9, f)));
    EXPECT_GT(e(hit.normal).dot(e(ray.direction)), 0.0);
    caps += hit.part != kPartSide ? 1 : 0;
  }
  EXPECT_GT(caps, 100);
  EXPECT_LE(worst, 1e-12);
}

TEST_F(KnurledScrew, FloatAgreesWithDoubleAtTenCentimetres) {
  std::mt19937 rng(6);
  const FloatAgainstDouble r = float_against_double(scene, 5000, [&] { return random_screw_ray(rng, k, 0.1); });
  std::printf("screw float vs double at 0.1 m: max %.3g m over %d hits\n", r.worst_m, r.compared);
  EXPECT_TRUE(r.missed_by_float.empty()) << "ray " << r.missed_by_float.front();
  EXPECT_GT(r.compared, 1000);
  EXPECT_LE(r.worst_m, 1e-7);
}

TEST_F(KnurledScrew, CreasesAndTheirDistance) {
  const auto& creases = scene.creases();
  ASSERT_EQ(creases.size(), 2u * 101 + 2);  // ridge + groove lines, two cap outlines
  const double R = k.ridge_radius, H = k.height;
  EXPECT_NEAR(scene.distance_to_creases(Vec3(R, 0, 0.3 * H)), 0.0, 1e-16);
  EXPECT_NEAR(scene.distance_to_creases(Vec3(R + 2e-4, 0, 0.5 * H)), 2e-4, 1e-15);
  std::mt19937 rng(7);
  double worst = 0.0;
  for (int i = 0; i < 500; ++i) {
    const double rho = i % 5 == 0 ? uniform(rng, 0.0, 0.04) : uniform(rng, k.root_radius - 5e-4, R + 5e-4);
    const double a = uniform(rng, -kPi, kPi);
    const Vec3 p(rho * std::cos(a), rho * std::sin(a), uniform(rng, -2e-3, H + 2e-3));
    double ref = 1e300;
    for (const Polyline& line : creases) {
      for (std::size_t j = 0; j + 1 < line.size(); ++j) {
        const Vec3 s = line[j + 1] - line[j];
        const double u = std::clamp((p - line[j]).dot(s) / s.squaredNorm(), 0.0, 1.0);
        ref = std::min(ref, (p - (line[j] + u * s)).norm());
      }
    }
    worst = std::max(worst, std::abs(scene.distance_to_creases(p) - ref));
  }
  EXPECT_LE(worst, 1e-15);
  EXPECT_TRUE(std::isinf(make_scene("sphere").distance_to_creases(Vec3::Zero())));
}

TEST_F(KnurledScrew, ReferenceCloudLiesOnTheSurfaceWithExactNormals) {
  const auto samples = scene.reference_samples(2e-4);
  ASSERT_GT(samples.size(), 50000u);
  double worst = 0.0, worst_normal = 0.0, worst_offset = 0.0;
  for (const SurfaceSample& s : samples) {
    worst = std::max(worst, std::abs(scene.signed_distance(s.position)));
    worst_normal = std::max(worst_normal, std::abs(s.normal.norm() - 1.0));
    // One micrometre along the normal is one micrometre away (samples keep off the creases).
    worst_offset = std::max(worst_offset, std::abs(scene.signed_distance(s.position + 1e-6 * s.normal) - 1e-6));
  }
  EXPECT_LE(worst, 1e-12);
  EXPECT_LE(worst_normal, 1e-15);
  EXPECT_LE(worst_offset, 1e-12);
  // z range.
  const auto band = scene.reference_samples(2e-4, ZRange{0.005, 0.006});
  ASSERT_FALSE(band.empty());
  for (const SurfaceSample& s : band) ASSERT_TRUE(s.position.z() >= 0.005 && s.position.z() <= 0.006);
  // As a PLY file.
  test::TemporaryDirectory dir;
  const PointCloud cloud = scene.reference_cloud(5e-4, ZRange{0.0, 0.002});
  write_ply(dir.file("screw.ply"), cloud);
  const PointCloud back = read_ply_cloud(dir.file("screw.ply"));
  ASSERT_EQ(back.size(), cloud.size());
  EXPECT_TRUE(back.has_normals());
}

}  // namespace
}  // namespace sls::sim
