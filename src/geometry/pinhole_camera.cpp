#include "dqo_map/geometry/pinhole_camera.h"

namespace dqo {

Eigen::Matrix3d PinholeCamera::K() const {
  Eigen::Matrix3d k;
  k << fx, 0.0, cx,  //
      0.0, fy, cy,   //
      0.0, 0.0, 1.0;
  return k;
}

Eigen::Vector2d PinholeCamera::project(const Eigen::Vector3d& p_c) const {
  const double inv_z = 1.0 / p_c.z();
  return {fx * p_c.x() * inv_z + cx, fy * p_c.y() * inv_z + cy};
}

Eigen::Vector3d PinholeCamera::back_project(double u, double v, double depth) const {
  return {(u - cx) / fx * depth, (v - cy) / fy * depth, depth};
}

bool PinholeCamera::in_image(const Eigen::Vector2d& uv) const {
  return uv.x() >= 0.0 && uv.y() >= 0.0 && uv.x() <= static_cast<double>(width) &&
         uv.y() <= static_cast<double>(height);
}

Eigen::Matrix<double, 3, 4> PinholeCamera::projection_matrix(const SE3& T_cw) const {
  return K() * T_cw.matrix3x4();
}

}  // namespace dqo
