#include "sdk/core/ply.h"

#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "tests/support/test_support.h"

namespace sls {
namespace {

PointCloud make_cloud(std::size_t n, bool all_attributes, std::uint32_t seed = 1) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> coordinate(-0.05f, 0.05f);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  std::uniform_int_distribution<int> byte(0, 255);
  PointCloud cloud;
  for (std::size_t i = 0; i < n; ++i) {
    cloud.positions.emplace_back(coordinate(rng), coordinate(rng), coordinate(rng));
  }
  if (!all_attributes) return cloud;
  PointProperty weight{"weight", {}};
  PointProperty frame{"frame", {}};
  for (std::size_t i = 0; i < n; ++i) {
    cloud.normals.push_back(Eigen::Vector3f(coordinate(rng), coordinate(rng), coordinate(rng)).normalized());
    cloud.confidence.push_back(unit(rng));
    cloud.colors.push_back({static_cast<std::uint8_t>(byte(rng)), static_cast<std::uint8_t>(byte(rng)),
                            static_cast<std::uint8_t>(byte(rng))});
    weight.values.push_back(unit(rng) * 100.0f);
    frame.values.push_back(static_cast<float>(i % 7));
  }
  cloud.properties.push_back(weight);
  cloud.properties.push_back(frame);
  return cloud;
}

void expect_same_cloud(const PointCloud& expected, const PointCloud& actual) {
  ASSERT_EQ(expected.size(), actual.size());
  EXPECT_EQ(expected.positions, actual.positions);
  EXPECT_EQ(expected.normals, actual.normals);
  EXPECT_EQ(expected.confidence, actual.confidence);
  EXPECT_EQ(expected.colors, actual.colors);
  ASSERT_EQ(expected.properties.size(), actual.properties.size());
  for (std::size_t p = 0; p < expected.properties.size(); ++p) {
    EXPECT_EQ(expected.properties[p].name, actual.properties[p].name);
    EXPECT_EQ(expected.properties[p].values, actual.properties[p].values);
  }
}

// A regular octahedron: 6 vertices, 8 faces.
TriangleMesh make_octahedron() {
  TriangleMesh mesh;
  const float r = 0.01f;
  mesh.vertices.positions = {{r, 0, 0}, {-r, 0, 0}, {0, r, 0}, {0, -r, 0}, {0, 0, r}, {0, 0, -r}};
  for (const Eigen::Vector3f& p : mesh.vertices.positions) mesh.vertices.normals.push_back(p.normalized());
  mesh.faces = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  return mesh;
}

// Builds PLY data bytes by hand, in either byte order.
class Bytes {
 public:
  explicit Bytes(bool big_endian = false) : big_endian_(big_endian) {}
  Bytes& text(const std::string& s) {
    data_ += s;
    return *this;
  }
  template <typename T>
  Bytes& put(T value) {
    char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    for (std::size_t i = 0; i < sizeof(T); ++i) data_ += bytes[big_endian_ ? sizeof(T) - 1 - i : i];
    return *this;
  }
  const std::string& str() const { return data_; }

