// Open3D reads the PLY files we write: a cloud with normals, colors, confidence and an extra
// property, and a closed triangle mesh. The checks run in open3d_read_ply.py under the
// system python (Debian's python3-open3d); the expected values travel in a JSON file.
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>

#include <array>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <fmt/format.h>
#include <gtest/gtest.h>

#include "sdk/core/file_util.h"
#include "sdk/core/ply.h"
#include "tests/support/test_support.h"

extern char** environ;

namespace sls {
namespace {

constexpr const char* kPython = "/usr/bin/python3";
constexpr float kRadius = 0.016f;

// Points spread evenly over a sphere (Fibonacci lattice), normals pointing out.
PointCloud make_sphere_cloud(std::size_t n) {
  PointCloud cloud;
  PointProperty weight{"weight", {}};
  const double golden_angle = 3.14159265358979323846 * (3.0 - std::sqrt(5.0));
  for (std::size_t i = 0; i < n; ++i) {
    const double z = 1.0 - 2.0 * (static_cast<double>(i) + 0.5) / static_cast<double>(n);
    const double r = std::sqrt(1.0 - z * z);
    const double angle = golden_angle * static_cast<double>(i);
    const Eigen::Vector3f normal =
        Eigen::Vector3d(r * std::cos(angle), r * std::sin(angle), z).cast<float>().normalized();
    cloud.positions.push_back(normal * kRadius);
    cloud.normals.push_back(normal);
    cloud.confidence.push_back(static_cast<float>(i % 100) / 100.0f);
    cloud.colors.push_back({static_cast<std::uint8_t>(i % 256), static_cast<std::uint8_t>((i * 7) % 256),
                            static_cast<std::uint8_t>(255 - i % 256)});
    weight.values.push_back(static_cast<float>(i) * 0.5f);
  }
  cloud.properties.push_back(weight);
  return cloud;
}

TriangleMesh make_icosahedron() {
  TriangleMesh mesh;
  const float t = (1.0f + std::sqrt(5.0f)) / 2.0f;
  const std::vector<Eigen::Vector3f> corners = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                                                {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                                                {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  for (const Eigen::Vector3f& corner : corners) mesh.vertices.positions.push_back(corner.normalized() * kRadius);
  mesh.faces = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                {11, 10, 2}, {10, 7, 6}, {7, 1, 8},   {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                {3, 8, 9},  {4, 9, 5},  {2, 4, 11},  {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  return mesh;
}

double surface_area(const TriangleMesh& mesh) {
  double area = 0.0;
  for (const auto& face : mesh.faces) {
    const Eigen::Vector3d a = mesh.vertices.positions[static_cast<std::size_t>(face[0])].cast<double>();
    const Eigen::Vector3d b = mesh.vertices.positions[static_cast<std::size_t>(face[1])].cast<double>();
    const Eigen::Vector3d c = mesh.vertices.positions[static_cast<std::size_t>(face[2])].cast<double>();
    area += 0.5 * (b - a).cross(c - a).norm();
  }
  return area;
}

// JSON arrays of the first `count` vectors, printed so that floats come back exactly.
template <typename Vector>
std::string json_rows(const std::vector<Vector>& rows, std::size_t count) {
  std::string out = "[";
  for (std::size_t i = 0; i < count && i < rows.size(); ++i) {
    out += i == 0 ? "[" : ", [";
    for (std::size_t k = 0; k < 3; ++k) {
      out += fmt::format(k == 0 ? "{:.9g}" : ", {:.9g}", static_cast<double>(rows[i][static_cast<Eigen::Index>(k)]));
    }
    out += "]";
  }
  return out + "]";
}

std::string json_colors(const PointCloud& cloud, std::size_t count) {
  std::string out = "[";
  for (std::size_t i = 0; i < count; ++i) {
    const auto& c = cloud.colors[i];
    out += fmt::format("{}[{}, {}, {}]", i == 0 ? "" : ", ", c[0], c[1], c[2]);
  }
  return out + "]";
}

std::string json_values(const std::vector<float>& values, std::size_t count) {
  std::string out = "[";
  for (std::size_t i = 0; i < count; ++i) {
    out += fmt::format("{}{:.9g}", i == 0 ? "" : ", ", static_cast<double>(values[i]));
  }
  return out + "]";
}

std::string expected_json(const PointCloud& cloud, const TriangleMesh& mesh, std::size_t cloud_count) {
  constexpr std::size_t kFirst = 5;
  std::string faces = "[";
  for (std::size_t f = 0; f < kFirst; ++f) {
    faces += fmt::format("{}[{}, {}, {}]", f == 0 ? "" : ", ", mesh.faces[f][0], mesh.faces[f][1], mesh.faces[f][2]);
  }
  faces += "]";
  return fmt::format(
      "{{\n"
      "  \"cloud\": {{\"count\": {}, \"radius\": {:.9g}, \"positions\": {}, \"normals\": {}, \"colors\": {},\n"
      "            \"properties\": {{\"confidence\": {}, \"weight\": {}}}}},\n"
      "  \"mesh\": {{\"vertex_count\": {}, \"triangle_count\": {}, \"vertices\": {}, \"triangles\": {},\n"
      "           \"area\": {:.17g}}}\n"
      "}}\n",
      cloud_count, static_cast<double>(kRadius), json_rows(cloud.positions, kFirst), json_rows(cloud.normals, kFirst),
      json_colors(cloud, kFirst), json_values(cloud.confidence, kFirst),
      json_values(cloud.properties[0].values, kFirst), mesh.vertices.size(), mesh.faces.size(),
      json_rows(mesh.vertices.positions, kFirst), faces, surface_area(mesh));
}

struct RunResult {
  int exit_status = -1;
  std::string output;
};

// Runs a program with stdout and stderr in `log_path` (Open3D may print warnings there).
RunResult run(const std::vector<std::string>& arguments, const std::string& log_path) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  std::vector<std::string> copies = arguments;
  std::vector<char*> argv;
  for (std::string& argument : copies) argv.push_back(argument.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  RunResult result;
  const int error = posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (error != 0) {
    result.output = "cannot start " + arguments[0] + ": " + std::strerror(error);
    return result;
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) break;
  }
  result.exit_status = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  std::ifstream log(log_path);
  std::stringstream text;
  text << log.rdbuf();
  result.output = text.str();
  return result;
}

TEST(PlyOpen3d, ReadsOurCloudAndMesh) {
  test::TemporaryDirectory dir;
  constexpr std::size_t kPoints = 1000;
  const PointCloud cloud = make_sphere_cloud(kPoints);
  const TriangleMesh mesh = make_icosahedron();
  const std::string cloud_path = dir.file("sphere_cloud.ply");
  const std::string mesh_path = dir.file("icosahedron.ply");
  const std::string expected_path = dir.file("expected.json");
  write_ply(cloud_path, cloud);
  write_ply(mesh_path, mesh);
  write_file_atomic(expected_path, expected_json(cloud, mesh, kPoints));

  const RunResult result =
      run({kPython, SLS_OPEN3D_CHECK_SCRIPT, cloud_path, mesh_path, expected_path}, dir.file("open3d.log"));
  ASSERT_NE(result.exit_status, 3) << "open3d is a declared dependency (Debian's python3-open3d for "
                                   << kPython << "):\n" << result.output;
  ASSERT_EQ(result.exit_status, 0) << result.output;

  // Our reader takes what Open3D writes: an ASCII cloud (doubles printed with limited
  // precision) and a binary mesh (double vertices, uint indices).
  const PointCloud open3d_cloud = read_ply_cloud(dir.file("open3d_cloud_ascii.ply"));
  ASSERT_EQ(open3d_cloud.size(), kPoints);
  ASSERT_TRUE(open3d_cloud.has_normals());
  ASSERT_TRUE(open3d_cloud.has_colors());
  for (std::size_t i = 0; i < kPoints; ++i) {
    ASSERT_LT((open3d_cloud.positions[i] - cloud.positions[i]).norm(), 1e-7f) << i;
    ASSERT_LT((open3d_cloud.normals[i] - cloud.normals[i]).norm(), 1e-5f) << i;
    ASSERT_EQ(open3d_cloud.colors[i], cloud.colors[i]) << i;
  }
  const TriangleMesh open3d_mesh = read_ply_mesh(dir.file("open3d_mesh.ply"));
  EXPECT_EQ(open3d_mesh.faces, mesh.faces);
  ASSERT_EQ(open3d_mesh.vertices.size(), mesh.vertices.size());
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    EXPECT_EQ(open3d_mesh.vertices.positions[i], mesh.vertices.positions[i]) << i;
  }

  // The check itself must be able to fail: a wrong expectation is reported.
  write_file_atomic(expected_path, expected_json(cloud, mesh, kPoints + 1));
  const RunResult wrong =
      run({kPython, SLS_OPEN3D_CHECK_SCRIPT, cloud_path, mesh_path, expected_path}, dir.file("open3d_wrong.log"));
  EXPECT_EQ(wrong.exit_status, 1) << wrong.output;
  EXPECT_NE(wrong.output.find("1001"), std::string::npos) << wrong.output;
}

}  // namespace
}  // namespace sls
