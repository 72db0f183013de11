#pragma once
// An object as an ellipsoid, kept in two equivalent forms (METHOD.md §1):
//   parameters  centre mu (world), rotation R (columns = the ellipsoid's axes in world), semi-axes
//               (a, b, c) > 0;
//   dual matrix Q* = T diag(a², b², c², −1) Tᵀ with T = [R mu; 0 1], which equals
//               [S − mu muᵀ, −mu; −muᵀ, −1] with S = R diag(a², b², c²) Rᵀ the "shape matrix".
// A plane pi is tangent to the ellipsoid iff piᵀ Q* pi = 0. S has the same form as a 3D Gaussian's
// covariance, which is what the quadric distances compare.

#include <optional>

#include <Eigen/Core>

#include "dqo_map/geometry/se3.h"

namespace dqo {

class DualQuadric {
 public:
  // The unit sphere at the origin.
  DualQuadric();

  // No checks here (R is assumed a proper rotation, the axes positive); see is_valid().
  static DualQuadric from_params(const Eigen::Vector3d& centre, const Eigen::Matrix3d& rotation,
                                 const Eigen::Vector3d& semi_axes);

  // Decomposes any dual ellipsoid matrix, known up to a nonzero scale (either sign). Returns nullopt
  // when Q* is not finite, its (3,3) entry vanishes (the quadric touches the plane at infinity) or
  // it is not an ellipsoid. The decomposition is canonical: semi-axes in descending order, rotation
  // proper, the first two axes with their largest-magnitude component positive (the third follows
  // from the right-hand rule), so equal matrices give equal parameters unless two axes are equal.
  static std::optional<DualQuadric> from_matrix(const Eigen::Matrix4d& Qstar);

  const Eigen::Vector3d& centre() const { return centre_; }
  const Eigen::Matrix3d& rotation() const { return rotation_; }
  const Eigen::Vector3d& semi_axes() const { return semi_axes_; }

  // Q*, normalised so that Q*(3,3) = −1 (conic_bounding_box relies on this sign).
  Eigen::Matrix4d matrix() const;

  // S = R diag(a², b², c²) Rᵀ.
  Eigen::Matrix3d shape_matrix() const;

  // The same ellipsoid seen from another frame: for points p_b = T_ba p_a, Q*_b = T_ba Q*_a T_baᵀ.
  DualQuadric transformed(const SE3& T_ba) const;

  // Finite entries, positive semi-axes, rotation orthonormal with det +1 (to 1e-6).
  bool is_valid() const;

  double volume() const;

 private:
  Eigen::Vector3d centre_;
  Eigen::Matrix3d rotation_;
  Eigen::Vector3d semi_axes_;
};

// True when Q* (up to scale) is a real, non-degenerate ellipsoid: finite, (3,3) entry away from zero,
// and after normalising to Q*(3,3) = −1 the matrix Q*₃ₓ₃ + mu muᵀ positive definite.
bool is_ellipsoid(const Eigen::Matrix4d& Qstar);

}  // namespace dqo
