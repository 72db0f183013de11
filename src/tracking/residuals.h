#pragma once
// Ceres residuals of the tracker, shared by the pose-only optimiser and local bundle adjustment.
//
// A camera pose is two parameter blocks: q_cw (4, Eigen's x y z w order, on
// ceres::EigenQuaternionManifold) and t_cw (3), so that p_c = R(q_cw) p_w + t_cw. Every residual
// is whitened (divided by its σ), so its squared norm is a chi-square value.

#include <ceres/autodiff_cost_function.h>
#include <ceres/cost_function.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"

namespace dqo::tracking {

struct Intrinsics {
  double fx, fy, cx, cy;
  explicit Intrinsics(const PinholeCamera& c) : fx(c.fx), fy(c.fy), cx(c.cx), cy(c.cy) {}
};

// p_c = R(q_cw) p_w + t_cw.
template <typename T>
Eigen::Matrix<T, 3, 1> world_to_camera(const T* q_cw, const T* t_cw,
                                       const Eigen::Matrix<T, 3, 1>& p_w) {
  const Eigen::Map<const Eigen::Quaternion<T>> q(q_cw);
  const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t(t_cw);
  return q * p_w + t;
}

// Reprojection: r = (π(p_c) − uv) / σ, σ = the keypoint level's scale (one pixel at level 0).
// π(p) = (fx x/z + cx, fy y/z + cy).
template <typename T>
void reprojection_residual(const Intrinsics& K, const Eigen::Vector2d& uv, double inv_sigma,
                           const Eigen::Matrix<T, 3, 1>& p_c, T* r) {
  const T inv_z = T(1.0) / p_c.z();
  r[0] = (T(K.fx) * p_c.x() * inv_z + T(K.cx) - T(uv.x())) * T(inv_sigma);
  r[1] = (T(K.fy) * p_c.y() * inv_z + T(K.cy) - T(uv.y())) * T(inv_sigma);
}

// Pose only, the point fixed.
struct ReprojectionCost {
  ReprojectionCost(const Intrinsics& K, const Eigen::Vector3d& p_w, const Eigen::Vector2d& uv,
                   double inv_sigma)
      : K_(K), p_w_(p_w), uv_(uv), inv_sigma_(inv_sigma) {}

  template <typename T>
  bool operator()(const T* q_cw, const T* t_cw, T* r) const {
    const Eigen::Matrix<T, 3, 1> p_c = world_to_camera(q_cw, t_cw, p_w_.cast<T>().eval());
    reprojection_residual(K_, uv_, inv_sigma_, p_c, r);
    return true;
  }

  static ceres::CostFunction* Create(const Intrinsics& K, const Eigen::Vector3d& p_w,
                                     const Eigen::Vector2d& uv, double inv_sigma) {
    return new ceres::AutoDiffCostFunction<ReprojectionCost, 2, 4, 3>(
        new ReprojectionCost(K, p_w, uv, inv_sigma));
  }

  Intrinsics K_;
  Eigen::Vector3d p_w_;
  Eigen::Vector2d uv_;
  double inv_sigma_;
};

// Depth: r = (z_c − z) / σ_z with σ_z = k z² (the sensor's noise grows with the square of the
// depth), pose only.
struct DepthCost {
  DepthCost(const Eigen::Vector3d& p_w, double depth, double inv_sigma)
      : p_w_(p_w), depth_(depth), inv_sigma_(inv_sigma) {}

  template <typename T>
  bool operator()(const T* q_cw, const T* t_cw, T* r) const {
    const Eigen::Matrix<T, 3, 1> p_c = world_to_camera(q_cw, t_cw, p_w_.cast<T>().eval());
    r[0] = (p_c.z() - T(depth_)) * T(inv_sigma_);
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector3d& p_w, double depth, double inv_sigma) {
    return new ceres::AutoDiffCostFunction<DepthCost, 1, 4, 3>(
        new DepthCost(p_w, depth, inv_sigma));
  }

