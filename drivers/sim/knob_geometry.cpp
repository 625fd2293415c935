#include "drivers/sim/knob_geometry.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace sls::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kInf = std::numeric_limits<double>::infinity();
using Vec3 = Eigen::Vector3d;

}  // namespace

double angular_distance_to_arc(double theta, double lo, double hi) {
  double d = std::fmod(theta - lo, 2.0 * kPi);
  if (d < 0.0) d += 2.0 * kPi;
  const double width = hi - lo;
  if (d <= width) return 0.0;
  return std::min(d - width, 2.0 * kPi - d);
}

double knob_patch_tri(int j, double u) {
  return (j % 2 == 0) ? 2.0 * (u - 0.5 * j) : 2.0 * (0.5 * (j + 1) - u);
}

KnobPatchPoint knob_patch_eval(const KnurledKnobT<double>& k, int j, double u, double z) {
  const double n = k.teeth;
  const double ru = (j % 2 == 0) ? -2.0 * k.depth : 2.0 * k.depth;  // dR/du
  const double R = k.outer_radius - k.depth * knob_patch_tri(j, u);
  const double sw = std::sin(k.omega * z), cw = std::cos(k.omega * z);
  const double theta = (2.0 * kPi * u - k.wave_phase * sw) / n;
  const double tu = 2.0 * kPi / n;
  const double tz = -k.wave_phase * k.omega * cw / n;
  const double tzz = k.wave_phase * k.omega * k.omega * sw / n;
  const Vec3 er(std::cos(theta), std::sin(theta), 0.0);
  const Vec3 et(-er.y(), er.x(), 0.0);
  const Vec3 ez(0.0, 0.0, 1.0);
  KnobPatchPoint q;
  q.s = R * er + z * ez;
  q.su = ru * er + R * tu * et;
  q.sz = R * tz * et + ez;
  q.suu = -R * tu * tu * er + 2.0 * ru * tu * et;
  q.suz = ru * tz * et - R * tu * tz * er;
  q.szz = R * tzz * et - R * tz * tz * er;
  return q;
}

namespace {

// Minimises |p - S(u, z)|^2 over patch j from a seed: projected Newton with an active set
// for the box (so minima on a crease or cap edge are found too), Gauss-Newton where the
// Hessian is not positive definite, Armijo backtracking. Returns the squared distance.
double knob_patch_distance2(const KnurledKnobT<double>& k, int j, const Vec3& p, double u_seed, double z_seed) {
  const double lo[2] = {0.5 * j, 0.0};
  const double hi[2] = {0.5 * (j + 1), k.height};
  double x[2] = {std::clamp(u_seed, lo[0], hi[0]), std::clamp(z_seed, lo[1], hi[1])};
  auto dist2 = [&](const double* y) {
    const double R = k.outer_radius - k.depth * knob_patch_tri(j, y[0]);
    const double theta = (2.0 * kPi * y[0] - k.wave_phase * std::sin(k.omega * y[1])) / k.teeth;
    return (Vec3(R * std::cos(theta), R * std::sin(theta), y[1]) - p).squaredNorm();
  };
  double D = dist2(x);
  for (int it = 0; it < 100; ++it) {
    const KnobPatchPoint q = knob_patch_eval(k, j, x[0], x[1]);
    const Vec3 r = q.s - p;
    const double g[2] = {2.0 * r.dot(q.su), 2.0 * r.dot(q.sz)};
    const double gn[3] = {2.0 * q.su.dot(q.su), 2.0 * q.su.dot(q.sz), 2.0 * q.sz.dot(q.sz)};
    double h[3] = {gn[0] + 2.0 * r.dot(q.suu), gn[1] + 2.0 * r.dot(q.suz), gn[2] + 2.0 * r.dot(q.szz)};
    bool free_var[2];
    for (int i = 0; i < 2; ++i) free_var[i] = !((x[i] <= lo[i] && g[i] > 0.0) || (x[i] >= hi[i] && g[i] < 0.0));
    double dx[2] = {0.0, 0.0};
    if (free_var[0] && free_var[1]) {
      double det = h[0] * h[2] - h[1] * h[1];
      if (!(h[0] > 0.0 && det > 0.0)) {
        std::copy(gn, gn + 3, h);
        det = h[0] * h[2] - h[1] * h[1];
      }
      if (!(det > 0.0)) break;
      dx[0] = -(h[2] * g[0] - h[1] * g[1]) / det;
      dx[1] = -(-h[1] * g[0] + h[0] * g[1]) / det;
    } else if (free_var[0] || free_var[1]) {
      const int i = free_var[0] ? 0 : 1;
      const double hii = h[i == 0 ? 0 : 2] > 0.0 ? h[i == 0 ? 0 : 2] : gn[i == 0 ? 0 : 2];
      dx[i] = -g[i] / hii;
    } else {
      break;  // a corner satisfying the optimality conditions
    }
    double alpha = 1.0;
    bool accepted = false;
    double y[2];
    double Dy = D;
    for (int ls = 0; ls < 60; ++ls) {
      for (int i = 0; i < 2; ++i) y[i] = std::clamp(x[i] + alpha * dx[i], lo[i], hi[i]);
      Dy = dist2(y);
      const double decrease = g[0] * (y[0] - x[0]) + g[1] * (y[1] - x[1]);
      if (Dy <= D + 1e-4 * decrease) {
        accepted = true;
        break;
      }
      alpha *= 0.5;
    }
    if (!accepted) break;
    const double moved = q.su.norm() * std::abs(y[0] - x[0]) + std::abs(y[1] - x[1]);
    x[0] = y[0];
    x[1] = y[1];
    D = Dy;
    if (moved < 1e-16) break;
  }
  return D;
}

}  // namespace

