#include "dqo_map/geometry/dual_quadric.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

namespace dqo {
namespace {

// |Q*(3,3)| below this fraction of the largest entry means the quadric touches the plane at infinity
// (a paraboloid or a cylinder), whose centre is not defined.
constexpr double kMinRelativeQ33 = 1e-12;
// Shape eigenvalues below this fraction of the largest are a flat (degenerate) ellipsoid.
constexpr double kMinRelativeEigenvalue = 1e-14;

struct Normalised {
  Eigen::Vector3d centre;
  Eigen::Matrix3d shape;
};

// Q* / (−Q*(3,3)) gives [S − mu muᵀ, −mu; −muᵀ, −1]; read mu and S from it.
std::optional<Normalised> normalise(const Eigen::Matrix4d& Qstar) {
  if (!Qstar.allFinite()) return std::nullopt;
  const double scale = Qstar.cwiseAbs().maxCoeff();
  if (!(scale > 0.0) || std::abs(Qstar(3, 3)) <= kMinRelativeQ33 * scale) return std::nullopt;
  Eigen::Matrix4d Q = Qstar / (-Qstar(3, 3));
  Q = 0.5 * (Q + Q.transpose()).eval();  // tolerate round-off asymmetry of the caller's product
  Normalised n;
  n.centre = -Q.topRightCorner<3, 1>();
  n.shape = Q.topLeftCorner<3, 3>() + n.centre * n.centre.transpose();
  return n;
}

}  // namespace

DualQuadric::DualQuadric()
    : centre_(Eigen::Vector3d::Zero()),
      rotation_(Eigen::Matrix3d::Identity()),
      semi_axes_(Eigen::Vector3d::Ones()) {}

DualQuadric DualQuadric::from_params(const Eigen::Vector3d& centre, const Eigen::Matrix3d& rotation,
                                     const Eigen::Vector3d& semi_axes) {
  DualQuadric q;
  q.centre_ = centre;
  q.rotation_ = rotation;
  q.semi_axes_ = semi_axes;
  return q;
}

std::optional<DualQuadric> DualQuadric::from_matrix(const Eigen::Matrix4d& Qstar) {
  const std::optional<Normalised> n = normalise(Qstar);
  if (!n) return std::nullopt;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(n->shape);
  if (eig.info() != Eigen::Success) return std::nullopt;
  const Eigen::Vector3d lambda = eig.eigenvalues();  // ascending
  if (!(lambda(0) > kMinRelativeEigenvalue * std::abs(lambda(2)))) return std::nullopt;

  // Descending order so the first axis is the longest.
  Eigen::Matrix3d R;
  Eigen::Vector3d axes;
  for (int i = 0; i < 3; ++i) {
    R.col(i) = eig.eigenvectors().col(2 - i);
    axes(i) = std::sqrt(lambda(2 - i));
  }
  // Eigenvectors have arbitrary sign; fix it so the decomposition is a function of the matrix.
  for (int i = 0; i < 2; ++i) {
    Eigen::Index k;
    R.col(i).cwiseAbs().maxCoeff(&k);
    if (R(k, i) < 0.0) R.col(i) = -R.col(i);
  }
  R.col(2) = R.col(0).cross(R.col(1));
  return from_params(n->centre, R, axes);
}

Eigen::Matrix4d DualQuadric::matrix() const {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = rotation_;
  T.topRightCorner<3, 1>() = centre_;
  Eigen::Vector4d d;
  d << semi_axes_.cwiseAbs2(), -1.0;
  return T * d.asDiagonal() * T.transpose();
}

Eigen::Matrix3d DualQuadric::shape_matrix() const {
  return rotation_ * semi_axes_.cwiseAbs2().asDiagonal() * rotation_.transpose();
}

DualQuadric DualQuadric::transformed(const SE3& T_ba) const {
  return from_params(T_ba * centre_, T_ba.rotation() * rotation_, semi_axes_);
}

bool DualQuadric::is_valid() const {
  if (!centre_.allFinite() || !rotation_.allFinite() || !semi_axes_.allFinite()) return false;
  if (!(semi_axes_.minCoeff() > 0.0)) return false;
  const double orthonormality = (rotation_.transpose() * rotation_ - Eigen::Matrix3d::Identity())
                                    .cwiseAbs()
                                    .maxCoeff();
  return orthonormality < 1e-6 && rotation_.determinant() > 0.0;
}

double DualQuadric::volume() const {
  constexpr double kPi = 3.14159265358979323846;
  return 4.0 / 3.0 * kPi * semi_axes_.prod();
}

bool is_ellipsoid(const Eigen::Matrix4d& Qstar) {
  const std::optional<Normalised> n = normalise(Qstar);
  if (!n) return false;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(n->shape, Eigen::EigenvaluesOnly);
  if (eig.info() != Eigen::Success) return false;
  const Eigen::Vector3d lambda = eig.eigenvalues();
  return lambda(0) > kMinRelativeEigenvalue * std::abs(lambda(2));
}

}  // namespace dqo
