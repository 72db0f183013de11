#pragma once
// Rigid-body transform in 3D: a unit quaternion and a translation.
//
// Naming: `T_ab` maps points from frame b to frame a (p_a = T_ab * p_b), so T_wc maps camera to world
// and T_wc * T_cb chains. The quaternion is kept normalised on every construction so that repeated
// composition cannot drift away from SO(3).

#include <cmath>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace dqo {

using Vector6d = Eigen::Matrix<double, 6, 1>;

// The 3x3 matrix of the cross product: skew(a) * b = a x b.
inline Eigen::Matrix3d skew(const Eigen::Vector3d& a) {
  Eigen::Matrix3d m;
  m << 0.0, -a.z(), a.y(),  //
      a.z(), 0.0, -a.x(),   //
      -a.y(), a.x(), 0.0;
  return m;
}

class SE3 {
 public:
  SE3() : q_(Eigen::Quaterniond::Identity()), t_(Eigen::Vector3d::Zero()) {}
  SE3(const Eigen::Quaterniond& q, const Eigen::Vector3d& t) : q_(q.normalized()), t_(t) {}

  static SE3 identity() { return SE3(); }

  // R must be a rotation; it is re-orthonormalised through the quaternion.
  static SE3 from_rotation_translation(const Eigen::Matrix3d& R, const Eigen::Vector3d& t) {
    return SE3(Eigen::Quaterniond(R), t);
  }

  // The bottom row of T is ignored (assumed [0 0 0 1]).
  static SE3 from_matrix(const Eigen::Matrix4d& T) {
    return from_rotation_translation(T.topLeftCorner<3, 3>(), T.topRightCorner<3, 1>());
  }

  Eigen::Matrix4d matrix() const {
    Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
    T.topLeftCorner<3, 3>() = q_.toRotationMatrix();
    T.topRightCorner<3, 1>() = t_;
    return T;
  }
  // The top three rows of matrix(): [R | t].
  Eigen::Matrix<double, 3, 4> matrix3x4() const {
    Eigen::Matrix<double, 3, 4> T;
    T.leftCols<3>() = q_.toRotationMatrix();
    T.col(3) = t_;
    return T;
  }
  Eigen::Matrix3d rotation() const { return q_.toRotationMatrix(); }
  const Eigen::Quaterniond& quaternion() const { return q_; }
  const Eigen::Vector3d& translation() const { return t_; }

  SE3 inverse() const {
    const Eigen::Quaterniond q_inv = q_.conjugate();
    return SE3(q_inv, -(q_inv * t_));
  }

  // Composition: (T_ab * T_bc) maps c to a.
  SE3 operator*(const SE3& other) const { return SE3(q_ * other.q_, q_ * other.t_ + t_); }

  // Transforms a point.
  Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return q_ * p + t_; }

  // Exponential map of xi = [rho; phi] (translation part first, then the rotation vector), with the
  // left Jacobian V so that exp and log are exact inverses, not just the rotation part.
  static SE3 exp(const Vector6d& xi) {
    const Eigen::Vector3d rho = xi.head<3>();
    const Eigen::Vector3d phi = xi.tail<3>();
    const double theta = phi.norm();
    Eigen::Quaterniond q;
    if (theta < 1e-10) {
      // Second-order expansion keeps the quaternion accurate where sin(theta)/theta is 0/0.
      q = Eigen::Quaterniond(1.0, 0.5 * phi.x(), 0.5 * phi.y(), 0.5 * phi.z());
    } else {
      q = Eigen::Quaterniond(Eigen::AngleAxisd(theta, phi / theta));
    }
    return SE3(q, left_jacobian(phi) * rho);
  }

  Vector6d log() const {
    // Pick the quaternion with w >= 0 so the angle is in [0, pi].
    Eigen::Quaterniond q = q_;
    if (q.w() < 0.0) q.coeffs() = -q.coeffs();
    const double vnorm = q.vec().norm();
    Eigen::Vector3d phi;
    if (vnorm < 1e-12) {
      phi = 2.0 * q.vec() / q.w();
    } else {
      const double theta = 2.0 * std::atan2(vnorm, q.w());
      phi = theta * q.vec() / vnorm;
    }
    Vector6d xi;
    xi.head<3>() = left_jacobian_inverse(phi) * t_;
    xi.tail<3>() = phi;
    return xi;
  }

  // V(phi) = I + (1 - cos t)/t^2 [phi]x + (t - sin t)/t^3 [phi]x^2, with Taylor forms near zero.
  static Eigen::Matrix3d left_jacobian(const Eigen::Vector3d& phi) {
    const double t2 = phi.squaredNorm();
    const Eigen::Matrix3d W = skew(phi);
    double a, b;
    if (t2 < 1e-8) {
      a = 0.5 - t2 / 24.0;
      b = 1.0 / 6.0 - t2 / 120.0;
    } else {
      const double t = std::sqrt(t2);
      a = (1.0 - std::cos(t)) / t2;
      b = (t - std::sin(t)) / (t2 * t);
    }
    return Eigen::Matrix3d::Identity() + a * W + b * W * W;
  }

  // V^-1(phi) = I - 1/2 [phi]x + (1/t^2)(1 - t sin t / (2 (1 - cos t))) [phi]x^2.
  static Eigen::Matrix3d left_jacobian_inverse(const Eigen::Vector3d& phi) {
    const double t2 = phi.squaredNorm();
    const Eigen::Matrix3d W = skew(phi);
    double c;
    if (t2 < 1e-8) {
      c = 1.0 / 12.0 + t2 / 720.0;
    } else {
      const double t = std::sqrt(t2);
      c = (1.0 - t * std::sin(t) / (2.0 * (1.0 - std::cos(t)))) / t2;
    }
    return Eigen::Matrix3d::Identity() - 0.5 * W + c * W * W;
  }

 private:
  Eigen::Quaterniond q_;
  Eigen::Vector3d t_;
};

}  // namespace dqo
