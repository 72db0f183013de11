#include "dqo_map/geometry/se3.h"

#include <gtest/gtest.h>

#include "geometry_checks.h"

namespace dqo {
namespace {

TEST(SE3, RandomComposeInverseExpLog) {
  for (uint64_t seed = 1; seed <= 20; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    EXPECT_LE(checks::se3_error(seed), checks::kSe3Tolerance);
  }
}

TEST(SE3, IdentityAndConventions) {
  const Eigen::Vector3d p(1.0, 2.0, 3.0);
  EXPECT_TRUE((SE3::identity() * p).isApprox(p));
  // T_wc of a camera at (0, 0, 1) turned 90° about z: its x axis is the world's y axis.
  const Eigen::Matrix3d R_wc = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const SE3 T_wc = SE3::from_rotation_translation(R_wc, Eigen::Vector3d(0, 0, 1));
  EXPECT_TRUE((T_wc * Eigen::Vector3d(1, 0, 0)).isApprox(Eigen::Vector3d(0, 1, 1)));
  EXPECT_TRUE((T_wc.inverse() * Eigen::Vector3d(0, 1, 1)).isApprox(Eigen::Vector3d(1, 0, 0)));
}

TEST(SE3, ExpOfSmallAndHalfTurnRotations) {
  Vector6d xi = Vector6d::Zero();
  xi << 0.1, -0.2, 0.3, 1e-12, -2e-12, 0.5e-12;
  EXPECT_LT((SE3::exp(xi).log() - xi).norm(), 1e-12);
  xi << 0.1, -0.2, 0.3, 0.0, 0.0, M_PI - 1e-6;
  EXPECT_LT((SE3::exp(xi).log() - xi).norm(), 1e-6);
}

}  // namespace
}  // namespace dqo
