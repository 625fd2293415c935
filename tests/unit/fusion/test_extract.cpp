// Surface extraction (fusion/extract.h): the marching-cubes tables case by case, then
// zero-crossing clouds and meshes of volumes holding the exact truncated SDF of a plane and
// a sphere, in both voxel formats, against the analytic surfaces.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <random>
#include <set>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "fusion/extract.h"
#include "fusion/extract_internal.h"
#include "fusion/extract_shared.h"
#include "fusion/marching_cubes_tables.h"
#include "fusion/volume.h"
#include "sdk/core/error.h"
#include "sdk/core/ply.h"
#include "tests/support/test_support.h"

namespace sls::fusion {
namespace {

constexpr double kPi = 3.14159265358979323846;

// ---------------------------------------------------------------------------------------
// The tables, every case.

Eigen::Vector3d corner_position(int c) { return Eigen::Vector3d(mc::corner_dx(c), mc::corner_dy(c), mc::corner_dz(c)); }
Eigen::Vector3d edge_midpoint(int e) {
  return 0.5 * (corner_position(mc::edge_corner_a(e)) + corner_position(mc::edge_corner_b(e)));
}
bool inside(int cube_case, int c) { return ((cube_case >> c) & 1) != 0; }

std::vector<std::array<int, 3>> case_triangles(int cube_case) {
  std::vector<std::array<int, 3>> triangles;
  int n = 0;
  for (; n < 15 && mc::triangle_edge(cube_case, n) >= 0; n += 3) {
    triangles.push_back({mc::triangle_edge(cube_case, n), mc::triangle_edge(cube_case, n + 1),
                         mc::triangle_edge(cube_case, n + 2)});
  }
  for (; n < 16; ++n) EXPECT_EQ(mc::triangle_edge(cube_case, n), -1) << "case " << cube_case << " entry " << n;
  return triangles;
}

// The cube's faces as corner cycles, the same for the test as for any cell.
constexpr int kFaces[6][4] = {{0, 1, 2, 3}, {4, 5, 6, 7}, {0, 1, 5, 4}, {3, 2, 6, 7}, {0, 3, 7, 4}, {1, 2, 6, 5}};

int edge_between(int a, int b) {
  for (int e = 0; e < 12; ++e) {
    if ((mc::edge_corner_a(e) == a && mc::edge_corner_b(e) == b) ||
        (mc::edge_corner_a(e) == b && mc::edge_corner_b(e) == a)) {
      return e;
    }
  }
  ADD_FAILURE() << "corners " << a << " and " << b << " share no edge";
  return -1;
}

// The boundary segments the face rule prescribes on face f: one segment when two face
// edges cross, one per inside corner when all four do (the ambiguous face).
std::set<std::pair<int, int>> face_rule_segments(int cube_case, int f) {
  std::vector<int> crossing;
  int edges[4];
  for (int n = 0; n < 4; ++n) {
    edges[n] = edge_between(kFaces[f][n], kFaces[f][(n + 1) % 4]);
    if (inside(cube_case, kFaces[f][n]) != inside(cube_case, kFaces[f][(n + 1) % 4])) crossing.push_back(edges[n]);
  }
  std::set<std::pair<int, int>> segments;
  if (crossing.size() == 2) segments.insert(std::minmax(crossing[0], crossing[1]));
  if (crossing.size() == 4) {
    for (int n = 0; n < 4; ++n) {
      if (inside(cube_case, kFaces[f][n])) segments.insert(std::minmax(edges[(n + 3) % 4], edges[n]));
    }
  }
  return segments;
}

bool edge_on_face(int e, int f) {
  int hits = 0;
  for (const int c : kFaces[f]) hits += (c == mc::edge_corner_a(e) || c == mc::edge_corner_b(e)) ? 1 : 0;
  return hits == 2;
}

TEST(MarchingCubesTables, EdgeTableListsTheEdgesWhoseCornersDiffer) {
  for (int cube_case = 0; cube_case < 256; ++cube_case) {
    unsigned expected = 0;
    for (int e = 0; e < 12; ++e) {
      if (inside(cube_case, mc::edge_corner_a(e)) != inside(cube_case, mc::edge_corner_b(e))) expected |= 1u << e;
    }
    EXPECT_EQ(mc::edge_mask(cube_case), expected) << "case " << cube_case;
  }
}

TEST(MarchingCubesTables, EveryCaseIsAClosedOrientedSurfaceThatMatchesTheFaceRule) {
  for (int cube_case = 0; cube_case < 256; ++cube_case) {
    SCOPED_TRACE("case " + std::to_string(cube_case));
    const std::vector<std::array<int, 3>> triangles = case_triangles(cube_case);
    const unsigned mask = mc::edge_mask(cube_case);
    unsigned used = 0;
    std::map<std::pair<int, int>, int> directed;  // (from, to) -> count
    for (const auto& t : triangles) {
      for (int n = 0; n < 3; ++n) {
        ASSERT_TRUE(t[static_cast<std::size_t>(n)] >= 0 && t[static_cast<std::size_t>(n)] < 12);
        ASSERT_NE(mask & (1u << t[static_cast<std::size_t>(n)]), 0u) << "a vertex on an edge with no sign change";
        used |= 1u << t[static_cast<std::size_t>(n)];
        ++directed[{t[static_cast<std::size_t>(n)], t[static_cast<std::size_t>((n + 1) % 3)]}];
      }
      // Counter-clockwise seen from outside: the normal (vertices at edge midpoints) leans
      // the way U grows, from the inside corner to the outside corner of each edge.
      const Eigen::Vector3d a = edge_midpoint(t[0]), b = edge_midpoint(t[1]), c = edge_midpoint(t[2]);
      const Eigen::Vector3d normal = (b - a).cross(c - a);
      Eigen::Vector3d outward = Eigen::Vector3d::Zero();
      for (const int e : t) {
        const int ca = mc::edge_corner_a(e), cb = mc::edge_corner_b(e);
        outward += inside(cube_case, ca) ? corner_position(cb) - corner_position(ca)
                                         : corner_position(ca) - corner_position(cb);
      }
      EXPECT_GT(normal.normalized().dot(outward.normalized()), 0.5);
      // No triangle lies in a cube face (it would be shared with the neighbour's surface).
      for (int f = 0; f < 6; ++f) EXPECT_FALSE(edge_on_face(t[0], f) && edge_on_face(t[1], f) && edge_on_face(t[2], f));
    }
    EXPECT_EQ(used, mask) << "every sign change carries a vertex";
    // Inside the cell every segment is shared by two triangles, once in each direction;
    // segments used once are the boundary on the faces, exactly as the face rule says.
    std::map<int, std::set<std::pair<int, int>>> boundary_by_face;
    for (const auto& [segment, count] : directed) {
      const int reverse = directed.count({segment.second, segment.first}) ? directed.at({segment.second, segment.first}) : 0;
      EXPECT_EQ(count, 1) << "segment " << segment.first << "-" << segment.second << " used twice the same way";
      if (reverse > 0) continue;
      int face = -1;
      for (int f = 0; f < 6; ++f) {
        if (edge_on_face(segment.first, f) && edge_on_face(segment.second, f)) face = f;
      }
      ASSERT_GE(face, 0) << "open segment " << segment.first << "-" << segment.second << " inside the cell";
      boundary_by_face[face].insert(std::minmax(segment.first, segment.second));
    }
    for (int f = 0; f < 6; ++f) EXPECT_EQ(boundary_by_face[f], face_rule_segments(cube_case, f)) << "face " << f;
  }
}

// Two cells side by side along each axis, for every pair of cases whose shared face agrees:
// their boundaries on that face are the same segments run in opposite directions, so the
// surface closes across cells with a consistent orientation.
TEST(MarchingCubesTables, NeighbouringCellsCloseAcrossTheirSharedFace) {
  // Face corners of the low cell (its + face) and of the high cell (its - face), in the same
  // positions.
  const int high_face[3][4] = {{1, 2, 6, 5}, {3, 2, 6, 7}, {4, 5, 6, 7}};
  const int low_face[3][4] = {{0, 3, 7, 4}, {0, 1, 5, 4}, {0, 1, 2, 3}};
  int pairs = 0;
  for (int axis = 0; axis < 3; ++axis) {
    // A cell edge on the shared face, named by the global corners it joins.
    auto global_segments = [](int cube_case, const int face[4]) {
      std::map<int, std::pair<int, int>> edge_to_position;  // cell edge -> position pair on the face
      for (int n = 0; n < 4; ++n) {
        const int e = edge_between(face[n], face[(n + 1) % 4]);
        edge_to_position[e] = std::minmax(n, (n + 1) % 4);
      }
      std::set<std::pair<std::pair<int, int>, std::pair<int, int>>> segments;  // directed, by face positions
      for (const auto& t : case_triangles(cube_case)) {
        for (int n = 0; n < 3; ++n) {
          const int from = t[static_cast<std::size_t>(n)], to = t[static_cast<std::size_t>((n + 1) % 3)];
          if (edge_to_position.count(from) && edge_to_position.count(to)) {
            segments.insert({edge_to_position.at(from), edge_to_position.at(to)});
          }
        }
      }
      return segments;
    };
    for (int low = 0; low < 256; ++low) {
      for (int high = 0; high < 256; ++high) {
        bool agree = true;
        for (int n = 0; n < 4; ++n) agree = agree && inside(low, high_face[axis][n]) == inside(high, low_face[axis][n]);
        if (!agree) continue;
        ++pairs;
        const auto a = global_segments(low, high_face[axis]);
        const auto b = global_segments(high, low_face[axis]);
        std::set<std::pair<std::pair<int, int>, std::pair<int, int>>> b_reversed;
        for (const auto& s : b) b_reversed.insert({s.second, s.first});
        ASSERT_EQ(a, b_reversed) << "axis " << axis << " cases " << low << " | " << high;
      }
    }
  }
  EXPECT_EQ(pairs, 3 * 256 * 16);
}

// ---------------------------------------------------------------------------------------
// Volumes holding exact truncated SDFs.

// A volume turned and moved in the world, so the world transform is exercised too.
VolumeGeometry test_geometry(int n, double voxel_m) {
  VolumeGeometry g;
  g.nx = n;
  g.ny = n + 2;
  g.nz = n + 4;
  g.voxel_size_m = voxel_m;
  const Eigen::Matrix3d rotation = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1.0, 2.0, 3.0).normalized()).toRotationMatrix();
  g.T_world_volume = Pose(rotation, Eigen::Vector3d(0.01, -0.02, 0.005));
  return g;
}

