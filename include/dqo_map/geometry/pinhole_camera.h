#pragma once
// Pinhole camera without distortion (images are rectified before they reach the library).
//
// Pixel convention: pixel (u, v) = (column, row) has its centre at integer coordinates, as in
// OpenCV and ROS CameraInfo, and the image covers the continuous rectangle [0, width] x [0, height]
// used by Box2d::clip and the detection boxes.

#include <Eigen/Core>

#include "dqo_map/geometry/se3.h"

namespace dqo {

struct PinholeCamera {
  double fx = 0.0;
  double fy = 0.0;
  double cx = 0.0;
  double cy = 0.0;
  int width = 0;
  int height = 0;

  Eigen::Matrix3d K() const;

  // p_c must have p_c.z() != 0; points behind the camera project too (callers check depth).
  Eigen::Vector2d project(const Eigen::Vector3d& p_c) const;

  // The point at `depth` along the ray of pixel (u, v): p_c.z() == depth.
  Eigen::Vector3d back_project(double u, double v, double depth) const;

  bool in_image(const Eigen::Vector2d& uv) const;

  // P = K [R_cw | t_cw]: maps homogeneous world points to homogeneous pixels.
  Eigen::Matrix<double, 3, 4> projection_matrix(const SE3& T_cw) const;
};

}  // namespace dqo
