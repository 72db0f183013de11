#include "dqo_map/geometry/pinhole_camera.h"

#include <gtest/gtest.h>

#include "geometry_checks.h"

namespace dqo {
namespace {

TEST(PinholeCamera, ProjectBackProjectAndProjectionMatrix) {
  for (uint64_t seed = 1; seed <= 20; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    EXPECT_LE(checks::camera_error(seed), checks::kCameraTolerancePx);
  }
}

TEST(PinholeCamera, KnownValues) {
  const PinholeCamera cam = checks::test_camera();
  const Eigen::Vector2d uv = cam.project(Eigen::Vector3d(0.2, -0.1, 2.0));
  EXPECT_DOUBLE_EQ(uv.x(), 525.0 * 0.1 + 319.5);
  EXPECT_DOUBLE_EQ(uv.y(), -525.0 * 0.05 + 239.5);
  EXPECT_TRUE(cam.K().isApprox((Eigen::Matrix3d() << 525, 0, 319.5, 0, 525, 239.5, 0, 0, 1).finished()));
  EXPECT_TRUE(cam.in_image(Eigen::Vector2d(0.0, 480.0)));
  EXPECT_FALSE(cam.in_image(Eigen::Vector2d(-0.1, 10.0)));
  EXPECT_FALSE(cam.in_image(Eigen::Vector2d(10.0, 480.5)));
}

}  // namespace
}  // namespace dqo