 private:
  bool big_endian_;
  std::string data_;
};

void write_bytes(const std::string& path, const std::string& bytes) { write_file_atomic(path, bytes); }

// Runs `read`, which must throw sls::Error with `code` and a message naming `path` and
// containing `detail`.
void expect_error(const std::function<void()>& read, const std::string& path, ErrorCode code,
                  const std::string& detail) {
  try {
    read();
    ADD_FAILURE() << "no error for " << path;
  } catch (const Error& error) {
    const std::string message = error.what();
    EXPECT_EQ(error.code(), code) << message;
    EXPECT_NE(message.find(path), std::string::npos) << message;
    EXPECT_NE(message.find(detail), std::string::npos) << "expected '" << detail << "' in: " << message;
  }
}

TEST(Ply, RoundTripsCloudWithEveryAttribute) {
  test::TemporaryDirectory dir;
  const PointCloud cloud = make_cloud(1000, true);
  const std::string path = dir.file("cloud.ply");
  write_ply(path, cloud);
  expect_same_cloud(cloud, read_ply_cloud(path));

  const std::string bytes = read_file_text(path);
  EXPECT_EQ(bytes.rfind("ply\nformat binary_little_endian 1.0\ncomment written by slscan\n", 0), 0u);
  const std::string header = bytes.substr(0, bytes.find("end_header\n"));
  for (const char* line : {"element vertex 1000\n", "property float x\n", "property float nz\n",
                           "property float confidence\n", "property uchar red\n", "property uchar blue\n",
                           "property float weight\n", "property float frame\n"}) {
    EXPECT_NE(header.find(line), std::string::npos) << line;
  }
  // 12 position + 12 normal + 4 confidence + 3 color + 2 * 4 property bytes per point.
  EXPECT_EQ(bytes.size(), header.size() + std::strlen("end_header\n") + 1000u * 39u);
  // Nothing but the file is left in the folder (no temporary from the atomic write).
  std::size_t files = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(dir.path())) ++files;
  EXPECT_EQ(files, 1u);
}

TEST(Ply, RoundTripsPositionsOnlyAndEmptyCloud) {
  test::TemporaryDirectory dir;
  const PointCloud cloud = make_cloud(17, false);
  write_ply(dir.file("positions.ply"), cloud);
  expect_same_cloud(cloud, read_ply_cloud(dir.file("positions.ply")));

  write_ply(dir.file("empty.ply"), PointCloud{});
  EXPECT_TRUE(read_ply_cloud(dir.file("empty.ply")).empty());
}

TEST(Ply, RoundTripsMesh) {
  test::TemporaryDirectory dir;
  const TriangleMesh mesh = make_octahedron();
  const std::string path = dir.file("mesh.ply");
  write_ply(path, mesh);
  const TriangleMesh read = read_ply_mesh(path);
  expect_same_cloud(mesh.vertices, read.vertices);
  EXPECT_EQ(read.faces, mesh.faces);
  EXPECT_NE(read_file_text(path).find("element face 8\nproperty list uchar int vertex_indices\n"), std::string::npos);
  // The vertices of a mesh file read as a cloud.
  expect_same_cloud(mesh.vertices, read_ply_cloud(path));
  // A cloud file read as a mesh has no faces.
  write_ply(dir.file("cloud.ply"), mesh.vertices);
  EXPECT_TRUE(read_ply_mesh(dir.file("cloud.ply")).faces.empty());
}

TEST(Ply, ReadsLargeCloudQuickly) {
  test::TemporaryDirectory dir;
  PointCloud cloud = make_cloud(1'000'000, false);
  cloud.normals = cloud.positions;
  cloud.confidence.assign(cloud.size(), 0.5f);
  const std::string path = dir.file("large.ply");
  const auto start = std::chrono::steady_clock::now();
  write_ply(path, cloud);
  const auto written = std::chrono::steady_clock::now();
  const PointCloud read = read_ply_cloud(path);
  const auto end = std::chrono::steady_clock::now();
  expect_same_cloud(cloud, read);
  using ms = std::chrono::duration<double, std::milli>;
  std::printf("1M points: write %.1f ms, read %.1f ms\n", ms(written - start).count(), ms(end - written).count());
}

