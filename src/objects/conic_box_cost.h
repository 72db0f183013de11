#pragma once
// Private to object_refinement.cpp: the per-view residual of the IoU refinement, templated so that
// Ceres differentiates it automatically and the same code evaluates it in double.

#include <algorithm>
#include <cmath>

#include <Eigen/Core>
#include <ceres/autodiff_cost_function.h>
#include <ceres/jet.h>
#include <ceres/rotation.h>

namespace dqo::objects::internal {

template <typename T>
inline T min_t(const T& a, const T& b) {
  return a < b ? a : b;
}
template <typename T>
inline T max_t(const T& a, const T& b) {
  return a < b ? b : a;
}
template <typename T>
inline T clamp_t(const T& x, double lo, double hi) {
  return x < T(lo) ? T(lo) : (x > T(hi) ? T(hi) : x);
}

// Generalised IoU of boxes given as (x_min, y_min, x_max, y_max):
//   GIoU = I/U − (C − U)/C
// with I the intersection area, U the union, C the area of the smallest box enclosing both.
// Areas of empty (or inverted) boxes count as 0. C = 0 only when both boxes are degenerate and
// aligned; the value is then 0 (nothing to compare). I ≤ U ≤ C gives GIoU ∈ [−1, 1].
// min/max make it piecewise smooth in the coordinates, which is all Ceres needs: away from ties the
// derivatives are those of the active branch.
template <typename T>
T generalised_iou_t(const T a[4], const T b[4]) {
  const T zero(0.0);
  const T iw = max_t(zero, min_t(a[2], b[2]) - max_t(a[0], b[0]));
  const T ih = max_t(zero, min_t(a[3], b[3]) - max_t(a[1], b[1]));
  const T inter = iw * ih;
  const T area_a = max_t(zero, a[2] - a[0]) * max_t(zero, a[3] - a[1]);
  const T area_b = max_t(zero, b[2] - b[0]) * max_t(zero, b[3] - b[1]);
  const T uni = area_a + area_b - inter;
  const T cw = max_t(a[2], b[2]) - min_t(a[0], b[0]);
  const T ch = max_t(a[3], b[3]) - min_t(a[1], b[1]);
  const T enclosing = max_t(zero, cw) * max_t(zero, ch);
  if (!(enclosing > zero)) return zero;
  const T iou = uni > zero ? inter / uni : zero;
  return iou - (enclosing - uni) / enclosing;
}

// The bounding box of the ellipsoid (centre mu, rotation of the unit quaternion q = (w, x, y, z),
// semi-axes s = exp(log_axes)) seen through P = [M | p₄].
//
// Derivation. With S = R diag(s²) Rᵀ, Q* = [S − mu muᵀ, −mu; −muᵀ, −1] (dual_quadric.h), so
//   C* = P Q* Pᵀ = M S Mᵀ − (M mu + p₄)(M mu + p₄)ᵀ = A Aᵀ − m mᵀ,
// A = M R diag(s) (3×3), m = M mu + p₄ the homogeneous image of the centre. This never forms the 4×4
// Q* and needs only the five entries C₀₀, C₁₁, C₂₂, C₀₂, C₁₂. The box is then conic.h's closed form:
// x = (C₀₂ ± sqrt(C₀₂² − C₀₀ C₂₂)) / C₂₂, y likewise with C₁₂, C₁₁; C₂₂ < 0 says the camera plane
// misses the ellipsoid, so with the centre in front (m₂ · depth_sign > 0) it is wholly in front.
// Returns false where the box does not exist (straddling or behind the camera, or not finite):
// inside Ceres that rejects the step, which keeps the solver on the side of the camera it started.
// ceres::QuaternionToRotation divides by |q|², so R is a rotation for any q ≠ 0 and the derivatives
// along all four quaternion coordinates are those of the normalised quaternion.
template <typename T>
bool conic_box_t(const Eigen::Matrix<double, 3, 4>& P, double depth_sign, const T* centre,
                 const T* q_wxyz, const T* log_axes, T box[4]) {
  T R[9];  // row-major
  ceres::QuaternionToRotation(q_wxyz, R);
  using std::exp;
  const T s[3] = {exp(log_axes[0]), exp(log_axes[1]), exp(log_axes[2])};
  T A[3][3];
  T m[3];
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      A[i][j] = (P(i, 0) * R[0 * 3 + j] + P(i, 1) * R[1 * 3 + j] + P(i, 2) * R[2 * 3 + j]) * s[j];
    }
    m[i] = P(i, 0) * centre[0] + P(i, 1) * centre[1] + P(i, 2) * centre[2] + P(i, 3);
  }
  auto c = [&](int i, int j) {
    return A[i][0] * A[j][0] + A[i][1] * A[j][1] + A[i][2] * A[j][2] - m[i] * m[j];
  };
  const T c00 = c(0, 0), c11 = c(1, 1), c22 = c(2, 2), c02 = c(0, 2), c12 = c(1, 2);
  if (!(m[2] * depth_sign > T(0.0))) return false;
  // Relative threshold as in conic_bounding_box: near tangency the box runs off to infinity.
  using std::abs;
  const T scale = max_t(abs(c00), max_t(abs(c11), abs(c22)));
  if (!(c22 < T(-1e-12) * scale)) return false;
  const T disc_x = c02 * c02 - c00 * c22;
  const T disc_y = c12 * c12 - c11 * c22;
  if (!(disc_x > T(0.0)) || !(disc_y > T(0.0))) return false;
  using std::sqrt;
  const T sx = sqrt(disc_x);
  const T sy = sqrt(disc_y);
  // c22 < 0: (c02 + s) / c22 is the smaller root.
  box[0] = (c02 + sx) / c22;
  box[1] = (c12 + sy) / c22;
  box[2] = (c02 - sx) / c22;
  box[3] = (c12 - sy) / c22;
  using std::isfinite;
  for (int k = 0; k < 4; ++k) {
    if (!isfinite(box[k])) return false;
  }
  return true;
}