Eigen::Vector3d voxel_world(const VolumeGeometry& g, int i, int j, int k) {
  return g.T_world_volume * (Eigen::Vector3d(i + 0.5, j + 0.5, k + 0.5) * g.voxel_size_m);
}

// U = clamp(sdf / delta, -1, 1) with W = weight where |sdf| < delta, W = 0 elsewhere.
template <typename Sdf>
void fill(Volume* volume, const Sdf& sdf, double delta_m, float weight = 1.0f) {
  const VolumeGeometry& g = volume->geometry();
  const VolumeView view = volume->view();
  for (int k = 0; k < g.nz; ++k) {
    for (int j = 0; j < g.ny; ++j) {
      for (int i = 0; i < g.nx; ++i) {
        const double d = sdf(voxel_world(g, i, j, k));
        const std::size_t index = view.index(i, j, k);
        view.set_u(index, static_cast<float>(std::clamp(d / delta_m, -1.0, 1.0)));
        view.set_w(index, std::fabs(d) < delta_m ? weight : 0.0f);
      }
    }
  }
}

struct Sphere {
  Eigen::Vector3d centre;
  double radius;
  double operator()(const Eigen::Vector3d& p) const { return (p - centre).norm() - radius; }
  Eigen::Vector3d normal(const Eigen::Vector3d& p) const { return (p - centre).normalized(); }
};

