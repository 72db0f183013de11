#pragma once
// Stage: 3D covariance of a Gaussian from its log-scale and rotation, Σ = R S Sᵀ Rᵀ with
// S = diag(exp(log_scale)) (the map stores log standard deviations, 3DGS's `scale_*`).

#include "dqo_map/gaussians/math/types.h"

namespace dqo::gs {

template <typename T>
DQO_HD Mat3<T> covariance_3d(const Vec3<T>& log_scale,  // input
                             const Mat3<T>& R           // input, rotation (object to world)
) {
  const T s[3] = {hd_exp(log_scale.x), hd_exp(log_scale.y), hd_exp(log_scale.z)};
  Mat3<T> M;  // R S
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) M.m[i][j] = R.m[i][j] * s[j];
  return M * transpose(M);
}

// Σ = M Mᵀ, M = R S: dM = (G + Gᵀ) M; dR_ij = dM_ij s_j; ds_j = Σ_i R_ij dM_ij; d log s = s ds.
template <typename T>
DQO_HD void covariance_3d_vjp(const Vec3<T>& log_scale,  // input
                              const Mat3<T>& R,          // input
                              const Mat3<T>& v_cov,      // output gradient dL/dΣ (full matrix)
                              Vec3<T>* v_log_scale,      // accumulated gradient
                              Mat3<T>* v_R               // accumulated gradient
) {
  const T s[3] = {hd_exp(log_scale.x), hd_exp(log_scale.y), hd_exp(log_scale.z)};
  Mat3<T> M;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) M.m[i][j] = R.m[i][j] * s[j];
  const Mat3<T> v_M = (v_cov + transpose(v_cov)) * M;
  T v_s[3] = {T(0), T(0), T(0)};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      v_R->m[i][j] += v_M.m[i][j] * s[j];
      v_s[j] += R.m[i][j] * v_M.m[i][j];
    }
  v_log_scale->x += v_s[0] * s[0];
  v_log_scale->y += v_s[1] * s[1];
  v_log_scale->z += v_s[2] * s[2];
}

}  // namespace dqo::gs
