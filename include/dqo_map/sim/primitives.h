#pragma once
// Analytic shapes, intersected in closed form (exact depths): quad, box, ellipsoid, capped
// cylinder. All are centred on their local origin; the renderer places them with a pose and a
// uniform scale.

#include "dqo_map/sim/shape.h"

namespace dqo::sim {

// A rectangle in the local z = 0 plane, |x| <= size.x / 2, |y| <= size.y / 2, normal +z. Room
// surfaces (floor, walls, ceiling, posters) are quads: a plane is a quad larger than the room.
class Quad final : public Shape {
 public:
  explicit Quad(const Eigen::Vector2d& size);
  bool intersect(const Ray& ray, double t_min, double t_max, Hit* hit) const override;
  Aabb bounds() const override;
  TriangleMesh surface_mesh() const override;
  std::string type_name() const override { return "quad"; }

 private:
  Eigen::Vector2d half_;
};

// |x| <= size.x / 2 etc. From inside, the exit face is returned (a room can be a box seen from
// within).
class Box final : public Shape {
 public:
  explicit Box(const Eigen::Vector3d& size);
  bool intersect(const Ray& ray, double t_min, double t_max, Hit* hit) const override;
  Aabb bounds() const override;
  TriangleMesh surface_mesh() const override;
  std::string type_name() const override { return "box"; }

 private:
  Eigen::Vector3d half_;
};

// (x/a)^2 + (y/b)^2 + (z/c)^2 = 1 with radii (a, b, c); a sphere when they are equal.
class Ellipsoid final : public Shape {
 public:
  explicit Ellipsoid(const Eigen::Vector3d& radii, int mesh_segments = 128);
  bool intersect(const Ray& ray, double t_min, double t_max, Hit* hit) const override;
  Aabb bounds() const override;
  TriangleMesh surface_mesh() const override;
  std::string type_name() const override { return "ellipsoid"; }

 private:
  Eigen::Vector3d radii_;
  Eigen::Vector3d inv_radii_;
  int mesh_segments_;
};

// Axis z, x^2 + y^2 <= r^2, |z| <= height / 2, closed by two flat caps.
class Cylinder final : public Shape {
 public:
  Cylinder(double radius, double height, int mesh_segments = 128);
  bool intersect(const Ray& ray, double t_min, double t_max, Hit* hit) const override;
  Aabb bounds() const override;
  TriangleMesh surface_mesh() const override;
  std::string type_name() const override { return "cylinder"; }

 private:
  double radius_;
  double half_height_;
  int mesh_segments_;
};

// Real roots of a t^2 + 2 b t + c = 0 (note the 2 b), t0 <= t1, computed without cancellation.
// False when there are none (or a == 0).
bool solve_quadratic_half_b(double a, double b, double c, double* t0, double* t1);

}  // namespace dqo::sim
