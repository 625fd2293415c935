#include "drivers/sim/scene.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "drivers/sim/knob_geometry.h"
#include "sdk/core/error.h"

namespace sls::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kInf = std::numeric_limits<double>::infinity();
using Vec3 = Eigen::Vector3d;
using Json = nlohmann::ordered_json;

Vec3 to_eigen(const Vec3d& v) { return {v.x, v.y, v.z}; }
Vec3d to_vec(const Vec3& v) { return {v.x(), v.y(), v.z()}; }

double point_segment_distance(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 e = b - a;
  const double len2 = e.squaredNorm();
  const double u = len2 > 0.0 ? std::clamp((p - a).dot(e) / len2, 0.0, 1.0) : 0.0;
  return (p - (a + u * e)).norm();
}

// ---------------------------------------------------------------------------------------
// Crease index: segments of the crease polylines in an (angle x z) grid. A query visits the
// angle bins outwards from the point's angle and stops once no unvisited bin can hold a
// closer crease (detail::annulus_angle_bound with the creases' radial range).
class CreaseIndex {
 public:
  void build(const std::vector<Polyline>& polylines, int angle_bins, int z_bins) {
    segments_.clear();
    for (const Polyline& line : polylines) {
      for (std::size_t i = 0; i + 1 < line.size(); ++i) segments_.push_back({line[i], line[i + 1]});
    }
    if (segments_.empty()) return;
    angle_bins_ = std::max(angle_bins, 1);
    z_bins_ = std::max(z_bins, 1);
    bin_width_ = 2.0 * kPi / angle_bins_;
    rho_lo_ = kInf;
    rho_hi_ = 0.0;
    z_lo_ = kInf;
    z_hi_ = -kInf;
    for (const Segment& s : segments_) {
      // The chord's closest approach to the axis bounds the creases' radii from below.
      const Vec3 a2(s.a.x(), s.a.y(), 0.0), b2(s.b.x(), s.b.y(), 0.0);
      rho_lo_ = std::min(rho_lo_, point_segment_distance(Vec3::Zero(), a2, b2));
      rho_hi_ = std::max({rho_hi_, a2.norm(), b2.norm()});
      z_lo_ = std::min({z_lo_, s.a.z(), s.b.z()});
      z_hi_ = std::max({z_hi_, s.a.z(), s.b.z()});
    }
    z_step_ = std::max(z_hi_ - z_lo_, 1e-9) / z_bins_;
    cells_.assign(static_cast<std::size_t>(angle_bins_ * z_bins_), {});
    for (std::size_t i = 0; i < segments_.size(); ++i) {
      const Segment& s = segments_[i];
      const double ta = std::atan2(s.a.y(), s.a.x());
      double dt = std::atan2(s.b.y(), s.b.x()) - ta;
      if (dt > kPi) dt -= 2.0 * kPi;
      if (dt < -kPi) dt += 2.0 * kPi;
      const double lo = std::min(ta, ta + dt), hi = std::max(ta, ta + dt);
      const int b_lo = static_cast<int>(std::floor((lo + kPi) / bin_width_));
      const int b_hi = static_cast<int>(std::floor((hi + kPi) / bin_width_));
      const int z_lo = z_bin(std::min(s.a.z(), s.b.z()));
      const int z_hi = z_bin(std::max(s.a.z(), s.b.z()));
      for (int b = b_lo; b <= b_hi; ++b) {
        const int bw = detail::wrap_index<double>(b, angle_bins_);
        for (int z = z_lo; z <= z_hi; ++z) cells_[cell(bw, z)].push_back(static_cast<int>(i));
      }
    }
  }