TEST(Ply, ReadsAsciiWrittenByHand) {
  test::TemporaryDirectory dir;
  const std::string path = dir.file("ascii.ply");
  write_bytes(path,
              "ply\r\n"
              "format ascii 1.0\r\n"
              "comment made by hand, with CRLF line ends\r\n"
              "obj_info some tool\r\n"
              "element vertex 4\r\n"
              "property double x\r\n"
              "property double y\r\n"
              "property double z\r\n"
              "property float nx\r\n"
              "property float ny\r\n"
              "property float nz\r\n"
              "property uchar red\r\n"
              "property uchar green\r\n"
              "property uchar blue\r\n"
              "property float confidence\r\n"
              "property int label\r\n"
              "element face 2\r\n"
              "property list uchar int vertex_indices\r\n"
              "end_header\r\n"
              "0 0 0 0 0 1 255 0 0 0.5 7\r\n"
              "1.5 0 0 0 0 1 0 255 0 0.25 -3\r\n"
              "1.5 2.5e-1 0 0 0 1 0 0 255 1 +2\r\n"
              "0 0.25 -1e-3 0 0 1 10 20 30 0 0\r\n"
              "3 0 1 2\r\n"
              "4 0 1 2 3\r\n");
  const TriangleMesh mesh = read_ply_mesh(path);
  ASSERT_EQ(mesh.vertices.size(), 4u);
  EXPECT_EQ(mesh.vertices.positions[1], Eigen::Vector3f(1.5f, 0.0f, 0.0f));
  EXPECT_EQ(mesh.vertices.positions[2], Eigen::Vector3f(1.5f, 0.25f, 0.0f));
  EXPECT_EQ(mesh.vertices.positions[3], Eigen::Vector3f(0.0f, 0.25f, -1e-3f));
  ASSERT_EQ(mesh.vertices.normals.size(), 4u);
  EXPECT_EQ(mesh.vertices.normals[3], Eigen::Vector3f(0, 0, 1));
  EXPECT_EQ(mesh.vertices.colors[0], (std::array<std::uint8_t, 3>{255, 0, 0}));
  EXPECT_EQ(mesh.vertices.colors[3], (std::array<std::uint8_t, 3>{10, 20, 30}));
  EXPECT_EQ(mesh.vertices.confidence, (std::vector<float>{0.5f, 0.25f, 1.0f, 0.0f}));
  ASSERT_EQ(mesh.vertices.properties.size(), 1u);
  EXPECT_EQ(mesh.vertices.properties[0].name, "label");
  EXPECT_EQ(mesh.vertices.properties[0].values, (std::vector<float>{7, -3, 2, 0}));
  // The quad becomes a fan of two triangles.
  EXPECT_EQ(mesh.faces, (std::vector<std::array<std::int32_t, 3>>{{0, 1, 2}, {0, 1, 2}, {0, 2, 3}}));
}

TEST(Ply, SkipsUnknownElementsWithLists) {
  test::TemporaryDirectory dir;
  for (const bool ascii : {false, true}) {
    const std::string path = dir.file(ascii ? "unknown_ascii.ply" : "unknown_binary.ply");
    Bytes bytes;
    bytes.text(std::string("ply\nformat ") + (ascii ? "ascii" : "binary_little_endian") +
               " 1.0\n"
               "element material 2\n"
               "property uchar id\n"
               "property list ushort double weights\n"
               "property short flags\n"
               "element vertex 2\n"
               "property float x\nproperty float y\nproperty float z\n"
               "property list uchar float uv\n"
               "property ushort quality\n"
               "element edge 1\n"
               "property list uchar int vertex_pair\n"
               "element face 1\n"
               "property list uchar uint vertex_indices\n"
               "end_header\n");
    if (ascii) {
      bytes.text("1 3 0.5 0.25 0.125 -1\n2 0 9\n1 2 3 2 0.5 0.5 10\n4 5 6 0 11\n2 0 1\n3 1 0 1\n");
    } else {
      bytes.put<std::uint8_t>(1).put<std::uint16_t>(3).put(0.5).put(0.25).put(0.125).put<std::int16_t>(-1);
      bytes.put<std::uint8_t>(2).put<std::uint16_t>(0).put<std::int16_t>(9);
      bytes.put(1.0f).put(2.0f).put(3.0f).put<std::uint8_t>(2).put(0.5f).put(0.5f).put<std::uint16_t>(10);
      bytes.put(4.0f).put(5.0f).put(6.0f).put<std::uint8_t>(0).put<std::uint16_t>(11);
      bytes.put<std::uint8_t>(2).put<std::int32_t>(0).put<std::int32_t>(1);
      bytes.put<std::uint8_t>(3).put<std::uint32_t>(1).put<std::uint32_t>(0).put<std::uint32_t>(1);
    }
    write_bytes(path, bytes.str());
    const TriangleMesh mesh = read_ply_mesh(path);
    ASSERT_EQ(mesh.vertices.size(), 2u) << path;
    EXPECT_EQ(mesh.vertices.positions[0], Eigen::Vector3f(1, 2, 3));
    EXPECT_EQ(mesh.vertices.positions[1], Eigen::Vector3f(4, 5, 6));
    // The vertex list property is skipped; the scalar after it is read.
    ASSERT_EQ(mesh.vertices.properties.size(), 1u);
    EXPECT_EQ(mesh.vertices.properties[0].name, "quality");
    EXPECT_EQ(mesh.vertices.properties[0].values, (std::vector<float>{10, 11}));
    EXPECT_EQ(mesh.faces, (std::vector<std::array<std::int32_t, 3>>{{1, 0, 1}}));
  }
}