struct Plane {
  Eigen::Vector3d normal_world;  // unit
  double offset;                 // normal . p = offset on the plane
  double operator()(const Eigen::Vector3d& p) const { return normal_world.dot(p) - offset; }
};

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / kPi;
}

class Extract : public ::testing::TestWithParam<VoxelFormat> {};

constexpr double kVoxel = 1e-4;  // 100 µm: float positions a centimetre from the origin stay exact to ~1e-5 voxel

// A plane given in the volume frame as z = c + slope * x (grid units, voxel centres at
// integers): the closed-form crossing count is one per z line plus, for x lines, one per
// (j, k) whose centre height z_k lies between the plane's heights at the line's two ends.
void check_plane(VoxelFormat format, double slope, double c) {
  const VolumeGeometry g = test_geometry(24, kVoxel);
  Volume volume(g, format, Device::cpu());
  // Volume-frame plane n_v . x_v = d_v with x_v in metres, then into the world.
  const Eigen::Vector3d n_volume = Eigen::Vector3d(-slope, 0.0, 1.0).normalized();
  const double d_volume = (c + 0.5 - 0.5 * slope) * kVoxel * n_volume.z();  // through grid (0, *, c)
  const Plane plane{g.T_world_volume.rotation() * n_volume,
                    d_volume + (g.T_world_volume.rotation() * n_volume).dot(g.T_world_volume.translation())};
  const double delta = 4.0 * kVoxel;
  fill(&volume, plane, delta);

  const PointCloud cloud = extract_points(volume);
  // Closed form: plane height over grid x is h(i) = c + slope * i (grid units).
  std::size_t expected = static_cast<std::size_t>(g.nx) * static_cast<std::size_t>(g.ny);  // z lines
  if (slope != 0.0) {
    const double h0 = c, h1 = c + slope * (g.nx - 1);
    // x lines at height k cross when h0 <= k < h1 (U >= 0 above the plane; U < 0 below).
    const auto first = static_cast<long>(std::ceil(std::min(h0, h1)));
    const auto last = static_cast<long>(std::ceil(std::max(h0, h1))) - 1;
    expected += static_cast<std::size_t>(std::max(0L, last - first + 1)) * static_cast<std::size_t>(g.ny);
  }
  EXPECT_EQ(cloud.size(), expected);
  ASSERT_TRUE(cloud.has_normals());
  ASSERT_TRUE(cloud.has_confidence());
  const PointProperty* weight = cloud.find_property("weight");
  ASSERT_NE(weight, nullptr);
  double worst_distance = 0.0, worst_angle = 0.0;
  for (std::size_t n = 0; n < cloud.size(); ++n) {
    worst_distance = std::max(worst_distance, std::fabs(plane(cloud.positions[n].cast<double>())));
    worst_angle = std::max(worst_angle, angle_deg(cloud.normals[n].cast<double>(), plane.normal_world));
    EXPECT_EQ(weight->values[n], 1.0f);
  }
  std::printf("plane (%s, slope %.2f): %zu points, worst distance %.2e voxel, worst normal %.3f deg\n",
              voxel_format_name(format), slope, cloud.size(), worst_distance / kVoxel, worst_angle);
  EXPECT_LE(worst_distance, 1e-3 * kVoxel);
  EXPECT_LE(worst_angle, 2.0);
}

