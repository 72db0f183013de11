#pragma once
// Private to tracking: the residual between a keyframe's pose and an object landmark it sees
// (QuadricSLAM's bounding-box cost, the object held fixed: the object stage owns it).
//
// Derivation. The sighting was made by a registered frame f whose pose follows a tracker keyframe
// k: T_fw = T_fk T_kw with T_fk fixed (register_frame) and T_kw = (q_cw, t_cw) the parameters.
// The object's dual quadric is Q* = [S − mu muᵀ, −mu; −muᵀ, −1] with S = L Lᵀ, L = R diag(a, b, c)
// (dual_quadric.h). Through P = K [R_fw | t_fw] its dual conic is
//   C* = P Q* Pᵀ = A Aᵀ − m mᵀ,   A = K R_fw L,   m = K (R_fw mu + t_fw) = K mu_c,
// and the conic's box is conic.h's closed form: x = (C₀₂ ± sqrt(C₀₂² − C₀₀ C₂₂)) / C₂₂, y likewise
// with C₁₂, C₁₁. C₂₂ < 0 iff the camera plane misses the ellipsoid; with mu_c in front that means
// the ellipsoid is wholly in front of the camera.
//
// Residual: r = (box − detection) · inv_sigma · sqrt(weight), four edges (x_min, y_min, x_max,
// y_max); an edge the detection has at the image border (within border_px) says nothing about the
// object's extent (the object goes on beyond it) and gives 0. The cost is not evaluated where the
// box does not exist (returns false: Ceres rejects the step).

#include <array>
#include <cmath>

#include <ceres/autodiff_cost_function.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "dqo_map/geometry/box2d.h"
#include "dqo_map/geometry/se3.h"
#include "residuals.h"

namespace dqo::tracking {

// The conic box of an ellipsoid (centre mu_c, L_c = R_cw R diag(s), both in the camera frame)
// through the intrinsics K; false where it does not exist. box = (x_min, y_min, x_max, y_max).
template <typename T>
bool conic_box_in_camera(const Intrinsics& K, const Eigen::Matrix<T, 3, 1>& mu_c,
                         const Eigen::Matrix<T, 3, 3>& L_c, T box[4]) {
  if (!(mu_c.z() > T(0.0))) return false;
  // Rows of K: (fx, 0, cx), (0, fy, cy), (0, 0, 1).
  Eigen::Matrix<T, 3, 3> A;
  A.row(0) = T(K.fx) * L_c.row(0) + T(K.cx) * L_c.row(2);
  A.row(1) = T(K.fy) * L_c.row(1) + T(K.cy) * L_c.row(2);
  A.row(2) = L_c.row(2);
  const Eigen::Matrix<T, 3, 1> m(T(K.fx) * mu_c.x() + T(K.cx) * mu_c.z(),
                                 T(K.fy) * mu_c.y() + T(K.cy) * mu_c.z(), mu_c.z());
  auto c = [&](int i, int j) { return A.row(i).dot(A.row(j)) - m[i] * m[j]; };
  const T c00 = c(0, 0), c11 = c(1, 1), c22 = c(2, 2), c02 = c(0, 2), c12 = c(1, 2);
  using std::abs;
  using std::sqrt;
  // Relative threshold as conic_bounding_box's: near tangency the box runs off to infinity.
  T scale = abs(c00);
  if (abs(c11) > scale) scale = abs(c11);
  if (abs(c22) > scale) scale = abs(c22);
  if (!(c22 < T(-1e-12) * scale)) return false;
  const T disc_x = c02 * c02 - c00 * c22;
  const T disc_y = c12 * c12 - c11 * c22;
  if (!(disc_x > T(0.0)) || !(disc_y > T(0.0))) return false;
  const T sx = sqrt(disc_x);
  const T sy = sqrt(disc_y);
  box[0] = (c02 + sx) / c22;  // c22 < 0: the smaller root
  box[1] = (c12 + sy) / c22;
  box[2] = (c02 - sx) / c22;
  box[3] = (c12 - sy) / c22;
  using std::isfinite;
  for (int k = 0; k < 4; ++k)
    if (!isfinite(box[k])) return false;
  return true;
}

struct ObjectBoxCost {
  // T_frame_kf: the sighting frame in the keyframe's (register_frame's T_ref_frame, inverted).
  // centre_w, L_w: the object's centre and R diag(semi-axes), world. use_edge: per box edge
  // (x_min, y_min, x_max, y_max), false for one at the image border.
  ObjectBoxCost(const Intrinsics& K, const SE3& T_frame_kf, const Eigen::Vector3d& centre_w,
                const Eigen::Matrix3d& L_w, const Box2d& detection,
                const std::array<bool, 4>& use_edge, double scale)
      : K_(K),
        q_fk_(T_frame_kf.quaternion()),
        t_fk_(T_frame_kf.translation()),
        centre_w_(centre_w),
        L_w_(L_w),
        detection_{detection.x_min, detection.y_min, detection.x_max, detection.y_max},
        use_edge_(use_edge),
        scale_(scale) {}

  template <typename T>
  bool operator()(const T* q_cw_raw, const T* t_cw_raw, T* r) const {
    using Q = Eigen::Quaternion<T>;
    using V = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Q> q_kw(q_cw_raw);
    const Eigen::Map<const V> t_kw(t_cw_raw);
    const Q q_fk = q_fk_.cast<T>();
    const Q q_fw = q_fk * q_kw;
    const V t_fw = q_fk * t_kw + t_fk_.cast<T>();
    const V mu_c = q_fw * centre_w_.cast<T>() + t_fw;
    const Eigen::Matrix<T, 3, 3> L_c = q_fw.toRotationMatrix() * L_w_.cast<T>();
    T box[4];
    if (!conic_box_in_camera(K_, mu_c, L_c, box)) return false;
    for (int k = 0; k < 4; ++k)
      r[k] = use_edge_[k] ? (box[k] - T(detection_[k])) * T(scale_) : T(0.0);
    return true;
  }

  static ceres::CostFunction* Create(const Intrinsics& K, const SE3& T_frame_kf,
                                     const Eigen::Vector3d& centre_w, const Eigen::Matrix3d& L_w,
                                     const Box2d& detection, const std::array<bool, 4>& use_edge,
                                     double scale) {
    return new ceres::AutoDiffCostFunction<ObjectBoxCost, 4, 4, 3>(
        new ObjectBoxCost(K, T_frame_kf, centre_w, L_w, detection, use_edge, scale));
  }

  Intrinsics K_;
  Eigen::Quaterniond q_fk_;
  Eigen::Vector3d t_fk_;
  Eigen::Vector3d centre_w_;
  Eigen::Matrix3d L_w_;
  double detection_[4];
  std::array<bool, 4> use_edge_;
  double scale_;  // inv_sigma · sqrt(weight)
};

}  // namespace dqo::tracking