TEST(Ply, TriangulatesPolygonsAsFans) {
  test::TemporaryDirectory dir;
  const std::string path = dir.file("polygons.ply");
  Bytes bytes;
  bytes.text("ply\nformat binary_little_endian 1.0\nelement vertex 5\n"
             "property float x\nproperty float y\nproperty float z\n"
             "element face 4\nproperty list uchar int vertex_indices\nend_header\n");
  for (int i = 0; i < 5; ++i) bytes.put(static_cast<float>(i)).put(0.0f).put(0.0f);
  bytes.put<std::uint8_t>(4).put(0).put(1).put(2).put(3);         // quad
  bytes.put<std::uint8_t>(2).put(0).put(1);                       // degenerate: dropped
  bytes.put<std::uint8_t>(5).put(4).put(3).put(2).put(1).put(0);  // pentagon
  bytes.put<std::uint8_t>(3).put(2).put(3).put(4);                // triangle
  write_bytes(path, bytes.str());
  const TriangleMesh mesh = read_ply_mesh(path);
  EXPECT_EQ(mesh.faces, (std::vector<std::array<std::int32_t, 3>>{
                            {0, 1, 2}, {0, 2, 3}, {4, 3, 2}, {4, 2, 1}, {4, 1, 0}, {2, 3, 4}}));
}

TEST(Ply, ReadsBigEndianAndEveryScalarType) {
  test::TemporaryDirectory dir;
  for (const bool big_endian : {false, true}) {
    const std::string path = dir.file(big_endian ? "big.ply" : "little.ply");
    Bytes bytes(big_endian);
    bytes.text(std::string("ply\nformat ") + (big_endian ? "binary_big_endian" : "binary_little_endian") +
               " 1.0\nelement vertex 2\n"
               "property float64 x\nproperty float32 y\nproperty int16 z\n"
               "property char a\nproperty uint8 b\nproperty ushort c\nproperty int32 d\nproperty uint e\n"
               "property float red\nproperty float green\nproperty float blue\n"
               "element face 1\n"
               "property uchar flags\n"
               "property list int16 uint16 vertex_index\n"
               "property list uchar float texcoord\n"
               "end_header\n");
    for (int i = 0; i < 2; ++i) {
      bytes.put(0.125 + i).put(-2.5f).put<std::int16_t>(static_cast<std::int16_t>(-300 + i));
      bytes.put<std::int8_t>(-5).put<std::uint8_t>(200).put<std::uint16_t>(60000).put<std::int32_t>(-70000);
      bytes.put<std::uint32_t>(4000000000u);
      bytes.put(1.0f).put(0.5f).put(-1.0f);
    }
    bytes.put<std::uint8_t>(1).put<std::int16_t>(3).put<std::uint16_t>(1).put<std::uint16_t>(0).put<std::uint16_t>(1);
    bytes.put<std::uint8_t>(2).put(0.5f).put(0.5f);
    write_bytes(path, bytes.str());
    const TriangleMesh mesh = read_ply_mesh(path);
    ASSERT_EQ(mesh.vertices.size(), 2u);
    EXPECT_EQ(mesh.vertices.positions[0], Eigen::Vector3f(0.125f, -2.5f, -300.0f));
    EXPECT_EQ(mesh.vertices.positions[1], Eigen::Vector3f(1.125f, -2.5f, -299.0f));
    EXPECT_EQ(mesh.vertices.colors[1], (std::array<std::uint8_t, 3>{255, 128, 0}));
    ASSERT_EQ(mesh.vertices.properties.size(), 5u);
    const std::vector<std::pair<std::string, float>> expected = {
        {"a", -5.0f}, {"b", 200.0f}, {"c", 60000.0f}, {"d", -70000.0f}, {"e", 4e9f}};
    for (std::size_t p = 0; p < expected.size(); ++p) {
      EXPECT_EQ(mesh.vertices.properties[p].name, expected[p].first);
      EXPECT_EQ(mesh.vertices.properties[p].values, std::vector<float>(2, expected[p].second));
    }
    EXPECT_EQ(mesh.faces, (std::vector<std::array<std::int32_t, 3>>{{1, 0, 1}}));
  }
}

