#include "dqo_map/geometry/conic.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

namespace dqo {

Eigen::Matrix3d project_quadric(const DualQuadric& quadric, const Eigen::Matrix<double, 3, 4>& P) {
  const Eigen::Matrix3d C = P * quadric.matrix() * P.transpose();
  return 0.5 * (C + C.transpose());
}

std::optional<Box2d> conic_bounding_box(const Eigen::Matrix3d& Cstar) {
  if (!Cstar.allFinite()) return std::nullopt;
  const double scale = Cstar.cwiseAbs().maxCoeff();
  const double c22 = Cstar(2, 2);
  // Relative threshold: a camera plane nearly tangent to the ellipsoid sends the box to infinity.
  if (!(scale > 0.0) || !(c22 < -1e-12 * scale)) return std::nullopt;
  const double disc_x = Cstar(0, 2) * Cstar(0, 2) - Cstar(0, 0) * c22;
  const double disc_y = Cstar(1, 2) * Cstar(1, 2) - Cstar(1, 1) * c22;
  if (disc_x < 0.0 || disc_y < 0.0) return std::nullopt;
  const double sx = std::sqrt(disc_x);
  const double sy = std::sqrt(disc_y);
  // c22 < 0, so (c02 + s)/c22 is the smaller root.
  Box2d box{(Cstar(0, 2) + sx) / c22, (Cstar(1, 2) + sy) / c22, (Cstar(0, 2) - sx) / c22,
            (Cstar(1, 2) - sy) / c22};
  if (!box.valid()) return std::nullopt;
  return box;
}

bool in_front_of_camera(const DualQuadric& quadric, const SE3& T_cw, double near) {
  const Eigen::Vector3d r3 = T_cw.rotation().row(2).transpose();
  const double z_centre = (T_cw * quadric.centre()).z();
  const double half_extent = std::sqrt(std::max(0.0, r3.dot(quadric.shape_matrix() * r3)));
  return z_centre - half_extent > near;
}

std::optional<ProjectedBox> projected_box(const DualQuadric& quadric, const PinholeCamera& camera,
                                          const SE3& T_cw, double near) {
  if (!in_front_of_camera(quadric, T_cw, near)) return std::nullopt;
  const std::optional<Box2d> box =
      conic_bounding_box(project_quadric(quadric, camera.projection_matrix(T_cw)));
  if (!box) return std::nullopt;
  ProjectedBox out;
  out.unclipped = *box;
  out.box = box->clip(camera.width, camera.height);
  out.fraction_in_image = out.box.area() / box->area();
  return out;
}

std::optional<Ellipse2d> conic_ellipse(const Eigen::Matrix3d& Cstar) {
  if (!conic_bounding_box(Cstar)) return std::nullopt;
  const Eigen::Matrix3d C = Cstar / -Cstar(2, 2);
  Ellipse2d e;
  e.centre = -C.block<2, 1>(0, 2);
  const Eigen::Matrix2d M = C.block<2, 2>(0, 0) + e.centre * e.centre.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(0.5 * (M + M.transpose()));
  if (eig.info() != Eigen::Success || !(eig.eigenvalues()(0) > 0.0)) return std::nullopt;
  // Eigenvalues ascend: the larger axis is the second.
  e.semi_axes = Eigen::Vector2d(std::sqrt(eig.eigenvalues()(1)), std::sqrt(eig.eigenvalues()(0)));
  const Eigen::Vector2d major = eig.eigenvectors().col(1);
  e.angle = std::atan2(major.y(), major.x());
  return e;
}

}  // namespace dqo