TEST_P(Extract, AxisPlaneGivesOnePointPerGridLineOnTheSurface) { check_plane(GetParam(), 0.0, 13.37); }

TEST_P(Extract, TiltedPlaneGivesTheClosedFormCountOnTheSurface) { check_plane(GetParam(), 0.3, 9.61); }

// A sphere of radius 20 voxels, centred in the volume (off the grid).
struct SphereVolume {
  VolumeGeometry geometry;
  Sphere sphere;
  Volume volume;
};

SphereVolume make_sphere_volume(VoxelFormat format, float weight = 1.0f) {
  const VolumeGeometry g = test_geometry(48, kVoxel);
  const Eigen::Vector3d centre_volume = Eigen::Vector3d(24.13, 25.29, 26.41) * kVoxel;
  SphereVolume s{g, Sphere{g.T_world_volume * centre_volume, 20.0 * kVoxel}, Volume(g, format, Device::cpu())};
  fill(&s.volume, s.sphere, 4.0 * kVoxel, weight);
  return s;
}

TEST_P(Extract, SpherePointsLieOnTheSurfaceWithItsNormals) {
  const SphereVolume s = make_sphere_volume(GetParam(), 7.0f);
  const auto start = std::chrono::steady_clock::now();
  const PointCloud cloud = extract_points(s.volume);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  // One crossing per grid line per side, three axes: about 3 * 2 * pi r^2 voxels' worth.
  const double r = 20.0;
  EXPECT_GT(static_cast<double>(cloud.size()), 0.9 * 1.5 * 4.0 * kPi * r * r);
  double worst_distance = 0.0, worst_angle = 0.0;
  for (std::size_t n = 0; n < cloud.size(); ++n) {
    const Eigen::Vector3d p = cloud.positions[n].cast<double>();
    worst_distance = std::max(worst_distance, std::fabs(s.sphere(p)));
    worst_angle = std::max(worst_angle, angle_deg(cloud.normals[n].cast<double>(), s.sphere.normal(p)));
    EXPECT_FLOAT_EQ(cloud.confidence[n], 7.0f / 20.0f);
    EXPECT_EQ(cloud.find_property("weight")->values[n], 7.0f);
  }
  std::printf("sphere r=20 voxels (%s): %zu points in %.1f ms, worst distance %.4f voxel, worst normal %.3f deg\n",
              voxel_format_name(GetParam()), cloud.size(), ms, worst_distance / kVoxel, worst_angle);
  EXPECT_LE(worst_distance, 0.02 * kVoxel);
  EXPECT_LE(worst_angle, 2.0);
}

struct MeshCheck {
  std::size_t boundary_edges = 0;
  std::size_t non_manifold_edges = 0;
  std::size_t same_direction_edges = 0;  // an edge run the same way by two faces: flipped orientation
  long euler = 0;
  double area = 0.0;
};

MeshCheck check_mesh(const TriangleMesh& mesh) {
  std::map<std::pair<std::int32_t, std::int32_t>, int> directed;
  MeshCheck out;
  for (const auto& f : mesh.faces) {
    for (int n = 0; n < 3; ++n) ++directed[{f[static_cast<std::size_t>(n)], f[static_cast<std::size_t>((n + 1) % 3)]}];
    const Eigen::Vector3d a = mesh.vertices.positions[static_cast<std::size_t>(f[0])].cast<double>();
    const Eigen::Vector3d b = mesh.vertices.positions[static_cast<std::size_t>(f[1])].cast<double>();
    const Eigen::Vector3d c = mesh.vertices.positions[static_cast<std::size_t>(f[2])].cast<double>();
    out.area += 0.5 * (b - a).cross(c - a).norm();
  }
  std::size_t edges = 0;
  for (const auto& [edge, count] : directed) {
    const auto reverse = directed.find({edge.second, edge.first});
    const int back = reverse == directed.end() ? 0 : reverse->second;
    if (count > 1) ++out.same_direction_edges;
    if (edge.first < edge.second || back == 0) {
      ++edges;
      const int total = count + back;
      if (total == 1) ++out.boundary_edges;
      if (total > 2) ++out.non_manifold_edges;
    }
  }
  out.euler = static_cast<long>(mesh.vertices.size()) - static_cast<long>(edges) + static_cast<long>(mesh.faces.size());
  return out;
}