// One view's residual r = 1 − GIoU(box(C*), detection), both boxes clipped to the image shrunk by
// the border margin: an edge the border cuts says nothing about the object's extent, and clipping
// both boxes to the same rectangle makes such an edge agree wherever the object ends beyond it.
// r ∈ [0, 2]; GIoU (not IoU) so that a projection that misses the detection is still pulled to it.
struct ConicBoxGiouCost {
  ConicBoxGiouCost(const Eigen::Matrix<double, 3, 4>& P, double depth_sign,
                   const double detection[4], const double inner[4])
      : P_(P), depth_sign_(depth_sign) {
    for (int k = 0; k < 4; ++k) {
      detection_[k] = detection[k];
      inner_[k] = inner[k];
    }
  }

  template <typename T>
  bool operator()(const T* centre, const T* q_wxyz, const T* log_axes, T* residual) const {
    T box[4];
    if (!conic_box_t(P_, depth_sign_, centre, q_wxyz, log_axes, box)) return false;
    box[0] = clamp_t(box[0], inner_[0], inner_[2]);
    box[2] = clamp_t(box[2], inner_[0], inner_[2]);
    box[1] = clamp_t(box[1], inner_[1], inner_[3]);
    box[3] = clamp_t(box[3], inner_[1], inner_[3]);
    const T det[4] = {T(detection_[0]), T(detection_[1]), T(detection_[2]), T(detection_[3])};
    residual[0] = T(1.0) - generalised_iou_t(box, det);
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Matrix<double, 3, 4>& P, double depth_sign,
                                     const double detection[4], const double inner[4]) {
    return new ceres::AutoDiffCostFunction<ConicBoxGiouCost, 1, 3, 4, 3>(
        new ConicBoxGiouCost(P, depth_sign, detection, inner));
  }

  Eigen::Matrix<double, 3, 4> P_;
  double depth_sign_;
  double detection_[4];  // already clipped to inner_
  double inner_[4];      // the image less the border margin, (x_min, y_min, x_max, y_max)
};

}  // namespace dqo::objects::internal