TEST(Ply, RejectsBadMagic) {
  test::TemporaryDirectory dir;
  const std::string path = dir.file("bad_magic.ply");
  write_bytes(path, "PLY\nformat ascii 1.0\nend_header\n");
  expect_error([&] { read_ply_cloud(path); }, path, ErrorCode::kFormat, "not a PLY file");
  write_bytes(path, "plyx\nformat ascii 1.0\nend_header\n");
  expect_error([&] { read_ply_cloud(path); }, path, ErrorCode::kFormat, "not a PLY file");
  write_bytes(path, "");
  expect_error([&] { read_ply_cloud(path); }, path, ErrorCode::kFormat, "not a PLY file");
}

TEST(Ply, RejectsTruncatedHeader) {
  test::TemporaryDirectory dir;
  const std::string good = encode_ply(make_cloud(10, true));
  const std::string path = dir.file("truncated_header.ply");
  write_bytes(path, good.substr(0, good.find("end_header") + 5));
  expect_error([&] { read_ply_cloud(path); }, path, ErrorCode::kFormat, "truncated header");
  write_bytes(path, "ply\n");
  expect_error([&] { read_ply_cloud(path); }, path, ErrorCode::kFormat, "truncated header");
}

TEST(Ply, RejectsTruncatedData) {
  test::TemporaryDirectory dir;
  const std::string path = dir.file("truncated_data.ply");
  write_bytes(path, encode_ply(make_cloud(100, true)).substr(0, encode_ply(make_cloud(100, true)).size() - 5));
  expect_error([&] { read_ply_cloud(path); }, path, ErrorCode::kFormat,
               "truncated data: expected 100 vertices of 39 bytes, the file ends after 99");

  const std::string mesh = encode_ply(make_octahedron());
  write_bytes(path, mesh.substr(0, mesh.size() - 3));
  expect_error([&] { read_ply_mesh(path); }, path, ErrorCode::kFormat, "expected 8 faces, the file ends after 7");

  write_bytes(path, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    "property float z\nend_header\n1.0 2.0 3.0\n4.0 5.0 6.0\n7.0 8.0\n");
  expect_error([&] { read_ply_cloud(path); }, path, ErrorCode::kFormat, "expected 3 vertices, the file ends after 2");
  // So short that the count is rejected before anything is read.
  write_bytes(path, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    "property float z\nend_header\n1 2 3\n4 5 6\n7 8\n");
  expect_error([&] { read_ply_cloud(path); }, path, ErrorCode::kFormat, "truncated data: expected 3 vertices");
}