TEST_P(Extract, SphereMeshIsWatertightOnTheSurfaceWithTheSphereArea) {
  const SphereVolume s = make_sphere_volume(GetParam());
  const auto start = std::chrono::steady_clock::now();
  const TriangleMesh mesh = extract_mesh(s.volume);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  ASSERT_NO_THROW(mesh.validate());
  ASSERT_GT(mesh.faces.size(), 1000u);
  const MeshCheck check = check_mesh(mesh);
  EXPECT_EQ(check.boundary_edges, 0u);
  EXPECT_EQ(check.non_manifold_edges, 0u);
  EXPECT_EQ(check.same_direction_edges, 0u);
  EXPECT_EQ(check.euler, 2) << "a sphere's V - E + F";
  const double true_area = 4.0 * kPi * s.sphere.radius * s.sphere.radius;
  EXPECT_NEAR(check.area / true_area, 1.0, 0.01);
  double worst_distance = 0.0, worst_normal = 0.0;
  std::size_t inward_faces = 0;
  for (std::size_t n = 0; n < mesh.vertices.size(); ++n) {
    const Eigen::Vector3d p = mesh.vertices.positions[n].cast<double>();
    worst_distance = std::max(worst_distance, std::fabs(s.sphere(p)));
    worst_normal = std::max(worst_normal, angle_deg(mesh.vertices.normals[n].cast<double>(), s.sphere.normal(p)));
  }
  for (const auto& f : mesh.faces) {
    const Eigen::Vector3d a = mesh.vertices.positions[static_cast<std::size_t>(f[0])].cast<double>();
    const Eigen::Vector3d b = mesh.vertices.positions[static_cast<std::size_t>(f[1])].cast<double>();
    const Eigen::Vector3d c = mesh.vertices.positions[static_cast<std::size_t>(f[2])].cast<double>();
    const Eigen::Vector3d normal = (b - a).cross(c - a);
    if (normal.norm() > 0.0 && normal.dot((a + b + c) / 3.0 - s.sphere.centre) <= 0.0) ++inward_faces;
  }
  EXPECT_EQ(inward_faces, 0u) << "faces are counter-clockwise seen from outside";
  EXPECT_LE(worst_distance, 0.02 * kVoxel);
  EXPECT_LE(worst_normal, 2.0);
  std::printf("sphere mesh (%s): %zu vertices, %zu faces in %.1f ms, area %.5f of 4 pi r^2, worst vertex %.4f voxel\n",
              voxel_format_name(GetParam()), mesh.vertices.size(), mesh.faces.size(), ms, check.area / true_area,
              worst_distance / kVoxel);
}

// Noise: every kind of cell, ambiguous faces included, side by side. The mesh must close
// everywhere except on the volume's outer faces, each edge between two faces run once each way.
TEST_P(Extract, RandomFieldMeshIsClosedInsideTheVolume) {
  const VolumeGeometry g = test_geometry(12, kVoxel);
  Volume volume(g, GetParam(), Device::cpu());
  const VolumeView view = volume.view();
  std::uint32_t state = 12345u;
  for (std::size_t n = 0; n < view.voxel_count(); ++n) {
    state = state * 1664525u + 1013904223u;  // LCG: the same field on every platform
    view.set_u(n, static_cast<float>(state >> 8) / 8388608.0f - 1.0f);
    view.set_w(n, 1.0f);
  }
  const TriangleMesh mesh = extract_mesh(volume);
  ASSERT_GT(mesh.faces.size(), 1000u);
  const MeshCheck check = check_mesh(mesh);
  EXPECT_EQ(check.non_manifold_edges, 0u);
  EXPECT_EQ(check.same_direction_edges, 0u);
  // Open edges only where the volume ends: both vertices on an outer face of the grid.
  const Pose T_volume_world = g.T_world_volume.inverse();
  auto on_outer_face = [&](std::int32_t v) {
    const Eigen::Vector3d grid =
        T_volume_world * mesh.vertices.positions[static_cast<std::size_t>(v)].cast<double>() / kVoxel -
        Eigen::Vector3d::Constant(0.5);
    const double counts[3] = {static_cast<double>(g.nx), static_cast<double>(g.ny), static_cast<double>(g.nz)};
    for (int axis = 0; axis < 3; ++axis) {
      if (std::fabs(grid[axis]) < 1e-3 || std::fabs(grid[axis] - (counts[axis] - 1.0)) < 1e-3) return true;
    }
    return false;
  };
  std::map<std::pair<std::int32_t, std::int32_t>, int> undirected;
  for (const auto& f : mesh.faces) {
    for (int n = 0; n < 3; ++n) {
      ++undirected[std::minmax(f[static_cast<std::size_t>(n)], f[static_cast<std::size_t>((n + 1) % 3)])];
    }
  }
  std::size_t open = 0;
  for (const auto& [edge, count] : undirected) {
    if (count != 1) continue;
    ++open;
    EXPECT_TRUE(on_outer_face(edge.first) && on_outer_face(edge.second)) << "a hole inside the volume";
  }
  EXPECT_GT(open, 0u);
}