  Eigen::Vector3d p_w_;
  double depth_;
  double inv_sigma_;
};

// Bundle adjustment: the same two residuals with the point as a third parameter block.
struct BaReprojectionCost {
  BaReprojectionCost(const Intrinsics& K, const Eigen::Vector2d& uv, double inv_sigma)
      : K_(K), uv_(uv), inv_sigma_(inv_sigma) {}

  template <typename T>
  bool operator()(const T* q_cw, const T* t_cw, const T* p_w, T* r) const {
    const Eigen::Matrix<T, 3, 1> p_c =
        world_to_camera(q_cw, t_cw, Eigen::Map<const Eigen::Matrix<T, 3, 1>>(p_w).eval());
    reprojection_residual(K_, uv_, inv_sigma_, p_c, r);
    return true;
  }

  static ceres::CostFunction* Create(const Intrinsics& K, const Eigen::Vector2d& uv,
                                     double inv_sigma) {
    return new ceres::AutoDiffCostFunction<BaReprojectionCost, 2, 4, 3, 3>(
        new BaReprojectionCost(K, uv, inv_sigma));
  }

  Intrinsics K_;
  Eigen::Vector2d uv_;
  double inv_sigma_;
};

struct BaDepthCost {
  BaDepthCost(double depth, double inv_sigma) : depth_(depth), inv_sigma_(inv_sigma) {}

  template <typename T>
  bool operator()(const T* q_cw, const T* t_cw, const T* p_w, T* r) const {
    const Eigen::Matrix<T, 3, 1> p_c =
        world_to_camera(q_cw, t_cw, Eigen::Map<const Eigen::Matrix<T, 3, 1>>(p_w).eval());
    r[0] = (p_c.z() - T(depth_)) * T(inv_sigma_);
    return true;
  }

  static ceres::CostFunction* Create(double depth, double inv_sigma) {
    return new ceres::AutoDiffCostFunction<BaDepthCost, 1, 4, 3, 3>(
        new BaDepthCost(depth, inv_sigma));
  }

  double depth_;
  double inv_sigma_;
};

// The 6-vector residual of a pose error E = exp(δ) (right perturbation): r = S [t_E; 2 vec(q_E)],
// with q_E taken in the hemisphere w ≥ 0 so that 2 vec(q_E) ≈ the rotation vector for small
// errors. Shared by the dense prior and the odometry factor.
template <typename T>
void whitened_pose_error(Eigen::Quaternion<T> q_e, const Eigen::Matrix<T, 3, 1>& t_e,
                         const Eigen::Matrix<double, 6, 6>& sqrt_information, T* r) {
  if (q_e.w() < T(0.0)) q_e.coeffs() = -q_e.coeffs();
  Eigen::Matrix<T, 6, 1> delta;
  delta.template head<3>() = t_e;
  delta.template tail<3>() = T(2.0) * q_e.vec();
  Eigen::Map<Eigen::Matrix<T, 6, 1>> residual(r);
  residual = sqrt_information.cast<T>() * delta;
}

// The dense alignment as a 6-DoF Gaussian factor. Dense gives T̂_ref_cur (the current camera in
// the previous frame's) with information Λ for the right perturbation T_ref_cur = T̂_ref_cur exp(δ),
// δ = [ρ; φ] in the current camera's frame (dense_alignment.h). With the previous pose T_w_ref held
// fixed that is the right perturbation of T_wc about T̂_wc = T_w_ref T̂_ref_cur:
//   E = T̂_wc⁻¹ T_wc = T̂_cw T_wc = exp(δ),   δ ≈ [t_E; 2 vec(q_E)]   (first order in δ),
//   r = S δ  with SᵀS = Λ,
// so ‖r‖² = δᵀ Λ δ is the Mahalanobis distance to the dense measurement.
struct DensePriorCost {
  DensePriorCost(const SE3& T_cw_measured, const Eigen::Matrix<double, 6, 6>& sqrt_information)
      : q_hat_cw_(T_cw_measured.quaternion()),
        t_hat_cw_(T_cw_measured.translation()),
        sqrt_information_(sqrt_information) {}

