#pragma once
// Stage: perspective projection of a camera-frame Gaussian to the image (EWA splatting, Zwicker et
// al. 2001, as in 3DGS): the mean goes through the pinhole model, the covariance through the
// Jacobian J of the projection at the mean, Σ_2D = J Σ_c Jᵀ, then a 0.3 px² low-pass (3DGS's
// dilation, so that every splat covers at least about a pixel).
//
// As in 3DGS, J is evaluated at the mean's direction clamped to a margin around the field of view
// (1.3 × the half-field for a centred principal point; gsplat's asymmetric form for others): far
// outside the image the linearisation is meaningless and would blow up. Where the clamp is active,
// the direction's gradient through J is zero, exactly as the clamped function is flat.
//
// Pixel convention (PinholeCamera): pixel (u, v) has its centre at integer coordinates, so the mean
// is (fx x/z + cx, fy y/z + cy) with no half-pixel offset.

#include "dqo_map/gaussians/math/types.h"

namespace dqo::gs {

constexpr float kLowPass = 0.3f;  // px², added to the diagonal of Σ_2D

template <typename T>
struct PinholeIntrinsics {
  T fx, fy, cx, cy;
  int width, height;
};

template <typename T>
struct FrustumLimits {
  T x_neg, x_pos, y_neg, y_pos;  // clamp of x/z to [−x_neg, x_pos], y/z to [−y_neg, y_pos]
};

template <typename T>
DQO_HD FrustumLimits<T> frustum_limits(const PinholeIntrinsics<T>& K) {
  const T tan_x = T(0.5) * T(K.width) / K.fx;
  const T tan_y = T(0.5) * T(K.height) / K.fy;
  return {K.cx / K.fx + T(0.3) * tan_x, (T(K.width) - K.cx) / K.fx + T(0.3) * tan_x,
          K.cy / K.fy + T(0.3) * tan_y, (T(K.height) - K.cy) / K.fy + T(0.3) * tan_y};
}

// p_c.z must be > 0 (the caller culls near Gaussians first). cov2d excludes the low-pass.
template <typename T>
DQO_HD void perspective_projection(const Vec3<T>& p_c,             // input
                                   const Mat3<T>& cov_c,           // input
                                   const PinholeIntrinsics<T>& K,  // input
                                   Vec2<T>* mean2d,                // output, pixels
                                   Sym2<T>* cov2d                  // output, px²
) {
  const T rz = T(1) / p_c.z;
  const T u = p_c.x * rz, v = p_c.y * rz;
  const FrustumLimits<T> lim = frustum_limits(K);
  const T uc = hd_clamp(u, -lim.x_neg, lim.x_pos);
  const T vc = hd_clamp(v, -lim.y_neg, lim.y_pos);
  // J = [[fx/z, 0, −fx uc/z], [0, fy/z, −fy vc/z]].
  const T j00 = K.fx * rz, j02 = -K.fx * uc * rz, j11 = K.fy * rz, j12 = -K.fy * vc * rz;
  const T(&S)[3][3] = cov_c.m;
  // A = J Σ (2x3), then A Jᵀ; xy symmetrised so the map is exact for a non-symmetric Σ too.
  T A[2][3];
  for (int j = 0; j < 3; ++j) {
    A[0][j] = j00 * S[0][j] + j02 * S[2][j];
    A[1][j] = j11 * S[1][j] + j12 * S[2][j];
  }
  cov2d->xx = A[0][0] * j00 + A[0][2] * j02;
  cov2d->yy = A[1][1] * j11 + A[1][2] * j12;
  const T c01 = A[0][1] * j11 + A[0][2] * j12;
  const T c10 = A[1][0] * j00 + A[1][2] * j02;
  cov2d->xy = T(0.5) * (c01 + c10);
  mean2d->x = K.fx * u + K.cx;
  mean2d->y = K.fy * v + K.cy;
}

template <typename T>
DQO_HD void perspective_projection_vjp(const Vec3<T>& p_c,             // input
                                       const Mat3<T>& cov_c,           // input
                                       const PinholeIntrinsics<T>& K,  // input
                                       const Vec2<T>& v_mean2d,        // output gradient
                                       const Sym2<T>& v_cov2d,         // output gradient
                                       Vec3<T>* v_p_c,                 // accumulated gradient
                                       Mat3<T>* v_cov_c  // accumulated gradient (full matrix)
) {
  const T rz = T(1) / p_c.z;
  const T u = p_c.x * rz, v = p_c.y * rz;
  const FrustumLimits<T> lim = frustum_limits(K);
  const T uc = hd_clamp(u, -lim.x_neg, lim.x_pos);
  const T vc = hd_clamp(v, -lim.y_neg, lim.y_pos);
  const bool u_free = u == uc, v_free = v == vc;
  T J[2][3] = {{K.fx * rz, T(0), -K.fx * uc * rz}, {T(0), K.fy * rz, -K.fy * vc * rz}};
  // Full-matrix gradient of Σ_2D: the Sym2 xy gradient is split over both off-diagonal entries.
  const T G[2][2] = {{v_cov2d.xx, T(0.5) * v_cov2d.xy}, {T(0.5) * v_cov2d.xy, v_cov2d.yy}};
  const T(&S)[3][3] = cov_c.m;

  // dΣ_c = Jᵀ G J.
  T GJ[2][3];
  for (int a = 0; a < 2; ++a)
    for (int j = 0; j < 3; ++j) GJ[a][j] = G[a][0] * J[0][j] + G[a][1] * J[1][j];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) v_cov_c->m[i][j] += J[0][i] * GJ[0][j] + J[1][i] * GJ[1][j];

  // dJ = G J Σᵀ + Gᵀ J Σ (G is symmetric here: 2 G J Σ_sym, written out for a general Σ).
  T v_J[2][3];
  for (int a = 0; a < 2; ++a)
    for (int j = 0; j < 3; ++j) {
      T acc = T(0);
      for (int k = 0; k < 3; ++k) acc += GJ[a][k] * (S[j][k] + S[k][j]);
      v_J[a][j] = acc;
    }

  // J00 = fx/z, J02 = −fx uc/z, J11 = fy/z, J12 = −fy vc/z.
  const T rz2 = rz * rz;
  T v_z = -K.fx * rz2 * v_J[0][0] - K.fy * rz2 * v_J[1][1] + K.fx * uc * rz2 * v_J[0][2] +
          K.fy * vc * rz2 * v_J[1][2];
  T v_u = K.fx * v_mean2d.x + (u_free ? -K.fx * rz * v_J[0][2] : T(0));
  T v_v = K.fy * v_mean2d.y + (v_free ? -K.fy * rz * v_J[1][2] : T(0));
  // u = x/z, v = y/z.
  v_p_c->x += v_u * rz;
  v_p_c->y += v_v * rz;
  v_p_c->z += v_z - (u * v_u + v * v_v) * rz;
}

// The low-pass: its gradient is the identity, so there is no _vjp.
template <typename T>
DQO_HD Sym2<T> add_low_pass(const Sym2<T>& cov2d) {
  return {cov2d.xx + T(kLowPass), cov2d.xy, cov2d.yy + T(kLowPass)};
}

}  // namespace dqo::gs
