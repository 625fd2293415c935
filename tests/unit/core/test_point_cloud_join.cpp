// Joining clouds and meshes (the scan's final model): every per-point array and property of
// the first then the second, triangles re-indexed, an empty side taking the other's layout,
// positions and normals left to the caller when asked, and a missing property refused.
#include <gtest/gtest.h>

#include "sdk/core/error.h"
#include "sdk/core/point_cloud.h"
#include "tests/support/test_support.h"

namespace sls {
namespace {

PointCloud cloud_of(int n, float base) {
  PointCloud cloud;
  for (int i = 0; i < n; ++i) {
    cloud.positions.emplace_back(base + static_cast<float>(i), 0.0f, 1.0f);
    cloud.normals.emplace_back(0.0f, 0.0f, 1.0f);
    cloud.confidence.push_back(0.5f + 0.01f * static_cast<float>(i));
  }
  cloud.properties.push_back({"weight", std::vector<float>(static_cast<std::size_t>(n), base)});
  return cloud;
}

TEST(JoinClouds, FirstThenSecondInEveryArray) {
  const PointCloud a = cloud_of(3, 10.0f);
  const PointCloud b = cloud_of(2, 20.0f);
  const PointCloud joined = join_clouds(a, b);
  EXPECT_NO_THROW(joined.validate());
  ASSERT_EQ(joined.size(), 5u);
  EXPECT_EQ(joined.positions[2], a.positions[2]);
  EXPECT_EQ(joined.positions[3], b.positions[0]);
  EXPECT_EQ(joined.confidence[4], b.confidence[1]);
  ASSERT_NE(joined.find_property("weight"), nullptr);
  EXPECT_EQ(joined.find_property("weight")->values, (std::vector<float>{10, 10, 10, 20, 20}));
  // An empty side takes the other's layout.
  EXPECT_EQ(join_clouds(PointCloud{}, b).positions, b.positions);
  EXPECT_EQ(join_clouds(a, PointCloud{}).find_property("weight")->values, a.find_property("weight")->values);
  // Without the geometry: sized for the caller's own pass, the rest copied.
  const PointCloud sized = join_clouds(a, b, false);
  EXPECT_EQ(sized.positions.size(), 5u);
  EXPECT_EQ(sized.normals.size(), 5u);
  EXPECT_EQ(sized.confidence, joined.confidence);
  // The second must carry the first's properties.
  PointCloud bare = b;
  bare.properties.clear();
  EXPECT_EQ(test::code_of([&] { join_clouds(a, bare); }), ErrorCode::kInvalidArgument);
}

TEST(JoinMeshes, SecondsTrianglesIndexPastTheFirstsVertices) {
  TriangleMesh a;
  a.vertices = cloud_of(3, 0.0f);
  a.faces = {{0, 1, 2}};
  TriangleMesh b;
  b.vertices = cloud_of(4, 5.0f);
  b.faces = {{0, 1, 2}, {1, 3, 2}};
  const TriangleMesh joined = join_meshes(a, b);
  EXPECT_NO_THROW(joined.validate());
  ASSERT_EQ(joined.faces.size(), 3u);
  EXPECT_EQ(joined.faces[0], (std::array<std::int32_t, 3>{0, 1, 2}));
  EXPECT_EQ(joined.faces[2], (std::array<std::int32_t, 3>{4, 6, 5}));
  EXPECT_EQ(joined.vertices.positions[3], b.vertices.positions[0]);
}

}  // namespace
}  // namespace sls
