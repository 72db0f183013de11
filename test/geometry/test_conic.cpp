#include "dqo_map/geometry/conic.h"

#include <gtest/gtest.h>

#include "geometry_checks.h"

namespace dqo {
namespace {

TEST(Conic, BoxMatchesSampledSilhouette) {
  for (uint64_t seed = 1; seed <= 10; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    EXPECT_LE(checks::conic_box_error(seed), checks::kConicBoxTolerancePx);
  }
}

TEST(Conic, SphereOnTheOpticalAxis) {
  // A sphere of radius r at depth z on the axis: its silhouette is a circle of radius
  // f tan(asin(r / z)) = f r / sqrt(z² − r²), centred on the principal point.
  const PinholeCamera cam = checks::test_camera();
  const double r = 0.5, z = 2.0;
  const DualQuadric q =
      DualQuadric::from_params(Eigen::Vector3d(0, 0, z), Eigen::Matrix3d::Identity(), Eigen::Vector3d(r, r, r));
  const auto pb = projected_box(q, cam, SE3::identity());
  ASSERT_TRUE(pb);
  const double radius = cam.fx * r / std::sqrt(z * z - r * r);
  EXPECT_NEAR(pb->unclipped.x_min, cam.cx - radius, 1e-9);
  EXPECT_NEAR(pb->unclipped.x_max, cam.cx + radius, 1e-9);
  EXPECT_NEAR(pb->unclipped.y_min, cam.cy - radius, 1e-9);
  EXPECT_NEAR(pb->unclipped.y_max, cam.cy + radius, 1e-9);
  EXPECT_DOUBLE_EQ(pb->fraction_in_image, 1.0);
}

// The ellipse of a random object's conic: its bounding box is the conic's box (an ellipse of
// centre c and shape M spans c ± sqrt(diag M)), and its points x satisfy xᵀ C x = 0 for the point
// conic C = C*⁻¹.
TEST(Conic, EllipseAgreesWithTheBoxAndThePointConic) {
  std::mt19937_64 rng(5);
  const PinholeCamera cam = checks::test_camera();
  int tried = 0;
  for (int i = 0; i < 20; ++i) {
    const DualQuadric q = checks::random_quadric(rng);
    checks::SyntheticView view;
    if (!checks::random_view(rng, q, cam, checks::uniform(rng, -3.0, 3.0), 5.0, &view)) continue;
    ++tried;
    const Eigen::Matrix3d Cstar = project_quadric(q, cam.projection_matrix(view.T_cw));
    const auto e = conic_ellipse(Cstar);
    ASSERT_TRUE(e);
    EXPECT_GE(e->semi_axes(0), e->semi_axes(1));
    const double ca = std::cos(e->angle), sa = std::sin(e->angle);
    const double half_w = std::hypot(e->semi_axes(0) * ca, e->semi_axes(1) * sa);
    const double half_h = std::hypot(e->semi_axes(0) * sa, e->semi_axes(1) * ca);
    EXPECT_NEAR(e->centre.x() - half_w, view.box.x_min, 1e-6);
    EXPECT_NEAR(e->centre.x() + half_w, view.box.x_max, 1e-6);
    EXPECT_NEAR(e->centre.y() - half_h, view.box.y_min, 1e-6);
    EXPECT_NEAR(e->centre.y() + half_h, view.box.y_max, 1e-6);
    const Eigen::Matrix3d C = Cstar.inverse();
    for (double t = 0.0; t < 6.28; t += 0.5) {
      const Eigen::Vector2d p = e->centre + e->semi_axes(0) * std::cos(t) * Eigen::Vector2d(ca, sa) +
                                e->semi_axes(1) * std::sin(t) * Eigen::Vector2d(-sa, ca);
      const Eigen::Vector3d x(p.x(), p.y(), 1.0);
      EXPECT_NEAR(x.dot(C * x) / (C.norm() * x.squaredNorm()), 0.0, 1e-9);
    }
  }
  EXPECT_GE(tried, 10);
  EXPECT_FALSE(conic_ellipse(Eigen::Matrix3d::Constant(std::nan(""))));
}

TEST(Conic, BehindOrStraddlingTheCameraFails) {
  const PinholeCamera cam = checks::test_camera();
  const auto sphere_at = [](double z) {
    return DualQuadric::from_params(Eigen::Vector3d(0.1, 0, z), Eigen::Matrix3d::Identity(),
                                    Eigen::Vector3d(0.3, 0.3, 0.3));
  };
  EXPECT_TRUE(in_front_of_camera(sphere_at(0.31), SE3::identity()));
  EXPECT_FALSE(in_front_of_camera(sphere_at(0.29), SE3::identity()));
  EXPECT_FALSE(in_front_of_camera(sphere_at(0.5), SE3::identity(), 0.3));
  EXPECT_FALSE(in_front_of_camera(sphere_at(-2.0), SE3::identity()));
  EXPECT_FALSE(projected_box(sphere_at(-2.0), cam, SE3::identity()));
  // Straddling the camera plane: the conic is a hyperbola, there is no bounded box.
  EXPECT_FALSE(conic_bounding_box(project_quadric(sphere_at(0.0), cam.projection_matrix(SE3::identity()))));
  EXPECT_FALSE(conic_bounding_box(Eigen::Matrix3d::Constant(std::nan(""))));
}

TEST(Conic, PartlyOutsideTheImage) {
  const PinholeCamera cam = checks::test_camera();
  // Centre projects onto the left border: about half the box is inside.
  const double z = 3.0;
  const double x = (0.0 - cam.cx) / cam.fx * z;
  const DualQuadric q =
      DualQuadric::from_params(Eigen::Vector3d(x, 0, z), Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.2, 0.2, 0.2));
  const auto pb = projected_box(q, cam, SE3::identity());
  ASSERT_TRUE(pb);
  EXPECT_DOUBLE_EQ(pb->box.x_min, 0.0);
  EXPECT_GT(pb->unclipped.x_min, -200.0);
  EXPECT_LT(pb->unclipped.x_min, 0.0);
  EXPECT_NEAR(pb->fraction_in_image, 0.5, 0.05);
  EXPECT_NEAR(pb->fraction_in_image, pb->box.area() / pb->unclipped.area(), 1e-12);
}

}  // namespace
}  // namespace dqo
