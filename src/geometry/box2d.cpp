#include "dqo_map/geometry/box2d.h"

#include <algorithm>
#include <cmath>

namespace dqo {

double Box2d::area() const {
  return std::max(0.0, width()) * std::max(0.0, height());
}

bool Box2d::valid() const {
  return std::isfinite(x_min) && std::isfinite(y_min) && std::isfinite(x_max) &&
         std::isfinite(y_max) && x_max > x_min && y_max > y_min;
}

Box2d Box2d::clip(int image_width, int image_height) const {
  const double w = static_cast<double>(image_width);
  const double h = static_cast<double>(image_height);
  return {std::clamp(x_min, 0.0, w), std::clamp(y_min, 0.0, h), std::clamp(x_max, 0.0, w),
          std::clamp(y_max, 0.0, h)};
}

std::array<bool, 4> Box2d::edges_touching_border(int image_width, int image_height,
                                                 double margin_px) const {
  return {x_min <= margin_px, x_max >= static_cast<double>(image_width) - margin_px,
          y_min <= margin_px, y_max >= static_cast<double>(image_height) - margin_px};
}

bool Box2d::touches_border(int image_width, int image_height, double margin_px) const {
  const std::array<bool, 4> e = edges_touching_border(image_width, image_height, margin_px);
  return e[0] || e[1] || e[2] || e[3];
}

std::array<Eigen::Vector3d, 4> Box2d::edge_lines() const {
  // x = c is the line (1, 0, −c); y = c is (0, 1, −c).
  return {Eigen::Vector3d(1.0, 0.0, -x_min), Eigen::Vector3d(1.0, 0.0, -x_max),
          Eigen::Vector3d(0.0, 1.0, -y_min), Eigen::Vector3d(0.0, 1.0, -y_max)};
}

Box2d intersection(const Box2d& a, const Box2d& b) {
  return {std::max(a.x_min, b.x_min), std::max(a.y_min, b.y_min), std::min(a.x_max, b.x_max),
          std::min(a.y_max, b.y_max)};
}

double iou(const Box2d& a, const Box2d& b) {
  const double inter = intersection(a, b).area();
  const double uni = a.area() + b.area() - inter;
  return uni > 0.0 ? inter / uni : 0.0;
}

double overlap_ratio(const Box2d& big, const Box2d& small) {
  const double small_area = small.area();
  return small_area > 0.0 ? intersection(big, small).area() / small_area : 0.0;
}

Eigen::Vector4d plane_from_line(const Eigen::Matrix<double, 3, 4>& P, const Eigen::Vector3d& l) {
  return P.transpose() * l;
}

}  // namespace dqo
