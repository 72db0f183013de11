#pragma once
// Several shapes under one object ID (a laptop's base and hinged screen, a table's top and legs),
// each part with its own pose in the union's frame and its own material slot.

#include <vector>

#include "dqo_map/geometry/se3.h"
#include "dqo_map/sim/shape.h"

namespace dqo::sim {

struct UnionPart {
  ShapePtr shape;
  SE3 T_up;  // part frame to union frame
};

class UnionShape final : public Shape {
 public:
  explicit UnionShape(std::vector<UnionPart> parts);

  // Hit::part is the index of the part hit; tex_point and tex_normal stay in that part's frame.
  bool intersect(const Ray& ray, double t_min, double t_max, Hit* hit) const override;
  bool any_hit(const Ray& ray, double t_min, double t_max) const override;
  Aabb bounds() const override { return bounds_; }
  TriangleMesh surface_mesh() const override;
  std::string type_name() const override { return "union"; }

  int num_parts() const { return static_cast<int>(parts_.size()); }

 private:
  struct Part {
    ShapePtr shape;
    Eigen::Matrix3d R_up;  // rotation of the part into the union frame
    Eigen::Vector3d t_up;
    SE3 T_up;
    bool rotated = false;  // false: R_up is the identity and a translation suffices
    Aabb local_bounds;     // in the part frame
  };
  static Ray to_part(const Part& part, const Ray& ray);

  std::vector<Part> parts_;
  Aabb bounds_;
};

// The box of `b` after p -> R * (scale * p) + t (the box around its 8 transformed corners).
Aabb transform_aabb(const Aabb& b, const Eigen::Matrix3d& R, const Eigen::Vector3d& t,
                    double scale = 1.0);

}  // namespace dqo::sim
