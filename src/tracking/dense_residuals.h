#pragma once
// The maths of one dense-alignment correspondence: residuals, their Jacobians, the robust weight,
// and the 6x6 normal-equation accumulator. Header-only so that the alignment loop inlines it and
// the unit test checks the Jacobians against central differences and the accumulator against a
// plain double-precision sum.
//
// Perturbation used INSIDE the solver: the LEFT one, T_ref_cur <- exp(xi) * T_ref_cur with
// xi = [rho; phi]. It moves a transformed point q = T_ref_cur * p_cur to q + rho + phi x q, so
// every Jacobian has the form [a; q x a] for a direction a in the reference frame, and no
// per-pixel rotation is needed. The public result is converted to the right perturbation with
// adjoint() below.

#include <algorithm>
#include <cmath>

#include <Eigen/Core>

#include "dqo_map/geometry/se3.h"

namespace dqo::tracking::dense {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

// Point-to-plane residual of q (a current point mapped into the reference frame) against the
// reference surfel (p_ref, n_ref), held fixed for one Gauss-Newton step:
//   r = n_refᵀ (q - p_ref);  ∂r/∂q = n_refᵀ, so a = n_ref.
inline float point_to_plane_residual(const Eigen::Vector3f& q, const Eigen::Vector3f& p_ref,
                                     const Eigen::Vector3f& n_ref) {
  return n_ref.dot(q - p_ref);
}

// Photometric residual r = I_ref(π(q)) - I_cur with π(q) = (fx x/z + cx, fy y/z + cy). Its
// derivative in q is ∇I_ref(π(q))ᵀ ∂π/∂q, i.e. the direction
//   a = (gx fx / z, gy fy / z, -(gx fx x + gy fy y) / z²),
// where (gx, gy) is the reference gradient sampled at π(q), in intensity per pixel of the level.
inline Eigen::Vector3f photometric_direction(const Eigen::Vector3f& q, float gx, float gy, float fx,
                                             float fy) {
  const float inv_z = 1.0f / q.z();
  const float a = gx * fx * inv_z;
  const float b = gy * fy * inv_z;
  return Eigen::Vector3f(a, b, -(a * q.x() + b * q.y()) * inv_z);
}

// J = [a; q x a]: the left-perturbation Jacobian of a residual whose derivative in q is aᵀ
// (∂q/∂rho = I, ∂q/∂phi = -[q]x, and aᵀ(-[q]x) = (q x a)ᵀ).
inline Eigen::Matrix<float, 6, 1> jacobian_from_direction(const Eigen::Vector3f& q,
                                                          const Eigen::Vector3f& a) {
  // Written out: Eigen's vectorised float cross product reads a fourth float past a Vector3f,
  // which GCC rightly warns about.
  Eigen::Matrix<float, 6, 1> J;
  J << a.x(), a.y(), a.z(), q.y() * a.z() - q.z() * a.y(), q.z() * a.x() - q.x() * a.z(),
      q.x() * a.y() - q.y() * a.x();
  return J;
}

// Huber's weight ψ(r)/r: 1 inside ±delta, delta/|r| outside (IRLS); delta > 0. Written without a
// branch so that the loops calling it vectorise.
inline float huber_weight(float r, float delta) {
  return delta / std::max(std::abs(r), delta);
}

// Adjoint of T for xi = [rho; phi]: T exp(xi) T⁻¹ = exp(Ad_T xi), Ad_T = [R, [t]x R; 0, R].
// A right-perturbation Jacobian is the left one times Ad_T, so H_right = Ad_Tᵀ H_left Ad_T.
inline Matrix6d adjoint(const SE3& T) {
  const Eigen::Matrix3d R = T.rotation();
  Matrix6d A = Matrix6d::Zero();
  A.topLeftCorner<3, 3>() = R;
  A.topRightCorner<3, 3>() = skew(T.translation()) * R;
  A.bottomRightCorner<3, 3>() = R;
  return A;
}

// Residuals in a structure of arrays, so that the loops filling and summing them vectorise: entry i
// has the Jacobian J = [a; q x a] (left perturbation), residual r and weight w. A slot with w = 0
// counts for nothing; its q, a and r must still be finite (0 * NaN would poison the sums).
struct ResidualBlock {
  static constexpr int kSize = 256;  // a multiple of NormalEquations::kLanes
  alignas(32) float qx[kSize];
  alignas(32) float qy[kSize];
  alignas(32) float qz[kSize];
  alignas(32) float ax[kSize];
  alignas(32) float ay[kSize];
  alignas(32) float az[kSize];
  alignas(32) float r[kSize];
  alignas(32) float w[kSize];
};

// Accumulates H = Σ w J Jᵀ, g = Σ w r J and cost = Σ w r² over blocks of residuals. The sums run
// eight lanes at a time in float (the compiler vectorises the lane loop: SSE or NEON, no flags
// needed), and each block's lanes, a few dozen terms each, are added into double totals, so tens of
// thousands of residuals lose no precision. No allocation.
class NormalEquations {
 public:
  static constexpr int kLanes = 8;

