#pragma once
// Stage: a Gaussian's mean and covariance from the world frame to the camera (optical) frame,
// p_c = R_cw p_w + t_cw, Σ_c = R_cw Σ_w R_cwᵀ. The pose gradients are returned too, for a tracker
// that optimises the camera by rendering.

#include "dqo_map/gaussians/math/types.h"

namespace dqo::gs {

template <typename T>
DQO_HD Vec3<T> position_world_to_camera(const Mat3<T>& R_cw,  // input
                                        const Vec3<T>& t_cw,  // input
                                        const Vec3<T>& p_w    // input
) {
  return R_cw * p_w + t_cw;
}

template <typename T>
DQO_HD void position_world_to_camera_vjp(const Mat3<T>& R_cw,   // input
                                         const Vec3<T>& p_w,    // input
                                         const Vec3<T>& v_p_c,  // output gradient
                                         Vec3<T>* v_p_w,        // accumulated gradient
                                         Mat3<T>* v_R_cw,  // accumulated gradient (may be null)
                                         Vec3<T>* v_t_cw   // accumulated gradient (may be null)
) {
  *v_p_w += mul_transposed(R_cw, v_p_c);
  if (v_R_cw) *v_R_cw += outer(v_p_c, p_w);
  if (v_t_cw) *v_t_cw += v_p_c;
}

template <typename T>
DQO_HD Mat3<T> covariance_world_to_camera(const Mat3<T>& R_cw,  // input
                                          const Mat3<T>& cov_w  // input
) {
  return R_cw * cov_w * transpose(R_cw);
}

// dΣ_w = Rᵀ G R; dR = G R Σ_wᵀ + Gᵀ R Σ_w.
template <typename T>
DQO_HD void covariance_world_to_camera_vjp(const Mat3<T>& R_cw,     // input
                                           const Mat3<T>& cov_w,    // input
                                           const Mat3<T>& v_cov_c,  // output gradient (full)
                                           Mat3<T>* v_cov_w,        // accumulated gradient (full)
                                           Mat3<T>* v_R_cw  // accumulated gradient (may be null)
) {
  const Mat3<T> Rt = transpose(R_cw);
  *v_cov_w += Rt * v_cov_c * R_cw;
  if (v_R_cw) {
    *v_R_cw += v_cov_c * R_cw * transpose(cov_w);
    *v_R_cw += transpose(v_cov_c) * R_cw * cov_w;
  }
}

}  // namespace dqo::gs
