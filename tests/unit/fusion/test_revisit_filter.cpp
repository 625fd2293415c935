// fusion/revisit_filter.h: a moving volume's second pass over the same surface ships nothing
// new, surface elsewhere or facing the other way is kept, and meshes stay consistent.
#include <gtest/gtest.h>

#include "fusion/revisit_filter.h"
#include "sdk/core/error.h"

namespace sls::fusion {
namespace {

constexpr double kCell = 20e-6;

// A flat patch at height z (n x n points on a grid of `spacing`), normals along `normal_z`,
// meshed as two triangles per grid square, with a "weight" property on every point.
ExtractedSurface patch(int n, double spacing, double x0, float z, float normal_z) {
  ExtractedSurface s;
  PointCloud* clouds[2] = {&s.cloud, &s.mesh.vertices};
  for (PointCloud* cloud : clouds) {
    cloud->properties.push_back({"weight", {}});
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i) {
        // A quarter cell in from the cell edges, where float rounding cannot pick the cell.
        cloud->positions.emplace_back(static_cast<float>(x0 + 0.25 * kCell + i * spacing),
                                      static_cast<float>(0.25 * kCell + j * spacing), z);
        cloud->normals.emplace_back(0.0f, 0.0f, normal_z);
        cloud->properties[0].values.push_back(static_cast<float>(i + j));
      }
    }
  }
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      const std::int32_t a = j * n + i;
      s.mesh.faces.push_back({a, a + 1, a + n});
      s.mesh.faces.push_back({a + 1, a + n + 1, a + n});
    }
  }
  return s;
}

TEST(RevisitFilter, ASecondPassOverTheSameSurfaceShipsNothing) {
  RevisitFilter filter(kCell);
  const ExtractedSurface first = filter.filter(patch(10, 0.5 * kCell, 0.0, 1e-6f, 1.0f));
  EXPECT_EQ(first.cloud.size(), 100u);  // the first pass is all new, even where points share cells
  EXPECT_EQ(first.mesh.faces.size(), 162u);
  // Again, moved by a fraction of a cell (a later pass's drift): every point lands in a taken cell.
  const ExtractedSurface again = filter.filter(patch(10, 0.5 * kCell, 0.1 * kCell, 2e-6f, 1.0f));
  EXPECT_EQ(again.cloud.size(), 0u);
  EXPECT_EQ(again.mesh.faces.size(), 0u);
  EXPECT_EQ(again.mesh.vertices.size(), 0u);
}

// Merging begun part-way (RevisitPolicy::kAfterFirstRevolution): what was shipped before counts
// as shipped, facing included, and remembering it ships nothing.
TEST(RevisitFilter, SurfaceRememberedBeforeMergingCountsAsShipped) {
  RevisitFilter filter(kCell);
  filter.remember(patch(10, 0.5 * kCell, 0.0, 1e-6f, 1.0f).cloud);
  EXPECT_GT(filter.cells(), 0u);
  EXPECT_EQ(filter.filter(patch(10, 0.5 * kCell, 0.1 * kCell, 2e-6f, 1.0f)).cloud.size(), 0u);
  EXPECT_EQ(filter.filter(patch(10, 0.5 * kCell, 0.1 * kCell, 2e-6f, -1.0f)).cloud.size(), 100u);  // the back face
}

TEST(RevisitFilter, KeepsSurfaceElsewhereAndTheOtherFaceOfAThinWall) {
  RevisitFilter filter(kCell);
  (void)filter.filter(patch(4, kCell, 0.0, 1e-6f, 1.0f));
  const ExtractedSurface beside = filter.filter(patch(4, kCell, 5 * kCell, 1e-6f, 1.0f));  // a cell apart
  EXPECT_EQ(beside.cloud.size(), 16u);
  const ExtractedSurface back_face = filter.filter(patch(4, kCell, 0.0, 1e-6f, -1.0f));
  EXPECT_EQ(back_face.cloud.size(), 16u);
  EXPECT_EQ(back_face.mesh.faces.size(), 18u);
}

TEST(RevisitFilter, APartlyRevisitedMeshKeepsOnlyWholeFacesAndTheirVertices) {
  RevisitFilter filter(kCell);
  (void)filter.filter(patch(5, kCell, 0.0, 1e-6f, 1.0f));  // cells x 0..4, y 0..4
  // Overlaps the first in its first two columns (x 3, 4), touches it in the third (x 5: a
  // neighbour of a taken cell counts as taken) and is new in the last two (x 6, 7).
  const ExtractedSurface part = filter.filter(patch(5, kCell, 3 * kCell, 1e-6f, 1.0f));
  EXPECT_EQ(part.cloud.size(), 10u);
  ASSERT_NO_THROW(part.mesh.validate());
  ASSERT_NO_THROW(part.cloud.validate());
  // Faces between the new columns only (1 square x 4 rows x 2), and just their vertices.
  EXPECT_EQ(part.mesh.faces.size(), 8u);
  EXPECT_EQ(part.mesh.vertices.size(), 10u);
  for (const Eigen::Vector3f& p : part.mesh.vertices.positions) EXPECT_GE(p.x(), 6 * kCell);
  const PointProperty* weight = part.cloud.find_property("weight");
  ASSERT_NE(weight, nullptr);
  EXPECT_EQ(weight->values.front(), 3.0f);  // column 3 of that patch, row 0: i + j = 3
  filter.clear();
  EXPECT_EQ(filter.cells(), 0u);
}

TEST(RevisitFilter, RefusesACellSizeThatIsNotPositive) {
  EXPECT_THROW(RevisitFilter(0.0), Error);
  EXPECT_THROW(RevisitFilter(-1.0), Error);
}

}  // namespace
}  // namespace sls::fusion
