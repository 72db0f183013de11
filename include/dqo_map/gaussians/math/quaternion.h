#pragma once
// Stage: rotation of a Gaussian from its (unnormalised) quaternion.
//
// The map stores q = (w, x, y, z) without keeping it unit: the rotation is R(q / |q|), so an
// optimiser step that changes |q| changes nothing, and the gradient returned is with respect to the
// raw q, through the normalisation (it is orthogonal to q).

#include "dqo_map/gaussians/math/types.h"

namespace dqo::gs {

// R(q / |q|), the rotation of Eigen's Quaternion(w, x, y, z).toRotationMatrix().
template <typename T>
DQO_HD Mat3<T> quat_to_rotmat(const Quat<T>& q  // input, any non-zero norm
) {
  const T inv = T(1) / hd_sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
  const T w = q.w * inv, x = q.x * inv, y = q.y * inv, z = q.z * inv;
  Mat3<T> R;
  R.m[0][0] = T(1) - T(2) * (y * y + z * z);
  R.m[0][1] = T(2) * (x * y - w * z);
  R.m[0][2] = T(2) * (x * z + w * y);
  R.m[1][0] = T(2) * (x * y + w * z);
  R.m[1][1] = T(1) - T(2) * (x * x + z * z);
  R.m[1][2] = T(2) * (y * z - w * x);
  R.m[2][0] = T(2) * (x * z - w * y);
  R.m[2][1] = T(2) * (y * z + w * x);
  R.m[2][2] = T(1) - T(2) * (x * x + y * y);
  return R;
}

template <typename T>
DQO_HD void quat_to_rotmat_vjp(const Quat<T>& q,    // input
                               const Mat3<T>& v_R,  // output gradient dL/dR
                               Quat<T>* v_q         // accumulated gradient dL/dq (raw q)
) {
  const T inv = T(1) / hd_sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
  const T w = q.w * inv, x = q.x * inv, y = q.y * inv, z = q.z * inv;
  const T(&v)[3][3] = v_R.m;
  // dL/d(unit quaternion), entry by entry of the matrix above.
  const T gw =
      T(2) * (-z * v[0][1] + y * v[0][2] + z * v[1][0] - x * v[1][2] - y * v[2][0] + x * v[2][1]);
  const T gx = T(2) * (y * v[0][1] + z * v[0][2] + y * v[1][0] - T(2) * x * v[1][1] - w * v[1][2] +
                       z * v[2][0] + w * v[2][1] - T(2) * x * v[2][2]);
  const T gy = T(2) * (-T(2) * y * v[0][0] + x * v[0][1] + w * v[0][2] + x * v[1][0] + z * v[1][2] -
                       w * v[2][0] + z * v[2][1] - T(2) * y * v[2][2]);
  const T gz = T(2) * (-T(2) * z * v[0][0] - w * v[0][1] + x * v[0][2] + w * v[1][0] -
                       T(2) * z * v[1][1] + y * v[1][2] + x * v[2][0] + y * v[2][1]);
  // Through q̂ = q / |q|: dq = (g − q̂ (q̂ · g)) / |q|.
  const T proj = w * gw + x * gx + y * gy + z * gz;
  v_q->w += (gw - w * proj) * inv;
  v_q->x += (gx - x * proj) * inv;
  v_q->y += (gy - y * proj) * inv;
  v_q->z += (gz - z * proj) * inv;
}

}  // namespace dqo::gs