TEST_P(Extract, MeshVerticesAreTheCloudsPoints) {
  const SphereVolume s = make_sphere_volume(GetParam());
  const PointCloud cloud = extract_points(s.volume);
  const TriangleMesh mesh = extract_mesh(s.volume);
  // Every crossing of this sphere has all its cells observed, so the mesh uses them all.
  ASSERT_EQ(mesh.vertices.size(), cloud.size());
  for (std::size_t n = 0; n < cloud.size(); ++n) {
    ASSERT_EQ(mesh.vertices.positions[n], cloud.positions[n]);
    ASSERT_EQ(mesh.vertices.normals[n], cloud.normals[n]);
  }
  // One pass for both gives the same.
  const ExtractedSurface surface = extract_surface(s.volume);
  EXPECT_EQ(surface.cloud.positions, cloud.positions);
  EXPECT_EQ(surface.cloud.confidence, cloud.confidence);
  EXPECT_EQ(surface.mesh.faces, mesh.faces);
  EXPECT_EQ(surface.mesh.vertices.normals, mesh.vertices.normals);
}

TEST_P(Extract, RegionKeepsExactlyThePointsInsideTheBox) {
  const SphereVolume s = make_sphere_volume(GetParam());
  const PointCloud all = extract_points(s.volume);
  Box box;
  box.min = s.sphere.centre + Eigen::Vector3d(-0.3, -2.0, 0.1) * s.sphere.radius;
  box.max = s.sphere.centre + Eigen::Vector3d(2.0, 0.5, 2.0) * s.sphere.radius;
  const PointCloud part = extract_points(s.volume, &box);
  std::vector<Eigen::Vector3f> expected;
  for (const Eigen::Vector3f& p : all.positions) {
    if (box.contains(p.cast<double>())) expected.push_back(p);
  }
  ASSERT_GT(expected.size(), 100u);
  ASSERT_LT(expected.size(), all.size() / 2);
  EXPECT_EQ(part.positions, expected);
  EXPECT_EQ(part.normals.size(), part.size());
  EXPECT_EQ(part.find_property("weight")->values.size(), part.size());
  // An unbounded box keeps everything; a box away from the volume keeps nothing.
  Box everything;
  everything.min = Eigen::Vector3d::Constant(-HUGE_VAL);
  everything.max = Eigen::Vector3d::Constant(HUGE_VAL);
  EXPECT_EQ(extract_points(s.volume, &everything).positions, all.positions);
  Box far;
  far.min = Eigen::Vector3d::Constant(1.0);
  far.max = Eigen::Vector3d::Constant(2.0);
  EXPECT_TRUE(extract_points(s.volume, &far).empty());
}

TEST_P(Extract, UnobservedVoxelsProduceNothing) {
  SphereVolume s = make_sphere_volume(GetParam());
  const VolumeView view = s.volume.view();
  const VolumeGeometry& g = s.geometry;
  // Forget the half x < 24 (U stays: only W says what was observed).
  for (int k = 0; k < g.nz; ++k) {
    for (int j = 0; j < g.ny; ++j) {
      for (int i = 0; i < 24; ++i) view.set_w(view.index(i, j, k), 0.0f);
    }
  }
  const Pose T_volume_world = g.T_world_volume.inverse();
  const PointCloud cloud = extract_points(s.volume);
  ASSERT_GT(cloud.size(), 1000u);
  for (const Eigen::Vector3f& p : cloud.positions) {
    // Crossings only on edges between observed voxels: x >= the centre of voxel 24.
    ASSERT_GE((T_volume_world * p.cast<double>()).x() / kVoxel, 24.5 - 1e-4);
  }
  const TriangleMesh mesh = extract_mesh(s.volume);
  const MeshCheck check = check_mesh(mesh);
  EXPECT_GT(check.boundary_edges, 0u) << "the cut leaves a rim";
  EXPECT_EQ(check.non_manifold_edges, 0u);
  EXPECT_EQ(check.same_direction_edges, 0u);

  // Nothing observed at all: nothing extracted, whatever U holds.
  for (std::size_t n = 0; n < view.voxel_count(); ++n) view.set_w(n, 0.0f);
  EXPECT_TRUE(extract_points(s.volume).empty());
  EXPECT_TRUE(extract_mesh(s.volume).faces.empty());
  EXPECT_TRUE(extract_mesh(s.volume).vertices.empty());
}