double knob_signed_distance(const KnurledKnobT<double>& k, const Vec3& p) {
  const double rho = std::hypot(p.x(), p.y());
  const double theta = std::atan2(p.y(), p.x());
  const double H = k.height;
  const double zc = std::clamp(p.z(), 0.0, H);
  const bool inside = p.z() >= 0.0 && p.z() <= H && rho <= knurled_knob_radius(k, theta, p.z());
  double best2 = kInf;
  // Cap interiors: the foot of the perpendicular lies on the cap.
  if (rho <= knurled_knob_radius(k, theta, 0.0)) best2 = std::min(best2, p.z() * p.z());
  if (rho <= knurled_knob_radius(k, theta, H)) best2 = std::min(best2, (p.z() - H) * (p.z() - H));
  // Side patches, outwards from the point's own half tooth.
  const double u_p = knurled_knob_phase(k, theta, zc);
  const int j_p = static_cast<int>(std::floor(2.0 * u_p));
  const double n = k.teeth;
  const double dz_out = std::max({0.0, -p.z(), p.z() - H});
  // Patch j spans theta in [(pi j - w(z)) / N, (pi (j+1) - w(z)) / N], w = A sin(omega z). A
  // surface point closer than the best distance so far lies within |z' - z| < best, so only
  // the range of w over that window widens the patch's arc (a tighter bound, fewer patches).
  double w_lo = -std::abs(k.wave_phase), w_hi = std::abs(k.wave_phase);
  auto update_wave_window = [&]() {
    const double b = std::sqrt(best2);
    const double z0 = std::max(0.0, p.z() - b), z1 = std::min(H, p.z() + b);
    if (!(z0 <= z1) || !std::isfinite(b)) return;
    if ((z1 - z0) * k.omega >= 2.0 * kPi) return;
    // Range of sin over [omega z0, omega z1]: the ends plus any interior extremum.
    const double x0 = k.omega * z0, x1 = k.omega * z1;
    double lo = std::min(std::sin(x0), std::sin(x1)), hi = std::max(std::sin(x0), std::sin(x1));
    for (double c = std::ceil((x0 - 0.5 * kPi) / kPi); 0.5 * kPi + c * kPi <= x1; c += 1.0) {
      const double v = std::sin(0.5 * kPi + c * kPi);
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
    const double a0 = k.wave_phase * lo, a1 = k.wave_phase * hi;
    w_lo = std::min(a0, a1);
    w_hi = std::max(a0, a1);
  };
  auto arc_lo = [&](int j) { return (kPi * j - w_hi) / n; };
  auto arc_hi = [&](int j) { return (kPi * (j + 1) - w_lo) / n; };
  auto bound2 = [&](double delta) {
    const double b = detail::annulus_angle_bound(rho, k.root_radius, k.outer_radius, std::min(delta, kPi));
    return b * b + dz_out * dz_out;
  };
  // Pass 0 seeds each patch at the point's own (u, z): near the surface (where ground truth
  // matters) the squared distance on a patch has one minimum there. Far from it (beyond
  // kFar) a patch may hold several minima, so pass 1 repeats the search from a grid of seeds.
  constexpr double kFar = 0.3e-3;
  const int total = 2 * k.teeth;
  for (int pass = 0; pass < 2; ++pass) {
    if (pass == 1 && best2 <= kFar * kFar) break;
    auto visit = [&](int j) {
      if (bound2(angular_distance_to_arc(theta, arc_lo(j), arc_hi(j))) >= best2) return;
      double d2 = knob_patch_distance2(k, j, p, u_p, zc);
      if (pass == 1) {
        for (int iz = 0; iz <= 4; ++iz) {
          for (int iu = 0; iu <= 2; ++iu) {
            d2 = std::min(d2, knob_patch_distance2(k, j, p, 0.5 * j + 0.25 * iu, 0.25 * iz * H));
          }
        }
      }
      if (d2 < best2) {
        best2 = d2;
        update_wave_window();
      }
    };
    update_wave_window();
    for (int m = 0; m <= total / 2 + 1; ++m) {
      visit(j_p + m);
      if (m > 0) visit(j_p - m);
      // Every unvisited patch lies beyond the next patch on either side.
      const double delta =
          std::min(std::max(0.0, arc_lo(j_p + m + 1) - theta), std::max(0.0, theta - arc_hi(j_p - m - 1)));
      if (bound2(delta) >= best2) break;
    }
  }
  const double d = std::sqrt(best2);
  return inside ? -d : d;
}

}  // namespace sls::sim
