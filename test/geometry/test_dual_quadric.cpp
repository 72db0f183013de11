#include "dqo_map/geometry/dual_quadric.h"

#include <gtest/gtest.h>

#include "geometry_checks.h"

namespace dqo {
namespace {

TEST(DualQuadric, MatrixRoundTrip) {
  for (uint64_t seed = 1; seed <= 20; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    EXPECT_LE(checks::quadric_round_trip_error(seed), checks::kQuadricRoundTripTolerance);
  }
}

TEST(DualQuadric, TransformAndRejection) {
  for (uint64_t seed = 1; seed <= 20; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    EXPECT_LE(checks::quadric_transform_error(seed), checks::kQuadricRoundTripTolerance);
  }
}

TEST(DualQuadric, KnownSphereAndTangentPlanes) {
  const DualQuadric q =
      DualQuadric::from_params(Eigen::Vector3d(1, 2, 3), Eigen::Matrix3d::Identity(), Eigen::Vector3d(2, 2, 2));
  const Eigen::Matrix4d Q = q.matrix();
  EXPECT_DOUBLE_EQ(Q(3, 3), -1.0);
  EXPECT_TRUE(Q.col(3).head<3>().isApprox(-Eigen::Vector3d(1, 2, 3)));
  // Planes x = 1 ± 2 touch the sphere: piᵀ Q* pi = 0; x = 1 cuts it: > 0; x = 4 misses it: < 0.
  EXPECT_NEAR(Eigen::Vector4d(1, 0, 0, -3).dot(Q * Eigen::Vector4d(1, 0, 0, -3)), 0.0, 1e-12);
  EXPECT_NEAR(Eigen::Vector4d(1, 0, 0, 1).dot(Q * Eigen::Vector4d(1, 0, 0, 1)), 0.0, 1e-12);
  EXPECT_GT(Eigen::Vector4d(1, 0, 0, -1).dot(Q * Eigen::Vector4d(1, 0, 0, -1)), 0.0);
  EXPECT_LT(Eigen::Vector4d(1, 0, 0, -4).dot(Q * Eigen::Vector4d(1, 0, 0, -4)), 0.0);
  EXPECT_NEAR(q.volume(), 4.0 / 3.0 * M_PI * 8.0, 1e-12);
  EXPECT_TRUE(q.shape_matrix().isApprox(4.0 * Eigen::Matrix3d::Identity()));
}

TEST(DualQuadric, DecompositionIsCanonical) {
  // The same matrix decomposed from a rotation whose columns are permuted and negated gives the
  // same parameters: descending axes, proper rotation.
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const DualQuadric a = DualQuadric::from_params(Eigen::Vector3d(0.5, 0, 1), R, Eigen::Vector3d(0.1, 0.3, 0.2));
  Eigen::Matrix3d R2;
  R2 << -R.col(1), R.col(2), -R.col(0);
  const DualQuadric b = DualQuadric::from_params(a.centre(), R2, Eigen::Vector3d(0.3, 0.2, 0.1));
  const auto da = DualQuadric::from_matrix(a.matrix());
  const auto db = DualQuadric::from_matrix(-3.0 * b.matrix());
  ASSERT_TRUE(da && db);
  EXPECT_LT((da->rotation() - db->rotation()).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((da->semi_axes() - Eigen::Vector3d(0.3, 0.2, 0.1)).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_NEAR(da->rotation().determinant(), 1.0, 1e-12);
}

TEST(DualQuadric, RejectsInvalid) {
  EXPECT_FALSE(DualQuadric::from_matrix(Eigen::Matrix4d::Zero()));
  EXPECT_FALSE(is_ellipsoid(Eigen::Matrix4d::Zero()));
  // Degenerate (flat) ellipsoid: one zero axis.
  const Eigen::Matrix4d flat = Eigen::Vector4d(1.0, 1.0, 0.0, -1.0).asDiagonal();
  EXPECT_FALSE(is_ellipsoid(flat));
  // diag(1, 1, 1, +1) has no real points.
  EXPECT_FALSE(is_ellipsoid(Eigen::Matrix4d::Identity()));
  EXPECT_TRUE(is_ellipsoid(Eigen::Vector4d(1.0, 4.0, 9.0, -1.0).asDiagonal().toDenseMatrix()));
  const DualQuadric nan_centre = DualQuadric::from_params(Eigen::Vector3d(std::nan(""), 0, 0),
                                                          Eigen::Matrix3d::Identity(), Eigen::Vector3d::Ones());
  EXPECT_FALSE(nan_centre.is_valid());
  Eigen::Matrix3d reflection = Eigen::Matrix3d::Identity();
  reflection(2, 2) = -1.0;
  EXPECT_FALSE(DualQuadric::from_params(Eigen::Vector3d::Zero(), reflection, Eigen::Vector3d::Ones()).is_valid());
}

}  // namespace
}  // namespace dqo