TEST(Ply, RejectsHugeCountsWithoutAllocating) {
  test::TemporaryDirectory dir;
  const std::string path = dir.file("huge.ply");
  for (const char* format : {"binary_little_endian", "ascii"}) {
    write_bytes(path, std::string("ply\nformat ") + format +
                          " 1.0\nelement vertex 1000000000000\nproperty float x\nproperty float y\n"
                          "property float z\nend_header\n1 2 3\n");
    expect_error([&] { read_ply_cloud(path); }, path, ErrorCode::kFormat, "expected 1000000000000 vertices");
  }
  write_bytes(path, "ply\nformat binary_little_endian 1.0\nelement vertex 18446744073709551615\n"
                    "property double x\nproperty double y\nproperty double z\nend_header\n");
  expect_error([&] { read_ply_cloud(path); }, path, ErrorCode::kFormat, "truncated data");
  // A list whose count runs past the end of the file.
  Bytes bytes;
  bytes.text("ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
             "property float z\nelement face 1\nproperty list uint int vertex_indices\nend_header\n");
  bytes.put(0.0f).put(0.0f).put(0.0f).put<std::uint32_t>(4000000000u).put(0).put(0).put(0);
  write_bytes(path, bytes.str());
  expect_error([&] { read_ply_mesh(path); }, path, ErrorCode::kFormat, "expected 1 faces, the file ends after 0");
}

TEST(Ply, RejectsBadCounts) {
  test::TemporaryDirectory dir;
  const std::string path = dir.file("bad_count.ply");
  for (const char* count : {"-3", "abc", "1e3", "12x"}) {
    write_bytes(path, std::string("ply\nformat ascii 1.0\nelement vertex ") + count +
                          "\nproperty float x\nproperty float y\nproperty float z\nend_header\n");
    expect_error([&] { read_ply_cloud(path); }, path, ErrorCode::kFormat, "bad count");
  }
  write_bytes(path, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                    "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                    "0 0 0\n-2 0 0\n");
  expect_error([&] { read_ply_mesh(path); }, path, ErrorCode::kFormat, "negative");
}

TEST(Ply, RejectsFaceIndexOutOfRange) {
  test::TemporaryDirectory dir;
  const std::string path = dir.file("bad_index.ply");
  for (const int index : {6, -1}) {
    TriangleMesh mesh = make_octahedron();
    std::string bytes = encode_ply(mesh);
    // Patch the last index of the last face (the file's last four bytes).
    std::memcpy(bytes.data() + bytes.size() - 4, &index, 4);
    write_bytes(path, bytes);
    expect_error([&] { read_ply_mesh(path); }, path, ErrorCode::kFormat,
                 "face 7 refers to vertex " + std::to_string(index) + " but the file has 6 vertices");
  }
}

TEST(Ply, RejectsOtherCorruptHeaders) {
  test::TemporaryDirectory dir;
  const std::string path = dir.file("bad_header.ply");
  const std::string xyz = "property float x\nproperty float y\nproperty float z\n";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n0 0\n",
       "no scalar property 'z'"},
      {"ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n",
       "no vertex element"},
      {"ply\nelement vertex 0\n" + xyz + "end_header\n", "no format line"},
      {"ply\nformat binary_middle_endian 1.0\nelement vertex 0\n" + xyz + "end_header\n", "unknown format"},
      {"ply\nformat ascii 1.0\nelement vertex 0\nproperty quad x\nend_header\n", "unknown type 'quad'"},
      {"ply\nformat ascii 1.0\nproperty float x\nend_header\n", "property before any element"},
      {"ply\nformat ascii 1.0\nelement vertex 0\n" + xyz + "property float x\nend_header\n", "appears twice"},
      {"ply\nformat ascii 1.0\nelement vertex 0\nproperty list float int x\nend_header\n", "bad list count type"},
      {"ply\nformat ascii 1.0\nelement vertex 0\n" + xyz + "element vertex 0\nend_header\n",
       "more than one 'vertex' element"},
      {"ply\nformat ascii 1.0\nelement vertex 0\n" + xyz + "frobnicate\nend_header\n", "unknown keyword"},
      {"ply\nformat ascii 1.0\nelement vertex 1\n" + xyz + "end_header\n0 zero 0\n", "bad value 'zero'"},
  };
  for (const auto& [text, detail] : cases) {
    write_bytes(path, text);
    expect_error([&] { read_ply_mesh(path); }, path, ErrorCode::kFormat, detail);
  }
  write_bytes(path, "ply\nformat ascii 2.0\nelement vertex 0\n" + xyz + "end_header\n");
  expect_error([&] { read_ply_cloud(path); }, path, ErrorCode::kVersionMismatch, "version");
  write_bytes(path, "ply\nformat ascii 1.0\nelement vertex 1\n" + xyz +
                        "element face 1\nproperty list uchar float vertex_indices\nend_header\n0 0 0\n3 0 0 0\n");
  expect_error([&] { read_ply_mesh(path); }, path, ErrorCode::kFormat, "floating-point");
  write_bytes(path, "ply\nformat ascii 1.0\nelement vertex 1\n" + xyz +
                        "element face 1\nproperty list uchar int corners\nend_header\n0 0 0\n3 0 0 0\n");
  expect_error([&] { read_ply_mesh(path); }, path, ErrorCode::kFormat, "no 'vertex_indices' list");
}