TEST_P(Extract, MinimumWeightDropsVoxelsSeenTooFewTimes) {
  SphereVolume s = make_sphere_volume(GetParam(), 3.0f);
  const VolumeView view = s.volume.view();
  for (int k = 0; k < s.geometry.nz / 2; ++k) {
    for (int j = 0; j < s.geometry.ny; ++j) {
      for (int i = 0; i < s.geometry.nx; ++i) {
        const std::size_t index = view.index(i, j, k);
        if (view.w(index) > 0.0f) view.set_w(index, 1.0f);
      }
    }
  }
  ExtractOptions options;
  options.min_weight = 2.0f;
  const PointCloud cloud = extract_points(s.volume, nullptr, options);
  const PointCloud all = extract_points(s.volume);
  ASSERT_GT(cloud.size(), 1000u);
  ASSERT_LT(cloud.size(), all.size());
  for (const float w : cloud.find_property("weight")->values) EXPECT_EQ(w, 3.0f);
}

TEST_P(Extract, PlyKeepsNormalsConfidenceAndWeight) {
  const SphereVolume s = make_sphere_volume(GetParam(), 5.0f);
  const PointCloud cloud = extract_points(s.volume);
  const TriangleMesh mesh = extract_mesh(s.volume);
  test::TemporaryDirectory dir;
  write_ply(dir.file("cloud.ply"), cloud);
  write_ply(dir.file("mesh.ply"), mesh);
  const PointCloud cloud_back = read_ply_cloud(dir.file("cloud.ply"));
  EXPECT_EQ(cloud_back.positions, cloud.positions);
  EXPECT_EQ(cloud_back.normals, cloud.normals);
  EXPECT_EQ(cloud_back.confidence, cloud.confidence);
  ASSERT_NE(cloud_back.find_property("weight"), nullptr);
  EXPECT_EQ(cloud_back.find_property("weight")->values, cloud.find_property("weight")->values);
  const TriangleMesh mesh_back = read_ply_mesh(dir.file("mesh.ply"));
  EXPECT_EQ(mesh_back.faces, mesh.faces);
  EXPECT_EQ(mesh_back.vertices.normals, mesh.vertices.normals);
}

INSTANTIATE_TEST_SUITE_P(Formats, Extract, ::testing::Values(VoxelFormat::kFloat32, VoxelFormat::kCompact),
                         [](const ::testing::TestParamInfo<VoxelFormat>& format) {
                           return std::string(voxel_format_name(format.param));
                         });

TEST(ExtractErrors, BadOptionsAreInvalidArguments) {
  Volume volume(test_geometry(8, kVoxel), VoxelFormat::kFloat32, Device::cpu());
  ExtractOptions options;
  options.min_weight = -1.0f;
  try {
    extract_points(volume, nullptr, options);
    FAIL() << "no error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(error.what()).find("min_weight"), std::string::npos);
  }
  options = ExtractOptions{};
  options.full_confidence_weight = 0.0f;
  EXPECT_THROW(extract_mesh(volume, options), Error);
}

TEST(ExtractErrors, ACudaVolumeMustBeCopiedToTheHostFirst) {
  SLS_REQUIRE_CUDA_DEVICE();
  Volume volume(test_geometry(8, kVoxel), VoxelFormat::kCompact, Device::cuda());
  try {
    extract_points(volume);
    FAIL() << "no error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(error.what()).find("to_host"), std::string::npos);
  }
  EXPECT_TRUE(extract_points(volume.to_host()).empty());
}

// The GPU ship searches only bricks a region may keep anything of (region_drops_voxels): for
// regions that keep their outside, turned and shifted at random, a dropped box of voxels has
// no crossing point (anywhere on its voxels' edges) and no cell centre around them kept.
// The host assembly a GPU extraction runs (detail::cell_mesh): a cell finds its edges' crossings
// among its grid row's, with crossings in rows before, between and after; a cell whose edge
// has none is an internal error, not a face with a made-up vertex.
TEST(ExtractAssembly, ACellFindsItsEdgesCrossingsInTheirRowsAndAMissingOneIsAnError) {
  const int nx = 4, ny = 3;
  const auto id = [&](int i, int j, int k, int axis) {
    return (static_cast<std::uint64_t>((k * ny + j) * nx + i)) * 3u + static_cast<std::uint64_t>(axis);
  };
  const auto crossing_at = [&](int i, int j, int k, int axis) {
    EdgeCrossing c;
    c.edge_id = id(i, j, k, axis);
    c.crossing.point_volume = Vec3f{static_cast<float>(i) + (axis == 0 ? 0.5f : 0.0f),
                                    static_cast<float>(j) + (axis == 1 ? 0.5f : 0.0f),
                                    static_cast<float>(k) + (axis == 2 ? 0.5f : 0.0f)};
    c.crossing.normal_volume = Vec3f{0.0f, 0.0f, 1.0f};
    c.crossing.weight = 4.0f;
    return c;
  };
  // Cell (1, 1, 1) with only corner 0 inside: one triangle over the x, y and z edges of voxel
  // (1, 1, 1), whose rows (j, k) = (1, 1), (1, 1), (1, 1); others in rows 0, 4 and 8.
  std::vector<EdgeCrossing> crossings = {crossing_at(0, 0, 0, 0), crossing_at(3, 0, 1, 1), crossing_at(1, 1, 1, 0),
                                         crossing_at(1, 1, 1, 1), crossing_at(1, 1, 1, 2), crossing_at(2, 1, 1, 0),
                                         crossing_at(3, 2, 2, 2)};
  const std::vector<CellCase> cells = {CellCase{static_cast<std::uint64_t>((1 * ny + 1) * nx + 1), 1}};
  const TriangleMesh mesh = detail::cell_mesh(nx, ny, crossings, cells, Pose{}, ExtractOptions{});
  ASSERT_EQ(mesh.faces.size(), 1u);
  ASSERT_EQ(mesh.vertices.size(), 3u);  // only the crossings a face uses
  std::set<std::array<float, 3>> used;
  for (const std::int32_t v : mesh.faces[0]) {
    const Eigen::Vector3f& p = mesh.vertices.positions[static_cast<std::size_t>(v)];
    used.insert({p.x(), p.y(), p.z()});
  }
  const std::set<std::array<float, 3>> expected = {{1.5f, 1.0f, 1.0f}, {1.0f, 1.5f, 1.0f}, {1.0f, 1.0f, 1.5f}};
  EXPECT_EQ(used, expected);
  crossings.erase(crossings.begin() + 4);  // the z edge's
  EXPECT_EQ(test::code_of([&] { detail::cell_mesh(nx, ny, crossings, cells, Pose{}, ExtractOptions{}); }),
            ErrorCode::kInternal);
  crossings.resize(2);  // the cell's row past the last crossing's
  EXPECT_EQ(test::code_of([&] { detail::cell_mesh(nx, ny, crossings, cells, Pose{}, ExtractOptions{}); }),
            ErrorCode::kInternal);
}

