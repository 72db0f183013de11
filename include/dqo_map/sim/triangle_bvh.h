#pragma once
// Bounding volume hierarchy over the triangles of a mesh, built with the binned surface area
// heuristic, traversed nearest-child first with a fixed stack (no allocation per ray).
// Triangles are intersected with Möller–Trumbore in double, so mesh depths are as exact as the
// analytic shapes' and the hit lies on the very triangle written to meshes_gt.

#include <Eigen/Core>
#include <vector>

#include "dqo_map/common/triangle_mesh.h"
#include "dqo_map/sim/shape.h"

namespace dqo::sim {

struct TriangleHit {
  double t = kInfinity;
  int triangle = -1;  // index into the mesh's triangles
  double u = 0.0;     // barycentric weights of vertex 1 and 2 (vertex 0: 1 - u - v)
  double v = 0.0;
};

class TriangleBvh {
 public:
  TriangleBvh() = default;
  explicit TriangleBvh(const TriangleMesh& mesh);

  bool intersect(const Ray& ray, double t_min, double t_max, TriangleHit* hit) const;
  bool any_hit(const Ray& ray, double t_min, double t_max) const;

  const Aabb& bounds() const { return bounds_; }
  int depth() const { return depth_; }
  int num_nodes() const { return static_cast<int>(nodes_.size()); }

  // Deep enough for any tree the builder makes: it stops splitting at this depth.
  static constexpr int kMaxDepth = 60;

 private:
  struct Node {
    Aabb box;
    int first = 0;  // leaf: first entry in tris_; inner: index of the right child (left is +1)
    int count = 0;  // leaf: number of triangles; inner: 0
  };
  // Precomputed for Möller–Trumbore: one vertex and two edges.
  struct Tri {
    Eigen::Vector3d v0, e1, e2;
    int index;
  };

  int build(std::vector<int>& order, std::vector<Aabb>& boxes,
            std::vector<Eigen::Vector3d>& centres, int begin, int end, int level);
  static bool intersect_triangle(const Tri& tri, const Ray& ray, double t_min, double t_max,
                                 TriangleHit* hit);

  std::vector<Node> nodes_;
  std::vector<Tri> tris_;
  Aabb bounds_;
  int depth_ = 0;
};

}  // namespace dqo::sim