TEST(Ply, ReportsMissingFile) {
  test::TemporaryDirectory dir;
  const std::string path = dir.file("missing.ply");
  expect_error([&] { read_ply_cloud(path); }, path, ErrorCode::kNotFound, "cannot open");
  expect_error([&] { read_ply_mesh(dir.path()); }, dir.path(), ErrorCode::kIo, "cannot read");
}

TEST(Ply, WriterRejectsInconsistentInput) {
  test::TemporaryDirectory dir;
  const std::string path = dir.file("bad_input.ply");
  PointCloud cloud = make_cloud(10, true);
  cloud.confidence.pop_back();
  expect_error([&] { write_ply(path, cloud); }, path, ErrorCode::kInvalidArgument, "confidence");
  for (const char* name : {"nx", "red", "confidence", "has space", "", "weight"}) {
    cloud = make_cloud(10, true);
    cloud.properties.push_back(PointProperty{name, std::vector<float>(10)});
    expect_error([&] { write_ply(path, cloud); }, path, ErrorCode::kInvalidArgument, "property");
  }
  TriangleMesh mesh = make_octahedron();
  mesh.faces[3][1] = 6;
  expect_error([&] { write_ply(path, mesh); }, path, ErrorCode::kInvalidArgument, "face 3");
  EXPECT_FALSE(std::filesystem::exists(path));
}

// Every prefix and many random corruptions of a good file: an sls::Error or a result, never
// a crash or an out-of-bounds read (this test is meant to run under ASan).
TEST(Ply, SurvivesCorruptInput) {
  TriangleMesh mesh = make_octahedron();
  mesh.vertices.confidence.assign(6, 0.5f);
  mesh.vertices.colors.assign(6, {1, 2, 3});
  for (const bool ascii : {false, true}) {
    std::string good = encode_ply(mesh);
    if (ascii) {
      good = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
             "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
             "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n4 0 1 2 0\n";
    }
    auto attempt = [](const std::string& bytes) {
      // An exact-size heap copy (std::string has a terminator after its data), so ASan sees
      // a read one byte past the end.
      const std::unique_ptr<char[]> exact(new char[bytes.size()]);
      std::memcpy(exact.get(), bytes.data(), bytes.size());
      try {
        (void)decode_ply_mesh(std::string_view(exact.get(), bytes.size()), "corrupt.ply");
      } catch (const Error& error) {
        EXPECT_NE(std::string(error.what()).find("corrupt.ply"), std::string::npos) << error.what();
      }
    };
    for (std::size_t length = 0; length < good.size(); ++length) attempt(good.substr(0, length));
    std::mt19937 rng(42);
    for (int trial = 0; trial < 3000; ++trial) {
      std::string bytes = good;
      const int flips = 1 + trial % 4;
      for (int f = 0; f < flips; ++f) {
        const std::size_t at = std::uniform_int_distribution<std::size_t>(0, bytes.size() - 1)(rng);
        bytes[at] = static_cast<char>(std::uniform_int_distribution<int>(0, 255)(rng));
      }
      attempt(bytes);
    }
  }
}

