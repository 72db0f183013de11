#include "dqo_map/geometry/quadric_distance.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

namespace dqo {
namespace {

// The square root of a symmetric positive semi-definite matrix; eigenvalues that round-off made
// slightly negative count as 0.
Eigen::Matrix3d psd_sqrt(const Eigen::Matrix3d& A) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(0.5 * (A + A.transpose()));
  const Eigen::Vector3d s = eig.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  return eig.eigenvectors() * s.asDiagonal() * eig.eigenvectors().transpose();
}

}  // namespace

double quadric_distance(const DualQuadric& a, const DualQuadric& b, double tau) {
  const double d_centre = (a.centre() - b.centre()).norm();
  const double d_shape = (a.shape_matrix() - b.shape_matrix()).norm();  // Frobenius
  return std::exp(-tau * (d_centre + d_shape));
}

double wasserstein_distance_sq(const DualQuadric& a, const DualQuadric& b) {
  const Eigen::Matrix3d Sa = a.shape_matrix();
  const Eigen::Matrix3d Sb = b.shape_matrix();
  const Eigen::Matrix3d Sb_half = psd_sqrt(Sb);
  // tr(M^½) is the sum of the square roots of M's eigenvalues: no need to rebuild M^½.
  const Eigen::Matrix3d M = Sb_half * Sa * Sb_half;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(0.5 * (M + M.transpose()),
                                                           Eigen::EigenvaluesOnly);
  const double trace_cross = eig.eigenvalues().cwiseMax(0.0).cwiseSqrt().sum();
  const double trace_sum = Sa.trace() + Sb.trace();
  double shape_term = trace_sum - 2.0 * trace_cross;
  // The difference cancels to round-off of order eps·tr(Sa + Sb) for equal shapes; left as is, its
  // square root (the similarity takes one) would turn 1e-16 into 1e-8.
  if (shape_term < 64.0 * std::numeric_limits<double>::epsilon() * trace_sum) shape_term = 0.0;
  return (a.centre() - b.centre()).squaredNorm() + shape_term;
}

double wasserstein_similarity(const DualQuadric& a, const DualQuadric& b, double C) {
  return std::exp(-std::sqrt(wasserstein_distance_sq(a, b)) / C);
}

double quadric_similarity(const DualQuadric& a, const DualQuadric& b,
                          const QuadricDistanceParams& params) {
  switch (params.kind) {
    case QuadricDistanceKind::kQD: return quadric_distance(a, b, params.tau);
    case QuadricDistanceKind::kWasserstein: return wasserstein_similarity(a, b, params.wasserstein_c);
  }
  return 0.0;
}

}  // namespace dqo
