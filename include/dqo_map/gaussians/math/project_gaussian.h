#pragma once
// The whole per-Gaussian front end, stage after stage: quaternion → R, (log-scale, R) → Σ_w,
// world → camera, EWA projection, low-pass, conic, radius. The CPU rasteriser's projection pass and
// the CUDA projection kernel both call project_gaussian(), and both backward passes call
// project_gaussian_vjp(), so the two backends share every formula.

#include "dqo_map/gaussians/math/conic.h"
#include "dqo_map/gaussians/math/covariance.h"
#include "dqo_map/gaussians/math/projection.h"
#include "dqo_map/gaussians/math/quaternion.h"
#include "dqo_map/gaussians/math/types.h"
#include "dqo_map/gaussians/math/world_to_camera.h"

namespace dqo::gs {

template <typename T>
struct CameraView {
  PinholeIntrinsics<T> K;
  Mat3<T> R_cw;
  Vec3<T> t_cw;
  T near;  // Gaussians whose mean is nearer than this (camera z) are culled
};

template <typename T>
struct ProjectedGaussian {
  Vec2<T> mean2d;  // pixels
  Sym2<T> cov2d;   // px², low-pass included
  Sym2<T> conic;   // cov2d⁻¹
  T depth;         // camera-frame z of the mean
  int radius;      // pixels, 3σ
};

// Returns false when the Gaussian is culled (behind the near plane or degenerate); the caller also
// culls by image bounds using mean2d and radius.
template <typename T>
DQO_HD bool project_gaussian(const T* position,   // input [3], world
                             const T* log_scale,  // input [3]
                             const T* rotation,   // input [4], w x y z, any norm
                             const CameraView<T>& cam,
                             ProjectedGaussian<T>* out  // output
) {
  const Vec3<T> p_w = load_vec3(position);
  const Vec3<T> p_c = position_world_to_camera(cam.R_cw, cam.t_cw, p_w);
  if (!(p_c.z >= cam.near)) return false;
  const Mat3<T> R = quat_to_rotmat(load_quat(rotation));
  const Mat3<T> cov_w = covariance_3d(load_vec3(log_scale), R);
  const Mat3<T> cov_c = covariance_world_to_camera(cam.R_cw, cov_w);
  Sym2<T> cov2d;
  perspective_projection(p_c, cov_c, cam.K, &out->mean2d, &cov2d);
  out->cov2d = add_low_pass(cov2d);
  if (!conic_from_covariance(out->cov2d, &out->conic)) return false;
  out->depth = p_c.z;
  out->radius = radius_3sigma(out->cov2d);
  return true;
}

// Gradients of the map's attributes from those of the projected quantities, for a Gaussian that
// project_gaussian() accepted. Recomputes the forward intermediates (cheaper than storing them).
template <typename T>
DQO_HD void project_gaussian_vjp(const T* position,   // input [3]
                                 const T* log_scale,  // input [3]
                                 const T* rotation,   // input [4]
                                 const CameraView<T>& cam,
                                 const Vec2<T>& v_mean2d,  // output gradient
                                 const Sym2<T>& v_conic,   // output gradient
                                 T v_depth,                // output gradient
                                 T* v_position,            // accumulated gradient [3]
                                 T* v_log_scale,           // accumulated gradient [3]
                                 T* v_rotation,            // accumulated gradient [4]
                                 Mat3<T>* v_R_cw,          // accumulated gradient (may be null)
                                 Vec3<T>* v_t_cw           // accumulated gradient (may be null)
) {
  const Vec3<T> p_w = load_vec3(position);
  const Vec3<T> ls = load_vec3(log_scale);
  const Quat<T> q = load_quat(rotation);
  const Vec3<T> p_c = position_world_to_camera(cam.R_cw, cam.t_cw, p_w);
  const Mat3<T> R = quat_to_rotmat(q);
  const Mat3<T> cov_w = covariance_3d(ls, R);
  const Mat3<T> cov_c = covariance_world_to_camera(cam.R_cw, cov_w);
  Vec2<T> mean2d;
  Sym2<T> cov2d;
  Sym2<T> conic = {T(0), T(0), T(0)};
  perspective_projection(p_c, cov_c, cam.K, &mean2d, &cov2d);
  conic_from_covariance(add_low_pass(cov2d), &conic);

  Sym2<T> v_cov2d = {T(0), T(0), T(0)};
  conic_from_covariance_vjp(conic, v_conic, &v_cov2d);
  Vec3<T> v_p_c = {T(0), T(0), v_depth};
  Mat3<T> v_cov_c = mat3_zero<T>();
  perspective_projection_vjp(p_c, cov_c, cam.K, v_mean2d, v_cov2d, &v_p_c, &v_cov_c);
  Mat3<T> v_cov_w = mat3_zero<T>();
  covariance_world_to_camera_vjp(cam.R_cw, cov_w, v_cov_c, &v_cov_w, v_R_cw);
  Vec3<T> v_p_w = {T(0), T(0), T(0)};
  position_world_to_camera_vjp(cam.R_cw, p_w, v_p_c, &v_p_w, v_R_cw, v_t_cw);
  Vec3<T> v_ls = {T(0), T(0), T(0)};
  Mat3<T> v_R = mat3_zero<T>();
  covariance_3d_vjp(ls, R, v_cov_w, &v_ls, &v_R);
  Quat<T> v_q = {T(0), T(0), T(0), T(0)};
  quat_to_rotmat_vjp(q, v_R, &v_q);

  v_position[0] += v_p_w.x;
  v_position[1] += v_p_w.y;
  v_position[2] += v_p_w.z;
  v_log_scale[0] += v_ls.x;
  v_log_scale[1] += v_ls.y;
  v_log_scale[2] += v_ls.z;
  v_rotation[0] += v_q.w;
  v_rotation[1] += v_q.x;
  v_rotation[2] += v_q.y;
  v_rotation[3] += v_q.z;
}

}  // namespace dqo::gs
