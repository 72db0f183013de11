#pragma once
// A triangle mesh as a shape: procedural meshes (lathe, extrusion, superquadric) and meshes loaded
// by io/. Shading normals are interpolated per triangle corner, averaged only over neighbouring
// faces within a crease angle, so a bottle looks smooth while a cup's rim and a box's edges stay
// sharp. The ground-truth mesh is the rendered mesh itself, so depth lands on it exactly.

#include <array>
#include <string>
#include <vector>

#include "dqo_map/sim/shape.h"
#include "dqo_map/sim/triangle_bvh.h"

namespace dqo::sim {

class MeshShape final : public Shape {
 public:
  // `name` is what type_name() returns ("lathe", "mesh", ...). Degenerate triangles are dropped.
  explicit MeshShape(TriangleMesh mesh, std::string name = "mesh", double crease_deg = 40.0);

  bool intersect(const Ray& ray, double t_min, double t_max, Hit* hit) const override;
  bool any_hit(const Ray& ray, double t_min, double t_max) const override;
  Aabb bounds() const override { return bvh_.bounds(); }
  TriangleMesh surface_mesh() const override { return mesh_; }
  std::string type_name() const override { return name_; }

  const TriangleMesh& mesh() const { return mesh_; }

 private:
  TriangleMesh mesh_;
  std::string name_;
  TriangleBvh bvh_;
  std::vector<std::array<Eigen::Vector3d, 3>> corner_normals_;  // per triangle
  std::vector<Eigen::Vector3d> face_normals_;
};

}  // namespace dqo::sim