  double distance(const Vec3& p) const {
    if (segments_.empty()) return kInf;
    const double theta = std::atan2(p.y(), p.x());
    const double rho = std::hypot(p.x(), p.y());
    const int b0 = detail::wrap_index<double>(static_cast<int>(std::floor((theta + kPi) / bin_width_)), angle_bins_);
    const double dz_out = std::max({0.0, z_lo_ - p.z(), p.z() - z_hi_});
    double best = kInf;
    const int max_m = angle_bins_ / 2 + 1;
    for (int m = 0; m <= max_m; ++m) {
      for (int side = 0; side < (m == 0 ? 1 : 2); ++side) {
        const int b = detail::wrap_index<double>(side == 0 ? b0 + m : b0 - m, angle_bins_);
        if (m > 0 && 2 * m == angle_bins_ && side == 1) continue;  // the same bin twice
        const double bin_lo = -kPi + b * bin_width_;
        const double delta = angular_distance_to_arc(theta, bin_lo, bin_lo + bin_width_);
        const double bh = detail::annulus_angle_bound(rho, rho_lo_, rho_hi_, delta);
        if (bh >= best) continue;
        for (int z = 0; z < z_bins_; ++z) {
          const double c_lo = z_lo_ + z * z_step_;
          const double dz = std::max({0.0, c_lo - p.z(), p.z() - (c_lo + z_step_)});
          if (bh * bh + dz * dz >= best * best) continue;
          for (int i : cells_[cell(b, z)]) {
            best = std::min(best, point_segment_distance(p, segments_[static_cast<std::size_t>(i)].a,
                                                         segments_[static_cast<std::size_t>(i)].b));
          }
        }
      }
      // Unvisited bins are at least m bin widths away in angle.
      const double bound = detail::annulus_angle_bound(rho, rho_lo_, rho_hi_, std::min(m * bin_width_, kPi));
      if (bound * bound + dz_out * dz_out >= best * best) break;
    }
    return best;
  }

 private:
  struct Segment {
    Vec3 a, b;
  };
  int z_bin(double z) const {
    return std::clamp(static_cast<int>(std::floor((z - z_lo_) / z_step_)), 0, z_bins_ - 1);
  }
  std::size_t cell(int b, int z) const { return static_cast<std::size_t>(b * z_bins_ + z); }

  std::vector<Segment> segments_;
  std::vector<std::vector<int>> cells_;
  int angle_bins_ = 0, z_bins_ = 0;
  double bin_width_ = 0.0, z_step_ = 0.0;
  double rho_lo_ = 0.0, rho_hi_ = 0.0, z_lo_ = 0.0, z_hi_ = 0.0;
};

// ---------------------------------------------------------------------------------------
double sheet_signed_distance(double half_x, double half_y, const Vec3& p) {
  if (!(half_x > 0.0 && half_y > 0.0)) return p.z();
  const double dx = std::max(std::abs(p.x()) - half_x, 0.0);
  const double dy = std::max(std::abs(p.y()) - half_y, 0.0);
  const double d = std::sqrt(dx * dx + dy * dy + p.z() * p.z());
  return p.z() < 0.0 ? -d : d;
}

void check(bool ok, const char* what) {
  if (!ok) throw_error(ErrorCode::kInvalidArgument, "invalid scene parameter: {}", what);
}
void check(bool ok, const std::string& what) { check(ok, what.c_str()); }

void check_albedo(const AlbedoT<double>& a) {
  check(std::isfinite(a.base) && a.base >= 0.0 && a.base <= 1.0, "albedo base must lie in [0, 1]");
  check(std::isfinite(a.amplitude) && a.amplitude >= 0.0 && a.amplitude <= 1.0, "albedo amplitude must lie in [0, 1]");
  check(std::isfinite(a.period) && a.period > 0.0, "albedo period must be positive");
}

Json albedo_json(const AlbedoT<double>& a) {
  return Json{{"base", a.base}, {"amplitude", a.amplitude}, {"period_m", a.period}};
}

// Scenes sample their sheets over this square when they are unbounded.
constexpr double kUnboundedSampleHalfExtent = 0.01;

void add_grid_samples(double x0, double x1, double y0, double y1, double z, double nz, double spacing, int part,
                      const std::function<bool(double, double)>& keep, std::vector<SurfaceSample>* out) {
  const auto nx = static_cast<long>(std::ceil((x1 - x0) / spacing));
  const auto ny = static_cast<long>(std::ceil((y1 - y0) / spacing));
  const double sx = (x1 - x0) / static_cast<double>(nx), sy = (y1 - y0) / static_cast<double>(ny);
  for (long j = 0; j < ny; ++j) {
    for (long i = 0; i < nx; ++i) {
      const double x = x0 + (static_cast<double>(i) + 0.5) * sx;
      const double y = y0 + (static_cast<double>(j) + 0.5) * sy;
      if (!keep(x, y)) continue;
      out->push_back({Vec3(x, y, z), Vec3(0.0, 0.0, nz), part});
    }
  }
}