// A NaN or infinite position is refused, naming the file and the vertex; by every path of
// the reader: ASCII, binary in bulk (fixed-size records) and binary record by record (a list
// in the vertex element), either byte order, and a double too large for a float.
TEST(Ply, RejectsNonFinitePositions) {
  test::TemporaryDirectory dir;
  const std::string path = dir.file("nan.ply");
  const std::string ascii_header =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
  for (const char* bad : {"nan", "-inf", "inf", "NaN"}) {
    write_bytes(path, ascii_header + "0 0 0\n1 1 1\n2 " + bad + " 2\n");
    expect_error([&] { read_ply_cloud(path); }, path, ErrorCode::kFormat, "vertex 2 (counting from 0) has a non-finite position");
  }
  write_bytes(path, "ply\nformat ascii 1.0\nelement vertex 1\nproperty double x\nproperty double y\n"
                    "property double z\nend_header\n1e300 0 0\n");
  expect_error([&] { read_ply_cloud(path); }, path, ErrorCode::kFormat, "vertex 0 (counting from 0) has a non-finite");
  for (const bool big_endian : {false, true}) {
    for (const bool with_list : {false, true}) {
      Bytes bytes(big_endian);
      bytes.text(std::string("ply\nformat ") + (big_endian ? "binary_big_endian" : "binary_little_endian") +
                 " 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty double z\n" +
                 (with_list ? "property list uchar int extra\n" : "") + "end_header\n");
      bytes.put(1.0f).put(2.0f).put(3.0);
      if (with_list) bytes.put<std::uint8_t>(0);
      bytes.put(1.0f).put(std::numeric_limits<float>::quiet_NaN()).put(3.0);
      if (with_list) bytes.put<std::uint8_t>(0);
      write_bytes(path, bytes.str());
      expect_error([&] { read_ply_mesh(path); }, path, ErrorCode::kFormat,
                   "vertex 1 (counting from 0) has a non-finite position (1, nan, 3)");
    }
  }
  // What encode_ply writes is refused the same way when read back from memory.
  PointCloud cloud = make_cloud(4, false);
  cloud.positions[3].z() = std::numeric_limits<float>::infinity();
  expect_error([&] { decode_ply_cloud(encode_ply(cloud), "memory.ply"); }, "memory.ply", ErrorCode::kFormat,
               "vertex 3 (counting from 0)");
}

// Only positions must be finite: NaN in normals and other properties ("no value") is kept.
TEST(Ply, KeepsNonFiniteValuesOfOtherProperties) {
  test::TemporaryDirectory dir;
  const std::string path = dir.file("nan_properties.ply");
  write_bytes(path, "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                    "property float z\nproperty float nx\nproperty float ny\nproperty float nz\n"
                    "property float quality\nend_header\n0 0 0 nan nan nan inf\n1 2 3 0 0 1 nan\n");
  const PointCloud cloud = read_ply_cloud(path);
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_TRUE(std::isnan(cloud.normals[0].x()));
  EXPECT_TRUE(std::isinf(cloud.properties[0].values[0]));
  EXPECT_TRUE(std::isnan(cloud.properties[0].values[1]));
  EXPECT_EQ(cloud.positions[1], Eigen::Vector3f(1, 2, 3));
}

}  // namespace
}  // namespace sls