TEST(RegionBricks, ADroppedBoxOfVoxelsHasNothingTheRegionKeeps) {
  std::mt19937 generator(3);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const float h = 1e-4f;  // 0.1 mm voxels
  VolumeView view;
  view.nx = view.ny = view.nz = 96;
  view.voxel_size_m = h;
  std::size_t dropped = 0, kept = 0, points = 0;
  for (int trial = 0; trial < 400; ++trial) {
    // The new placement of a 96³ volume: turned by up to ~20° and shifted by up to 12 voxels.
    const double shift = 12.0 * static_cast<double>(h);
    const Pose T_old_new = Pose::exp((Eigen::Matrix<double, 6, 1>() << shift * unit(generator), shift * unit(generator),
                                      shift * unit(generator), 0.35 * unit(generator), 0.35 * unit(generator),
                                      0.35 * unit(generator))
                                         .finished());
    RegionFilter region;
    region.T_box_volume = T_old_new.inverse().to_rigid3f();
    region.lo = Vec3f{0.5f * h, 0.5f * h, 0.5f * h};
    region.hi = Vec3f{95.5f * h, 95.5f * h, 95.5f * h};
    region.keep_outside = 1;
    for (int brick = 0; brick < 40; ++brick) {
      std::uniform_int_distribution<int> start(0, 90);
      const int first[3] = {start(generator), start(generator), start(generator)};
      const int last[3] = {std::min(first[0] + 31, 95), first[1] + 3, first[2] + 3};
      if (!region_drops_voxels(region, h, first, last)) {
        ++kept;
        continue;
      }
      ++dropped;
      for (int k = first[2]; k <= last[2]; ++k) {
        for (int j = first[1]; j <= last[1]; ++j) {
          for (int i = first[0]; i <= last[0]; ++i) {
            // Points along each edge to the next voxel, and the centres of the cells around them.
            for (int axis = 0; axis < 3; ++axis) {
              for (const float t : {0.0f, 0.5f, 1.0f}) {
                Vec3f p = view.voxel_centre(i, j, k);
                (axis == 0 ? p.x : axis == 1 ? p.y : p.z) += t * h;
                ASSERT_FALSE(region_keeps(region, p)) << trial << " " << i << "," << j << "," << k;
                ++points;
              }
              ASSERT_FALSE(edge_has_region_cell(view, region, i, j, k, axis)) << trial;
            }
            if (i + 1 < view.nx && j + 1 < view.ny && k + 1 < view.nz) {
              ASSERT_FALSE(region_keeps(region, cell_centre(view, i, j, k)));
            }
          }
        }
      }
    }
  }
  std::printf("[region-bricks] %zu boxes dropped, %zu kept, %zu points checked\n", dropped, kept, points);
  EXPECT_GT(dropped, 2000u);  // most of a volume stays after such a move
  EXPECT_GT(kept, 1000u);
  // A region that keeps its inside drops nothing this way.
  RegionFilter inside;
  inside.lo = Vec3f{0.0f, 0.0f, 0.0f};
  inside.hi = Vec3f{1.0f, 1.0f, 1.0f};
  const int first[3] = {0, 0, 0}, last[3] = {3, 3, 3};
  EXPECT_FALSE(region_drops_voxels(inside, h, first, last));
}

}  // namespace
}  // namespace sls::fusion