  template <typename T>
  bool operator()(const T* q_cw_raw, const T* t_cw_raw, T* r) const {
    using Q = Eigen::Quaternion<T>;
    using V = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Q> q_cw(q_cw_raw);
    const Eigen::Map<const V> t_cw(t_cw_raw);
    const Q q_wc = q_cw.conjugate();
    const V t_wc = -(q_wc * t_cw);
    const Q q_hat = q_hat_cw_.cast<T>();
    const Q q_e = q_hat * q_wc;
    const V t_e = q_hat * t_wc + t_hat_cw_.cast<T>();
    whitened_pose_error(q_e, t_e, sqrt_information_, r);
    return true;
  }

  static ceres::CostFunction* Create(const SE3& T_cw_measured,
                                     const Eigen::Matrix<double, 6, 6>& sqrt_information) {
    return new ceres::AutoDiffCostFunction<DensePriorCost, 6, 4, 3>(
        new DensePriorCost(T_cw_measured, sqrt_information));
  }

  Eigen::Quaterniond q_hat_cw_;
  Eigen::Vector3d t_hat_cw_;
  Eigen::Matrix<double, 6, 6> sqrt_information_;
};

// Dense odometry between two keyframes in bundle adjustment: the tracker composed the dense
// alignments of the frames between them into T̂_ab (keyframe b in keyframe a's frame) with
// information Λ for the right perturbation T_ab = T̂_ab exp(δ). With both poses free:
//   E = T̂_ab⁻¹ T_aw T_wb = T̂_ba T_a_cw (T_b_cw)⁻¹ = exp(δ),   r = S [t_E; 2 vec(q_E)].
struct OdometryCost {
  OdometryCost(const SE3& T_ab_measured, const Eigen::Matrix<double, 6, 6>& sqrt_information)
      : q_ba_(T_ab_measured.inverse().quaternion()),
        t_ba_(T_ab_measured.inverse().translation()),
        sqrt_information_(sqrt_information) {}

  template <typename T>
  bool operator()(const T* q_a_raw, const T* t_a_raw, const T* q_b_raw, const T* t_b_raw,
                  T* r) const {
    using Q = Eigen::Quaternion<T>;
    using V = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Q> q_a(q_a_raw), q_b(q_b_raw);  // q_cw of a and b
    const Eigen::Map<const V> t_a(t_a_raw), t_b(t_b_raw);
    const Q q_bw_inv = q_b.conjugate();  // T_wb
    const V t_wb = -(q_bw_inv * t_b);
    const Q q_ab = q_a * q_bw_inv;  // T_aw T_wb
    const V t_ab = q_a * t_wb + t_a;
    const Q q_e = q_ba_.cast<T>() * q_ab;
    const V t_e = q_ba_.cast<T>() * t_ab + t_ba_.cast<T>();
    whitened_pose_error(q_e, t_e, sqrt_information_, r);
    return true;
  }

  static ceres::CostFunction* Create(const SE3& T_ab_measured,
                                     const Eigen::Matrix<double, 6, 6>& sqrt_information) {
    return new ceres::AutoDiffCostFunction<OdometryCost, 6, 4, 3, 4, 3>(
        new OdometryCost(T_ab_measured, sqrt_information));
  }

  Eigen::Quaterniond q_ba_;
  Eigen::Vector3d t_ba_;
  Eigen::Matrix<double, 6, 6> sqrt_information_;
};

// S with SᵀS = Λ for a symmetric positive semi-definite Λ (negative eigenvalues clamped to 0).
Eigen::Matrix<double, 6, 6> sqrt_information(const Eigen::Matrix<double, 6, 6>& information);

}  // namespace dqo::tracking
