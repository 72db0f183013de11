#pragma once
// Synthetic views of ellipsoids for the object-stage tests: cameras looking at a point, exact
// detection boxes (the projected conic's box) and depth images ray-cast against the ellipsoids.
#include <cmath>
#include <limits>
#include <vector>
#include <Eigen/Geometry>
#include "dqo_map/common/dataset.h"
#include "dqo_map/geometry/conic.h"
#include "dqo_map/geometry/dual_quadric.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"

namespace dqo::objects::test {

inline PinholeCamera test_camera(int width = 640, int height = 480) {
  PinholeCamera c;
  c.fx = c.fy = 525.0 * width / 640.0;
  c.cx = 0.5 * width - 0.5;
  c.cy = 0.5 * height - 0.5;
  c.width = width;
  c.height = height;
  return c;
}

// Optical camera (x right, y down, z forward) at `eye` looking at `target`, world z up.
inline SE3 look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - eye).normalized();
  Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ());
  if (x.norm() < 1e-9) x = Eigen::Vector3d::UnitX();
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R;
  R.col(0) = x;
  R.col(1) = y;
  R.col(2) = z;
  return SE3::from_rotation_translation(R, eye);
}

// The exact detection box of an ellipsoid (its conic's box, clipped); nullopt when not in view.
inline std::optional<Box2d> exact_box(const DualQuadric& q, const PinholeCamera& camera, const SE3& T_wc) {
  const auto p = projected_box(q, camera, T_wc.inverse(), 0.05);
  if (!p || p->box.area() <= 0.0) return std::nullopt;
  return p->box;
}

inline Detection2d detection(const Box2d& box, int class_id = 1, float score = 0.9f) {
  Detection2d d;
  d.box = box;
  d.class_id = class_id;
  d.class_name = "class" + std::to_string(class_id);
  d.score = score;
  return d;
}

// Depth (metres) of the nearest ellipsoid along each pixel ray; `background` where none is hit
// (0 = no measurement).
inline DepthImage render_depth(const std::vector<DualQuadric>& quadrics, const PinholeCamera& camera,
                               const SE3& T_wc, float background = 0.0f) {
  DepthImage depth(camera.width, camera.height, 1, background);
  const Eigen::Matrix3d R_wc = T_wc.rotation();
  const Eigen::Vector3d o = T_wc.translation();
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const Eigen::Vector3d d_c((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1.0);
      const Eigen::Vector3d d_w = R_wc * d_c;
      double best = std::numeric_limits<double>::infinity();
      for (const DualQuadric& q : quadrics) {
        const Eigen::Matrix3d Rt = q.rotation().transpose();
        const Eigen::Array3d inv_a = q.semi_axes().cwiseInverse().array();
        const Eigen::Array3d p = (Rt * (o - q.centre())).array() * inv_a;
        const Eigen::Array3d r = (Rt * d_w).array() * inv_a;
        const double A = (r * r).sum(), B = 2.0 * (p * r).sum(), C = (p * p).sum() - 1.0;
        const double disc = B * B - 4.0 * A * C;
        if (disc < 0.0) continue;
        const double s = (-B - std::sqrt(disc)) / (2.0 * A);
        if (s > 0.0 && s < best) best = s;
      }
      if (std::isfinite(best)) depth.at(u, v) = static_cast<float>(best);
    }
  }
  return depth;
}

inline DepthView view_of(const DepthImage& depth) {
  DepthView v;
  v.data = depth.data.data();
  v.width = depth.width;
  v.height = depth.height;
  return v;
}

// A pouf (the room scene's) on the floor against a wall, world z up: the wall's face at x = -1.49,
// the floor's at z = 0; wall and floor are flat ellipsoids 2 cm thick, 40 m wide.
struct CornerScene {
  DualQuadric wall = DualQuadric::from_params(Eigen::Vector3d(-1.5, 0.0, 2.0), Eigen::Matrix3d::Identity(),
                                              Eigen::Vector3d(0.01, 20.0, 20.0));
  DualQuadric floor = DualQuadric::from_params(Eigen::Vector3d(0.0, 0.0, -0.01), Eigen::Matrix3d::Identity(),
                                               Eigen::Vector3d(20.0, 20.0, 0.01));
  DualQuadric pouf = DualQuadric::from_params(Eigen::Vector3d(-1.27, 0.0, 0.14), Eigen::Matrix3d::Identity(),
                                              Eigen::Vector3d(0.19, 0.19, 0.14));
};

}  // namespace dqo::objects::test
