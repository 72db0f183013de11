// The box fit recovers an upright box from the exact boxes of its projected corners, and prefers
// the ellipsoid where the detections are an ellipsoid's.
#include <cmath>
#include <functional>
#include <gtest/gtest.h>
#include "../../src/objects/box_fit.h"
#include "dqo_map/geometry/oriented_box.h"
#include "object_test_util.h"

namespace dqo::objects {
namespace {

Box2d corner_box(const OrientedBox& b, const PinholeCamera& camera, const SE3& T_wc) {
  Box2d out{1e9, 1e9, -1e9, -1e9};
  for (const Eigen::Vector3d& p : box_corners(b)) {
    const Eigen::Vector2d uv = camera.project(T_wc.inverse() * p);
    out.x_min = std::min(out.x_min, uv.x());
    out.y_min = std::min(out.y_min, uv.y());
    out.x_max = std::max(out.x_max, uv.x());
    out.y_max = std::max(out.y_max, uv.y());
  }
  return out;
}

std::vector<BoxObservation> views_around(const Eigen::Vector3d& target, const PinholeCamera& camera,
                                         const std::function<Box2d(const SE3&)>& box_of) {
  std::vector<BoxObservation> views;
  for (int k = 0; k < 8; ++k) {
    const double a = 0.35 * k;
    const SE3 T_wc = test::look_at(target + Eigen::Vector3d(1.2 * std::cos(a), 1.2 * std::sin(a), 0.6), target);
    BoxObservation v;
    v.P = camera.projection_matrix(T_wc.inverse());
    v.box = box_of(T_wc);
    v.width = camera.width;
    v.height = camera.height;
    views.push_back(v);
  }
  return views;
}

TEST(BoxFit, RecoversAnUprightBoxFromItsCornerBoxes) {
  const PinholeCamera camera = test::test_camera();
  OrientedBox gt;
  gt.centre = Eigen::Vector3d(0.2, -0.1, 0.75);
  gt.rotation = Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  gt.half_extents = Eigen::Vector3d(0.11, 0.08, 0.02);  // a book lying flat
  const auto views = views_around(gt.centre, camera, [&](const SE3& T) { return corner_box(gt, camera, T); });
  // Start from a rough ellipsoid: shifted, turned and too large, as the conic fit leaves it.
  const DualQuadric start = DualQuadric::from_params(
      gt.centre + Eigen::Vector3d(0.01, -0.01, 0.01),
      Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix(), Eigen::Vector3d(0.14, 0.11, 0.05));
  BoxFitParams params;
  params.max_iterations = 100;
  const BoxFitResult r = fit_box(start, views, params);
  ASSERT_TRUE(r.ok);
  EXPECT_LT(r.final_cost, 1e-3);
  EXPECT_TRUE(r.better_than_ellipsoid);
  EXPECT_GT(iou_3d(r.box, gt), 0.95);
  EXPECT_LT((r.box.centre - gt.centre).norm(), 5e-3);
}

TEST(BoxFit, AnEllipsoidsOwnDetectionsPreferTheEllipsoid) {
  const PinholeCamera camera = test::test_camera();
  const DualQuadric q = DualQuadric::from_params(
      Eigen::Vector3d(0.0, 0.0, 0.8), Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix(),
      Eigen::Vector3d(0.12, 0.07, 0.09));
  const auto views = views_around(q.centre(), camera, [&](const SE3& T) { return *test::exact_box(q, camera, T); });
  const BoxFitResult r = fit_box(q, views, BoxFitParams());
  ASSERT_TRUE(r.ok);
  EXPECT_LT(r.ellipsoid_cost, 1e-9);
  EXPECT_FALSE(r.better_than_ellipsoid);
}

}  // namespace
}  // namespace dqo::objects
