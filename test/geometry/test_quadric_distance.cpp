#include "dqo_map/geometry/quadric_distance.h"

#include <gtest/gtest.h>

#include "geometry_checks.h"

namespace dqo {
namespace {

TEST(QuadricDistance, RandomIdentitySymmetryMonotonyClosedForm) {
  for (uint64_t seed = 1; seed <= 20; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    EXPECT_LE(checks::distance_error(seed), checks::kDistanceTolerance);
  }
}

TEST(QuadricDistance, HandComputedValues) {
  const DualQuadric a = DualQuadric::from_params(Eigen::Vector3d(0, 0, 0), Eigen::Matrix3d::Identity(),
                                                 Eigen::Vector3d(1, 2, 3));
  const DualQuadric b = DualQuadric::from_params(Eigen::Vector3d(3, 4, 0), Eigen::Matrix3d::Identity(),
                                                 Eigen::Vector3d(1, 2, 2));
  // ‖Δmu‖ = 5, S = diag(1, 4, 9) vs diag(1, 4, 4): ‖ΔS‖_F = 5.
  EXPECT_NEAR(quadric_distance(a, b, 0.1), std::exp(-1.0), 1e-15);
  // W2² = 25 + (3 − 2)² = 26.
  EXPECT_NEAR(wasserstein_distance_sq(a, b), 26.0, 1e-12);
  EXPECT_NEAR(wasserstein_similarity(a, b, 10.0), std::exp(-std::sqrt(26.0) / 10.0), 1e-15);
  QuadricDistanceParams p;
  p.tau = 0.1;
  EXPECT_NEAR(quadric_similarity(a, b, p), std::exp(-1.0), 1e-15);
}

TEST(QuadricDistance, RotationMatters) {
  // An elongated ellipsoid turned by 90° about z has the same axes but a different shape matrix.
  const DualQuadric a = DualQuadric::from_params(Eigen::Vector3d::Zero(), Eigen::Matrix3d::Identity(),
                                                 Eigen::Vector3d(1.0, 0.2, 0.2));
  const Eigen::Matrix3d Rz = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const DualQuadric b = DualQuadric::from_params(Eigen::Vector3d::Zero(), Rz, a.semi_axes());
  EXPECT_LT(quadric_distance(a, b, 1.0), 0.5);
  // Commuting shapes diag(1, .04, .04) and diag(.04, 1, .04): W2² = 2 (1 − 0.2)².
  EXPECT_NEAR(wasserstein_distance_sq(a, b), 2.0 * 0.64, 1e-12);
}

}  // namespace
}  // namespace dqo