  // Adds entries [0, n) of the block; n must be a multiple of kLanes (pad with w = 0). Always
  // inlined, so that it is compiled for its caller's target (accumulate() also has an AVX2 clone,
  // cpu_clones.h); out of line it ran as SSE2 code, a third of the alignment's time.
  __attribute__((always_inline)) void add(const ResidualBlock& b, int n) {
    float acc[28][kLanes] = {};
    for (int i = 0; i < n; i += kLanes) {
      for (int l = 0; l < kLanes; ++l) {
        const int k = i + l;
        const float j0 = b.ax[k], j1 = b.ay[k], j2 = b.az[k];
        const float j3 = b.qy[k] * j2 - b.qz[k] * j1;
        const float j4 = b.qz[k] * j0 - b.qx[k] * j2;
        const float j5 = b.qx[k] * j1 - b.qy[k] * j0;
        const float w = b.w[k];
        const float wr = w * b.r[k];
        const float w0 = w * j0, w1 = w * j1, w2 = w * j2, w3 = w * j3, w4 = w * j4, w5 = w * j5;
        acc[0][l] += w0 * j0;
        acc[1][l] += w0 * j1;
        acc[2][l] += w0 * j2;
        acc[3][l] += w0 * j3;
        acc[4][l] += w0 * j4;
        acc[5][l] += w0 * j5;
        acc[6][l] += w1 * j1;
        acc[7][l] += w1 * j2;
        acc[8][l] += w1 * j3;
        acc[9][l] += w1 * j4;
        acc[10][l] += w1 * j5;
        acc[11][l] += w2 * j2;
        acc[12][l] += w2 * j3;
        acc[13][l] += w2 * j4;
        acc[14][l] += w2 * j5;
        acc[15][l] += w3 * j3;
        acc[16][l] += w3 * j4;
        acc[17][l] += w3 * j5;
        acc[18][l] += w4 * j4;
        acc[19][l] += w4 * j5;
        acc[20][l] += w5 * j5;
        acc[21][l] += wr * j0;
        acc[22][l] += wr * j1;
        acc[23][l] += wr * j2;
        acc[24][l] += wr * j3;
        acc[25][l] += wr * j4;
        acc[26][l] += wr * j5;
        acc[27][l] += wr * b.r[k];
      }
    }
    for (int s = 0; s < 28; ++s) {
      double sum = 0.0;
      for (int l = 0; l < kLanes; ++l) sum += acc[s][l];
      totals_[s] += sum;
    }
  }

  Matrix6d hessian() const {
    Matrix6d H;
    int k = 0;
    for (int i = 0; i < 6; ++i) {
      for (int j = i; j < 6; ++j, ++k) {
        H(i, j) = totals_[k];
        H(j, i) = totals_[k];
      }
    }
    return H;
  }
  Vector6d gradient() const { return Eigen::Map<const Vector6d>(totals_ + 21); }
  double cost() const { return totals_[27]; }

 private:
  double totals_[28] = {};  // upper triangle of H row by row (21), g (6), cost
};

}  // namespace dqo::tracking::dense