void check_sample_count(double estimate) {
  if (!(estimate < 5e8)) {
    throw_error(ErrorCode::kOutOfMemory, "reference sampling would give {:.3g} points; use a larger spacing", estimate);
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------
struct Scene::Impl {
  std::string name;
  SceneShapeT<double> shape;
  Json parameters;
  Json derived;
  std::vector<Polyline> creases;
  CreaseIndex crease_index;
};

const std::string& Scene::name() const { return impl_->name; }
SceneKind Scene::kind() const { return impl_->shape.kind; }
const SceneShapeT<double>& Scene::shape() const { return impl_->shape; }
SceneShapeT<float> Scene::shape_float() const { return impl_->shape.cast<float>(); }

bool Scene::intersect(const Ray& ray, double t_min, double t_max, Hit* hit) const {
  return sls::sim::intersect(impl_->shape, ray, t_min, t_max, hit);
}

double Scene::signed_distance(const Eigen::Vector3d& p) const {
  const SceneShapeT<double>& s = impl_->shape;
  switch (s.kind) {
    case SceneKind::kPlane: return sheet_signed_distance(s.plane.half_extent_x, s.plane.half_extent_y, p);
    case SceneKind::kChessboard:
      return sheet_signed_distance(s.chessboard.half_width(), s.chessboard.half_height(), p);
    case SceneKind::kSphere: return (p - to_eigen(s.sphere.center)).norm() - s.sphere.radius;
    case SceneKind::kKnurledScrew: return knurled_screw_sdf(s.screw, to_vec(p));
    case SceneKind::kKnurledKnob: return knob_signed_distance(s.knob, p);
  }
  return kInf;
}

const std::vector<Polyline>& Scene::creases() const { return impl_->creases; }

double Scene::distance_to_creases(const Eigen::Vector3d& p) const { return impl_->crease_index.distance(p); }

std::vector<SurfaceSample> Scene::reference_samples(double spacing, const ZRange& z_range) const {
  if (!(spacing > 0.0 && std::isfinite(spacing))) {
    throw_error(ErrorCode::kInvalidArgument, "reference sampling spacing must be positive, got {}", spacing);
  }
  const SceneShapeT<double>& s = impl_->shape;
  std::vector<SurfaceSample> out;
  auto in_range = [&](double z) { return z >= z_range.min && z <= z_range.max; };
  auto all = [](double, double) { return true; };
  switch (s.kind) {
    case SceneKind::kPlane:
    case SceneKind::kChessboard: {
      if (!in_range(0.0)) break;
      double hx = s.kind == SceneKind::kPlane ? s.plane.half_extent_x : s.chessboard.half_width();
      double hy = s.kind == SceneKind::kPlane ? s.plane.half_extent_y : s.chessboard.half_height();
      if (!(hx > 0.0 && hy > 0.0)) hx = hy = kUnboundedSampleHalfExtent;
      check_sample_count(4.0 * hx * hy / (spacing * spacing));
      add_grid_samples(-hx, hx, -hy, hy, 0.0, 1.0, spacing, kPartSide, all, &out);
      break;
    }
    case SceneKind::kSphere: {
      // A Fibonacci lattice: near-uniform, every point exactly at the radius.
      const double r = s.sphere.radius;
      const double count = 4.0 * kPi * r * r / (spacing * spacing);
      check_sample_count(count);
      const auto n = static_cast<long>(std::max(1.0, std::ceil(count)));
      const double golden = kPi * (3.0 - std::sqrt(5.0));
      for (long i = 0; i < n; ++i) {
        const double z = 1.0 - (2.0 * static_cast<double>(i) + 1.0) / static_cast<double>(n);
        const double rr = std::sqrt(std::max(0.0, 1.0 - z * z));
        const double phi = golden * static_cast<double>(i);
        const Vec3 normal(rr * std::cos(phi), rr * std::sin(phi), z);
        const Vec3 pos = to_eigen(s.sphere.center) + r * normal;
        if (in_range(pos.z())) out.push_back({pos, normal, kPartSide});
      }
      break;
    }
    case SceneKind::kKnurledScrew: {
      const KnurledScrewT<double>& k = s.screw;
      const double R = k.ridge_radius, H = k.height;
      const double flank = std::hypot(R - k.root_x, k.root_y);
      check_sample_count(2.0 * k.teeth * flank * H / (spacing * spacing) + 2.0 * kPi * R * R / (spacing * spacing));
      const auto nl = static_cast<long>(std::ceil(flank / spacing));
      const auto nz = static_cast<long>(std::ceil(H / spacing));
      for (int t = 0; t < k.teeth; ++t) {
        const double phi = t * k.sector;
        const double c = std::cos(phi), sn = std::sin(phi);
        for (int side = 0; side < 2; ++side) {
          const double qy = side == 0 ? k.root_y : -k.root_y;
          const double ny = side == 0 ? k.flank_ny : -k.flank_ny;
          const Vec3 normal(c * k.flank_nx - sn * ny, sn * k.flank_nx + c * ny, 0.0);
          for (long i = 0; i < nl; ++i) {
            const double f = (static_cast<double>(i) + 0.5) / static_cast<double>(nl);
            const double lx = R + f * (k.root_x - R), ly = f * qy;
            const double x = c * lx - sn * ly, y = sn * lx + c * ly;
            for (long j = 0; j < nz; ++j) {
              const double z = (static_cast<double>(j) + 0.5) * H / static_cast<double>(nz);
              if (in_range(z)) out.push_back({Vec3(x, y, z), normal, kPartSide});
            }
          }
        }
      }
      auto inside = [&](double x, double y) { return knurled_screw_contains_2d(k, x, y); };
      if (in_range(0.0)) add_grid_samples(-R, R, -R, R, 0.0, -1.0, spacing, kPartBottomCap, inside, &out);
      if (in_range(H)) add_grid_samples(-R, R, -R, R, H, 1.0, spacing, kPartTopCap, inside, &out);
      break;
    }
    case SceneKind::kKnurledKnob: {
      const KnurledKnobT<double>& k = s.knob;
      const double R = k.outer_radius, H = k.height;
      // Arc length per unit u on a flank, at most sqrt((2 depth)^2 + (R 2 pi / N)^2).
      const double su = std::hypot(2.0 * k.depth, R * 2.0 * kPi / k.teeth);
      check_sample_count(k.teeth * su * H / (spacing * spacing) + 2.0 * kPi * R * R / (spacing * spacing));
      const auto nu = static_cast<long>(std::ceil(0.5 * su / spacing));
      const auto nz = static_cast<long>(std::ceil(H / spacing));
      for (long j = 0; j < nz; ++j) {
        const double z = (static_cast<double>(j) + 0.5) * H / static_cast<double>(nz);
        if (!in_range(z)) continue;
        for (int patch = 0; patch < 2 * k.teeth; ++patch) {
          const double sigma = patch % 2 == 0 ? 1.0 : -1.0;
          for (long i = 0; i < nu; ++i) {
            const double u = 0.5 * patch + 0.5 * (static_cast<double>(i) + 0.5) / static_cast<double>(nu);
            const KnobPatchPoint q = knob_patch_eval(k, patch, u, z);
            // Outward normal = grad(rho - R) on this patch.
            const double rho = std::hypot(q.s.x(), q.s.y());
            const Vec3 er(q.s.x() / rho, q.s.y() / rho, 0.0), et(-er.y(), er.x(), 0.0);
            const Vec3 g = er + (sigma * k.depth * k.teeth / (kPi * rho)) * et +
                           Vec3(0.0, 0.0, sigma * k.depth * k.wave_phase * k.omega * std::cos(k.omega * z) / kPi);
            out.push_back({q.s, g.normalized(), kPartSide});
          }
        }
      }
      auto inside_at = [&](double zc) {
        return [&k, zc](double x, double y) {
          return std::hypot(x, y) < knurled_knob_radius(k, std::atan2(y, x), zc);
        };
      };
      if (in_range(0.0)) add_grid_samples(-R, R, -R, R, 0.0, -1.0, spacing, kPartBottomCap, inside_at(0.0), &out);
      if (in_range(H)) add_grid_samples(-R, R, -R, R, H, 1.0, spacing, kPartTopCap, inside_at(H), &out);
      break;
    }
  }
  return out;
}

PointCloud Scene::reference_cloud(double spacing, const ZRange& z_range) const {
  const std::vector<SurfaceSample> samples = reference_samples(spacing, z_range);
  PointCloud cloud;
  cloud.positions.reserve(samples.size());
  cloud.normals.reserve(samples.size());
  for (const SurfaceSample& s : samples) {
    cloud.positions.push_back(s.position.cast<float>());
    cloud.normals.push_back(s.normal.cast<float>());
  }
  return cloud;
}

std::vector<Eigen::Vector3d> Scene::chessboard_corners() const {
  if (kind() != SceneKind::kChessboard) {
    throw_error(ErrorCode::kInvalidArgument, "scene '{}' is not a chessboard", name());
  }
  const ChessboardT<double>& c = impl_->shape.chessboard;
  std::vector<Eigen::Vector3d> corners;
  const double x0 = -0.5 * c.squares_x * c.square, y0 = -0.5 * c.squares_y * c.square;
  for (int j = 1; j < c.squares_y; ++j) {
    for (int i = 1; i < c.squares_x; ++i) corners.emplace_back(x0 + i * c.square, y0 + j * c.square, 0.0);
  }
  return corners;
}

std::string Scene::to_json() const {
  Json j;
  j["name"] = impl_->name;
  j["units"] = "m";
  const bool knurled = kind() == SceneKind::kKnurledScrew || kind() == SceneKind::kKnurledKnob;
  j["frame"] = knurled ? "object frame: z = the object's axis (turntable axis), origin on the axis at the bottom "
                         "cap, the solid spans 0 <= z <= height"
                       : (kind() == SceneKind::kSphere ? "object frame: the sphere's centre is given in it"
                                                      : "object frame: the sheet z = 0, normal +z, centred on "
                                                        "the origin");
  j["parameters"] = impl_->parameters;
  j["derived"] = impl_->derived;
  return j.dump(2);
}

// ---------------------------------------------------------------------------------------
int knurl_teeth(double diameter, double nominal_pitch) {
  check(diameter > 0.0 && std::isfinite(diameter), "diameter must be positive");
  check(nominal_pitch > 0.0 && std::isfinite(nominal_pitch), "pitch must be positive");
  const double n = std::round(kPi * diameter / nominal_pitch);
  check(n >= 3.0 && n <= 100000.0, "diameter / pitch must give 3 to 100000 teeth");
  return static_cast<int>(n);
}

double knurl_root_radius(double ridge_radius, int teeth, double groove_angle_rad) {
  check(groove_angle_rad > 0.0 && groove_angle_rad < kPi, "groove angle must lie in (0, 180) degrees");
  const double alpha = kPi / teeth;
  const double r = ridge_radius * (std::cos(alpha) - std::sin(alpha) / std::tan(0.5 * groove_angle_rad));
  check(r > 0.0, "groove angle too small for this tooth count: the roots would pass the axis");
  return r;
}

namespace {

constexpr int patches_per_bin = 1;  // crease grid: one angle bin per half tooth

std::vector<Polyline> screw_creases(const KnurledScrewT<double>& k) {
  std::vector<Polyline> lines;
  for (int t = 0; t < k.teeth; ++t) {
    const double a = t * k.sector, b = (t + 0.5) * k.sector;
    const double R = k.ridge_radius, r = k.root_radius;
    lines.push_back({Vec3(R * std::cos(a), R * std::sin(a), 0.0), Vec3(R * std::cos(a), R * std::sin(a), k.height)});
    lines.push_back({Vec3(r * std::cos(b), r * std::sin(b), 0.0), Vec3(r * std::cos(b), r * std::sin(b), k.height)});
  }
  for (double z : {0.0, k.height}) {
    Polyline outline;
    for (int v = 0; v <= 2 * k.teeth; ++v) {
      const double radius = v % 2 == 0 ? k.ridge_radius : k.root_radius;
      const double a = 0.5 * v * k.sector;
      outline.emplace_back(radius * std::cos(a), radius * std::sin(a), z);
    }
    lines.push_back(std::move(outline));
  }
  return lines;
}

// Sampling step so a polyline stays within `tolerance` of its curve: the linear interpolant of
// a C2 curve deviates by at most h^2/8 max|C''|.
int curve_segments(double length_in_parameter, double max_second_derivative, double tolerance) {
  const double h = std::sqrt(8.0 * tolerance / std::max(max_second_derivative, 1e-300));
  return std::max(1, static_cast<int>(std::ceil(length_in_parameter / h)));
}

constexpr double kCreaseTolerance = 0.5e-7;  // half the 0.1 um the brief allows

std::vector<Polyline> knob_creases(const KnurledKnobT<double>& k) {
  std::vector<Polyline> lines;
  const double n = k.teeth, a = std::abs(k.wave_phase), w = k.omega, H = k.height;
  // Ridge (u = t) and groove (u = t + 1/2) curves over z: |C''| <= rho (|theta''| + theta'^2).
  for (int t = 0; t < k.teeth; ++t) {
    for (int g = 0; g < 2; ++g) {
      const double u = t + 0.5 * g;
      const double rho = g == 0 ? k.outer_radius : k.root_radius;
      const int m = curve_segments(H, rho * (a * w * w / n + (a * w / n) * (a * w / n)), kCreaseTolerance);
      Polyline line;
      for (int i = 0; i <= m; ++i) {
        const double z = H * i / m;
        const double theta = (2.0 * kPi * u - k.wave_phase * std::sin(w * z)) / n;
        line.emplace_back(rho * std::cos(theta), rho * std::sin(theta), z);
      }
      lines.push_back(std::move(line));
    }
  }
  // Cap outlines: per flank rho is linear in u: |C''| <= 2 |rho_u| theta_u + rho theta_u^2.
  const double tu = 2.0 * kPi / n;
  const int m = curve_segments(0.5, 2.0 * (2.0 * k.depth) * tu + k.outer_radius * tu * tu, kCreaseTolerance);
  for (double z : {0.0, H}) {
    Polyline outline;
    const double shift = k.wave_phase * std::sin(w * z);
    for (int j = 0; j < 2 * k.teeth; ++j) {
      for (int i = (j == 0 ? 0 : 1); i <= m; ++i) {
        const double u = 0.5 * j + 0.5 * i / m;
        const double rho = k.outer_radius - k.depth * knob_patch_tri(j, u);
        const double theta = (2.0 * kPi * u - shift) / n;
        outline.emplace_back(rho * std::cos(theta), rho * std::sin(theta), z);
      }
    }
    lines.push_back(std::move(outline));
  }
  return lines;
}

}  // namespace

Scene make_knurled_screw_scene(const KnurledScrewParameters& p) {
  check(p.height > 0.0 && std::isfinite(p.height), "height must be positive");
  check_albedo(p.albedo);
  const int n = knurl_teeth(p.diameter, p.nominal_pitch);
  const double R = 0.5 * p.diameter;
  const double r = knurl_root_radius(R, n, p.groove_angle_deg * kPi / 180.0);
  auto impl = std::make_shared<Scene::Impl>();
  impl->name = "knurled-screw";
  impl->shape.kind = SceneKind::kKnurledScrew;
  impl->shape.screw = make_knurled_screw(n, R, r, p.height, p.albedo);
  const KnurledScrewT<double>& k = impl->shape.screw;
  impl->parameters = Json{{"diameter_m", p.diameter},
                          {"height_m", p.height},
                          {"nominal_pitch_m", p.nominal_pitch},
                          {"groove_angle_deg", p.groove_angle_deg},
                          {"albedo", albedo_json(p.albedo)}};
  const double ridge_angle = 2.0 * std::atan2(k.root_y, R - k.root_x) * 180.0 / kPi;
  impl->derived = Json{{"teeth", n},
                       {"pitch_m", kPi * p.diameter / n},
                       {"ridge_radius_m", R},
                       {"root_radius_m", r},
                       {"depth_m", R - r},
                       {"ridge_angle_deg", ridge_angle},
                       {"flank_length_m", std::hypot(R - k.root_x, k.root_y)}};
  impl->creases = screw_creases(k);
  impl->crease_index.build(impl->creases, 2 * n * patches_per_bin, std::max(1, static_cast<int>(p.height / 0.5e-3)));
  return Scene(impl);
}

Scene make_knurled_knob_scene(const KnurledKnobParameters& p) {
  check(p.height > 0.0 && std::isfinite(p.height), "height must be positive");
  check(p.wave_length > 0.0 && std::isfinite(p.wave_length), "wave length must be positive");
  check(std::isfinite(p.wave_amplitude_pitches) && std::abs(p.wave_amplitude_pitches) <= 100.0,
        "wave amplitude must be finite (at most 100 pitches)");
  check_albedo(p.albedo);
  const int n = knurl_teeth(p.diameter, p.nominal_pitch);
  const double R = 0.5 * p.diameter;
  const double depth = R - knurl_root_radius(R, n, p.groove_angle_deg * kPi / 180.0);
  const double phase = 2.0 * kPi * p.wave_amplitude_pitches;
  auto impl = std::make_shared<Scene::Impl>();
  impl->name = "knurled-knob";
  impl->shape.kind = SceneKind::kKnurledKnob;
  impl->shape.knob = make_knurled_knob(n, R, depth, p.height, phase, p.wave_length, p.albedo);
  const KnurledKnobT<double>& k = impl->shape.knob;
  impl->parameters = Json{{"diameter_m", p.diameter},
                          {"height_m", p.height},
                          {"nominal_pitch_m", p.nominal_pitch},
                          {"groove_angle_deg", p.groove_angle_deg},
                          {"wave_amplitude_pitches", p.wave_amplitude_pitches},
                          {"wave_length_m", p.wave_length},
                          {"albedo", albedo_json(p.albedo)}};
  impl->derived = Json{{"teeth", n},
                       {"pitch_m", kPi * p.diameter / n},
                       {"outer_radius_m", R},
                       {"root_radius_m", k.root_radius},
                       {"depth_m", depth},
                       {"wave_phase_rad", phase},
                       {"ridge_shift_m", p.wave_amplitude_pitches * kPi * p.diameter / n},
                       {"lipschitz_horizontal", k.lipschitz_horizontal},
                       {"lipschitz_vertical", k.lipschitz_vertical},
                       {"lipschitz_bound",
                        std::sqrt(k.lipschitz_horizontal * k.lipschitz_horizontal +
                                  k.lipschitz_vertical * k.lipschitz_vertical)}};
  impl->creases = knob_creases(k);
  impl->crease_index.build(impl->creases, 2 * n * patches_per_bin, std::max(1, static_cast<int>(p.height / 0.25e-3)));
  return Scene(impl);
}

Scene make_plane_scene(const PlaneParameters& p) {
  check(std::isfinite(p.half_extent_x) && std::isfinite(p.half_extent_y), "plane extent must be finite");
  check(std::isfinite(p.albedo) && p.albedo >= 0.0 && p.albedo <= 1.0, "albedo must lie in [0, 1]");
  auto impl = std::make_shared<Scene::Impl>();
  impl->name = "plane";
  impl->shape.kind = SceneKind::kPlane;
  impl->shape.plane = {p.half_extent_x, p.half_extent_y, p.albedo};
  impl->parameters = Json{{"half_extent_x_m", p.half_extent_x}, {"half_extent_y_m", p.half_extent_y}, {"albedo", p.albedo}};
  impl->derived = Json{{"bounded", p.half_extent_x > 0.0 && p.half_extent_y > 0.0}};
  return Scene(impl);
}

Scene make_sphere_scene(const SphereParameters& p) {
  check(p.radius > 0.0 && std::isfinite(p.radius), "radius must be positive");
  check(p.center.allFinite(), "centre must be finite");
  check(std::isfinite(p.albedo) && p.albedo >= 0.0 && p.albedo <= 1.0, "albedo must lie in [0, 1]");
  auto impl = std::make_shared<Scene::Impl>();
  impl->name = "sphere";
  impl->shape.kind = SceneKind::kSphere;
  impl->shape.sphere = {to_vec(p.center), p.radius, p.albedo};
  impl->parameters = Json{{"center_m", {p.center.x(), p.center.y(), p.center.z()}},
                          {"radius_m", p.radius},
                          {"albedo", p.albedo}};
  impl->derived = Json::object();
  return Scene(impl);
}

Scene make_chessboard_scene(const ChessboardParameters& p) {
  check(p.inner_corners_x >= 1 && p.inner_corners_y >= 1 && p.inner_corners_x < 1000 && p.inner_corners_y < 1000,
        "inner corner counts must lie in [1, 999]");
  check(p.square > 0.0 && std::isfinite(p.square), "square size must be positive");
  check(p.margin >= 0.0 && std::isfinite(p.margin), "margin must be non-negative");
  check(p.albedo_dark >= 0.0 && p.albedo_dark <= 1.0 && p.albedo_light >= 0.0 && p.albedo_light <= 1.0,
        "albedos must lie in [0, 1]");
  auto impl = std::make_shared<Scene::Impl>();
  impl->name = p.is_charuco() ? "charuco" : "chessboard";
  impl->shape.kind = SceneKind::kChessboard;
  impl->shape.chessboard = {p.inner_corners_x + 1, p.inner_corners_y + 1, p.square, p.margin, p.albedo_dark,
                            p.albedo_light};
  ChessboardT<double>& board = impl->shape.chessboard;
  if (p.is_charuco()) {
    const CharucoPattern& t = p.charuco;
    const int squares = board.squares_x * board.squares_y;
    check(squares <= kCharucoMaxSquares, fmt::format("a ChArUco board of {}x{} squares (the simulator renders up to {})",
                                                     board.squares_x, board.squares_y, kCharucoMaxSquares));
    check(t.cells >= 3 && t.cells <= kCharucoMaxCells,
          fmt::format("ChArUco markers of {} cells a side (the simulator renders 3 to {}: markers of up to 6x6 bits)",
                      t.cells, kCharucoMaxCells));
    check(t.marker > 0.0 && t.marker < p.square, "the ChArUco marker must be positive and smaller than its square");
    check(t.dark_square.size() == static_cast<std::size_t>(squares) &&
              t.dark_cells.size() == static_cast<std::size_t>(squares * t.cells * t.cells),
          "the ChArUco table's size does not match its squares and cells");
    board.marker_cells = t.cells;
    board.marker = t.marker;
    // Board frame to sheet: square (I, J) is sheet square (I, squares_y − 1 − J), and a
    // marker's row r (down the board) its row cells − 1 − r (sheet y is up the board).
    for (int j = 0; j < board.squares_y; ++j) {
      for (int i = 0; i < board.squares_x; ++i) {
        const int sheet = j * board.squares_x + i;
        const int square = (board.squares_y - 1 - j) * board.squares_x + i;
        if (t.dark_square[static_cast<std::size_t>(square)] != 0) board.dark_squares[sheet / 32] |= 1u << (sheet % 32);
        for (int r = 0; r < t.cells; ++r) {
          for (int c = 0; c < t.cells; ++c) {
            const std::size_t cell = static_cast<std::size_t>(square * t.cells * t.cells + (t.cells - 1 - r) * t.cells + c);
            if (t.dark_cells[cell] != 0) board.marker_dark[sheet] |= 1ull << (r * t.cells + c);
          }
        }
      }
    }
  }
  const ChessboardT<double>& c = impl->shape.chessboard;
  impl->parameters = Json{{"inner_corners_x", p.inner_corners_x},
                          {"inner_corners_y", p.inner_corners_y},
                          {"square_m", p.square},
                          {"margin_m", p.margin},
                          {"albedo_dark", p.albedo_dark},
                          {"albedo_light", p.albedo_light}};
  if (p.is_charuco()) {
    impl->parameters["charuco"] = Json{{"marker_m", p.charuco.marker},
                                       {"marker_cells", p.charuco.cells},
                                       {"dictionary", p.charuco.dictionary},
                                       {"dark_square", p.charuco.dark_square},
                                       {"dark_cells", p.charuco.dark_cells},
                                       {"frame", "board frame (calibration's): square J * squares_x + I, cell r * cells + c"}};
  }
  impl->derived = Json{{"squares_x", c.squares_x},
                       {"squares_y", c.squares_y},
                       {"board_width_m", 2.0 * c.half_width()},
                       {"board_height_m", 2.0 * c.half_height()}};
  return Scene(impl);
}

std::vector<std::string> scene_names() { return {"knurled-screw", "knurled-knob", "plane", "sphere", "chessboard"}; }

Scene make_scene(const std::string& name) {
  if (name == "knurled-screw") return make_knurled_screw_scene();
  if (name == "knurled-knob") return make_knurled_knob_scene();
  if (name == "plane") return make_plane_scene();
  if (name == "sphere") return make_sphere_scene();
  if (name == "chessboard") return make_chessboard_scene();
  if (name == "charuco") {
    throw_error(ErrorCode::kInvalidArgument,
                "scene 'charuco' needs its markers from OpenCV's dictionary: make it with make_chessboard_scene() and a "
                "CharucoPattern (calib::charuco_pattern; `sls sim --object charuco` does)");
  }
  std::string known;
  for (const std::string& n : scene_names()) known += (known.empty() ? "" : ", ") + n;
  throw_error(ErrorCode::kInvalidArgument, "unknown scene '{}' (known: {})", name, known);
}

}  // namespace sls::sim
