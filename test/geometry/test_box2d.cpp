#include "dqo_map/geometry/box2d.h"

#include <gtest/gtest.h>

#include "geometry_checks.h"

namespace dqo {
namespace {

TEST(Box2d, RandomIouAgainstCellCount) {
  for (uint64_t seed = 1; seed <= 50; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    EXPECT_LE(checks::box_iou_error(seed), checks::kBoxTolerance);
  }
}

TEST(Box2d, HandComputedIou) {
  const Box2d a{0, 0, 10, 10}, b{5, 5, 15, 20};
  // Intersection 5 x 5 = 25, union 100 + 150 − 25 = 225.
  EXPECT_DOUBLE_EQ(iou(a, b), 25.0 / 225.0);
  EXPECT_DOUBLE_EQ(iou(b, a), 25.0 / 225.0);
  EXPECT_DOUBLE_EQ(iou(a, a), 1.0);
  EXPECT_DOUBLE_EQ(iou(a, Box2d{10, 0, 20, 10}), 0.0);  // touching
  EXPECT_DOUBLE_EQ(iou(a, Box2d{30, 30, 40, 40}), 0.0);
  EXPECT_DOUBLE_EQ(iou(Box2d{}, Box2d{}), 0.0);  // no area: no NaN
  EXPECT_DOUBLE_EQ(overlap_ratio(a, b), 25.0 / 150.0);
  EXPECT_DOUBLE_EQ(overlap_ratio(Box2d{0, 0, 100, 100}, a), 1.0);
  EXPECT_DOUBLE_EQ(overlap_ratio(a, Box2d{}), 0.0);
}

TEST(Box2d, ClipBorderAndValidity) {
  const Box2d b{-10, 5, 700, 300};
  const Box2d c = b.clip(640, 480);
  EXPECT_DOUBLE_EQ(c.x_min, 0.0);
  EXPECT_DOUBLE_EQ(c.x_max, 640.0);
  EXPECT_DOUBLE_EQ(c.area(), 640.0 * 295.0);
  EXPECT_FALSE(Box2d({700, 10, 800, 20}).clip(640, 480).valid());
  EXPECT_DOUBLE_EQ(Box2d({700, 10, 800, 20}).clip(640, 480).area(), 0.0);
  EXPECT_TRUE(Box2d({3, 100, 200, 200}).touches_border(640, 480, 5.0));
  EXPECT_FALSE(Box2d({6, 6, 634, 474}).touches_border(640, 480, 5.0));
  const auto edges = Box2d({100, 2, 636, 200}).edges_touching_border(640, 480, 5.0);
  EXPECT_FALSE(edges[0]);
  EXPECT_TRUE(edges[1]);
  EXPECT_TRUE(edges[2]);
  EXPECT_FALSE(edges[3]);
  EXPECT_FALSE(Box2d({0, 0, std::nan(""), 1}).valid());
  EXPECT_FALSE(Box2d({5, 0, 5, 1}).valid());
  EXPECT_TRUE(Box2d({1, 2, 3, 4}).centre().isApprox(Eigen::Vector2d(2, 3)));
}

TEST(Box2d, EdgeLinesPassThroughTheEdges) {
  const Box2d b{10, 20, 110, 220};
  const auto lines = b.edge_lines();
  EXPECT_DOUBLE_EQ(lines[0].dot(Eigen::Vector3d(10, 57, 1)), 0.0);
  EXPECT_DOUBLE_EQ(lines[1].dot(Eigen::Vector3d(110, -3, 1)), 0.0);
  EXPECT_DOUBLE_EQ(lines[2].dot(Eigen::Vector3d(42, 20, 1)), 0.0);
  EXPECT_DOUBLE_EQ(lines[3].dot(Eigen::Vector3d(0, 220, 1)), 0.0);
}

TEST(Box2d, PlaneFromLineContainsBackProjectedRays) {
  for (uint64_t seed = 1; seed <= 20; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    EXPECT_LE(checks::plane_from_line_error(seed), checks::kPlaneTolerance);
  }
}

}  // namespace
}  // namespace dqo
