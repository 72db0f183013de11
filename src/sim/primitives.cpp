#include "dqo_map/sim/primitives.h"

#include <cmath>

#include "dqo_map/sim/procedural_mesh.h"

namespace dqo::sim {

bool solve_quadratic_half_b(double a, double b, double c, double* t0, double* t1) {
  if (a == 0.0) return false;
  const double disc = b * b - a * c;
  if (disc < 0.0) return false;
  // q carries the sign of b so that -b and the root never cancel; the other root comes from the
  // product of the roots, c / a.
  const double q = -(b + std::copysign(std::sqrt(disc), b));
  double r0 = q / a;
  double r1 = q != 0.0 ? c / q : r0;
  if (r0 > r1) std::swap(r0, r1);
  *t0 = r0;
  *t1 = r1;
  return true;
}

// ------------------------------------------------------------------------------------------ Quad

Quad::Quad(const Eigen::Vector2d& size) : half_(0.5 * size) {}

bool Quad::intersect(const Ray& ray, double t_min, double t_max, Hit* hit) const {
  const Eigen::Vector3d& o = ray.origin;
  const Eigen::Vector3d& d = ray.direction;
  if (d.z() == 0.0) return false;
  const double t = -o.z() / d.z();
  if (!(t > t_min && t < t_max)) return false;
  const double x = o.x() + t * d.x();
  const double y = o.y() + t * d.y();
  if (std::abs(x) > half_.x() || std::abs(y) > half_.y()) return false;
  hit->t = t;
  hit->normal = Eigen::Vector3d::UnitZ();
  hit->tex_point = Eigen::Vector3d(x, y, 0.0);
  hit->tex_normal = hit->normal;
  hit->part = -1;
  return true;
}

Aabb Quad::bounds() const {
  Aabb b;
  b.min = Eigen::Vector3d(-half_.x(), -half_.y(), 0.0);
  b.max = Eigen::Vector3d(half_.x(), half_.y(), 0.0);
  return b;
}

TriangleMesh Quad::surface_mesh() const { return make_quad_mesh(2.0 * half_); }

// ------------------------------------------------------------------------------------------- Box

Box::Box(const Eigen::Vector3d& size) : half_(0.5 * size) {}

bool Box::intersect(const Ray& ray, double t_min, double t_max, Hit* hit) const {
  const Eigen::Vector3d& o = ray.origin;
  const Eigen::Vector3d& d = ray.direction;
  double t_near = -kInfinity, t_far = kInfinity;
  int axis_near = -1, axis_far = -1;
  for (int i = 0; i < 3; ++i) {
    if (d[i] == 0.0) {
      if (std::abs(o[i]) > half_[i]) return false;
      continue;
    }
    const double inv = 1.0 / d[i];
    double t0 = (-half_[i] - o[i]) * inv;
    double t1 = (half_[i] - o[i]) * inv;
    if (t0 > t1) std::swap(t0, t1);
    if (t0 > t_near) {
      t_near = t0;
      axis_near = i;
    }
    if (t1 < t_far) {
      t_far = t1;
      axis_far = i;
    }
  }
  if (t_near > t_far) return false;
  double t;
  int axis;
  double sign;
  if (t_near > t_min && t_near < t_max) {
    // Entering: the face looks against the ray.
    t = t_near;
    axis = axis_near;
    sign = d[axis] > 0.0 ? -1.0 : 1.0;
  } else if (t_far > t_min && t_far < t_max) {
    // Leaving from inside (a room box seen from within): the face looks along the ray.
    t = t_far;
    axis = axis_far;
    sign = d[axis] > 0.0 ? 1.0 : -1.0;
  } else {
    return false;
  }
  Eigen::Vector3d p = o + t * d;
  p[axis] = sign * half_[axis];  // exactly on the face: the texture must not flicker across it
  hit->t = t;
  hit->normal = Eigen::Vector3d::Zero();
  hit->normal[axis] = sign;
  hit->tex_point = p;
  hit->tex_normal = hit->normal;
  hit->part = -1;
  return true;
}

Aabb Box::bounds() const {
  Aabb b;
  b.min = -half_;
  b.max = half_;
  return b;
}

TriangleMesh Box::surface_mesh() const { return make_box_mesh(2.0 * half_); }

// ------------------------------------------------------------------------------------- Ellipsoid

Ellipsoid::Ellipsoid(const Eigen::Vector3d& radii, int mesh_segments)
    : radii_(radii), inv_radii_(radii.cwiseInverse()), mesh_segments_(mesh_segments) {}

bool Ellipsoid::intersect(const Ray& ray, double t_min, double t_max, Hit* hit) const {
  // In the frame where the ellipsoid is the unit sphere the ray keeps its parameter t.
  const Eigen::Vector3d o = ray.origin.cwiseProduct(inv_radii_);
  const Eigen::Vector3d d = ray.direction.cwiseProduct(inv_radii_);
  double t0, t1;
  if (!solve_quadratic_half_b(d.squaredNorm(), o.dot(d), o.squaredNorm() - 1.0, &t0, &t1)) {
    return false;
  }
  double t;
  if (t0 > t_min && t0 < t_max) {
    t = t0;
  } else if (t1 > t_min && t1 < t_max) {
    t = t1;
  } else {
    return false;
  }
  const Eigen::Vector3d p = ray.origin + t * ray.direction;
  hit->t = t;
  hit->normal = p.cwiseProduct(inv_radii_).cwiseProduct(inv_radii_).normalized();
  hit->tex_point = p;
  hit->tex_normal = hit->normal;
  hit->part = -1;
  return true;
}

Aabb Ellipsoid::bounds() const {
  Aabb b;
  b.min = -radii_;
  b.max = radii_;
  return b;
}

TriangleMesh Ellipsoid::surface_mesh() const { return make_ellipsoid_mesh(radii_, mesh_segments_); }

// -------------------------------------------------------------------------------------- Cylinder

Cylinder::Cylinder(double radius, double height, int mesh_segments)
    : radius_(radius), half_height_(0.5 * height), mesh_segments_(mesh_segments) {}

bool Cylinder::intersect(const Ray& ray, double t_min, double t_max, Hit* hit) const {
  const Eigen::Vector3d& o = ray.origin;
  const Eigen::Vector3d& d = ray.direction;
  double best = t_max;
  int kind = 0;  // 1 side, 2 top cap, 3 bottom cap
  double t0, t1;
  if (solve_quadratic_half_b(d.x() * d.x() + d.y() * d.y(), o.x() * d.x() + o.y() * d.y(),
                             o.x() * o.x() + o.y() * o.y() - radius_ * radius_, &t0, &t1)) {
    for (const double t : {t0, t1}) {
      if (t > t_min && t < best && std::abs(o.z() + t * d.z()) <= half_height_) {
        best = t;
        kind = 1;
        break;
      }
    }
  }
  if (d.z() != 0.0) {
    for (const double z : {half_height_, -half_height_}) {
      const double t = (z - o.z()) / d.z();
      if (!(t > t_min && t < best)) continue;
      const double x = o.x() + t * d.x();
      const double y = o.y() + t * d.y();
      if (x * x + y * y <= radius_ * radius_) {
        best = t;
        kind = z > 0.0 ? 2 : 3;
      }
    }
  }
  if (kind == 0) return false;
  Eigen::Vector3d p = o + best * d;
  if (kind == 1) {
    hit->normal = Eigen::Vector3d(p.x(), p.y(), 0.0).normalized();
  } else {
    p.z() = kind == 2 ? half_height_ : -half_height_;
    hit->normal = Eigen::Vector3d(0.0, 0.0, kind == 2 ? 1.0 : -1.0);
  }
  hit->t = best;
  hit->tex_point = p;
  hit->tex_normal = hit->normal;
  hit->part = -1;
  return true;
}

Aabb Cylinder::bounds() const {
  Aabb b;
  b.min = Eigen::Vector3d(-radius_, -radius_, -half_height_);
  b.max = Eigen::Vector3d(radius_, radius_, half_height_);
  return b;
}

TriangleMesh Cylinder::surface_mesh() const {
  return make_cylinder_mesh(radius_, 2.0 * half_height_, mesh_segments_);
}

}  // namespace dqo::sim
