#pragma once
// The interface every shape of the synthetic world implements: ray intersection in the shape's own
// (local) frame, a conservative local bounding box for culling, and a fine triangle mesh of the
// surface for the ground truth (meshes_gt).
//
// Rays are deliberately not normalised. The renderer casts camera rays with d_c.z = 1, so the ray
// parameter t of a hit *is* its depth (z in the camera frame); rotation, translation and uniform
// scale map a ray to another ray with the same t, so t survives the trip into any local frame
// without a division. Every shape therefore accepts any non-zero direction.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <limits>
#include <memory>
#include <string>
#include <utility>

#include "dqo_map/common/triangle_mesh.h"

namespace dqo::sim {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

// o + t d, in double: depths must be exact to float precision after the frame changes.
struct Ray {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();
};

struct Hit {
  double t = kInfinity;
  // Unit, outward (away from the solid; for a quad, its +z side), in the frame of the shape that
  // was asked. The renderer turns it towards the viewer itself (surfaces are two-sided).
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  // Where the solid texture is evaluated: the hit in the frame of the innermost part that was hit,
  // so that a part's texture turns with the part. No UVs needed.
  Eigen::Vector3d tex_point = Eigen::Vector3d::Zero();
  // The outward normal in that same frame (a checker picks the two axes across the surface).
  Eigen::Vector3d tex_normal = Eigen::Vector3d::UnitZ();
  // Index of the union part that was hit (selects its material), -1 for a shape without parts.
  int part = -1;
};

// Axis-aligned box; empty (min > max) by default so that extend() works from nothing.
struct Aabb {
  Eigen::Vector3d min = Eigen::Vector3d::Constant(kInfinity);
  Eigen::Vector3d max = Eigen::Vector3d::Constant(-kInfinity);

  bool empty() const { return (min.array() > max.array()).any(); }
  void extend(const Eigen::Vector3d& p) {
    min = min.cwiseMin(p);
    max = max.cwiseMax(p);
  }
  void extend(const Aabb& b) {
    min = min.cwiseMin(b.min);
    max = max.cwiseMax(b.max);
  }
  Eigen::Vector3d centre() const { return 0.5 * (min + max); }
  Eigen::Vector3d extent() const { return max - min; }

  // Slab test. inv_dir holds 1/d per axis (±inf for a zero component). On success *t_enter is where
  // the ray enters the box clipped to [t_min, t_max] (t_min when it starts inside).
  bool intersect(const Eigen::Vector3d& origin, const Eigen::Vector3d& inv_dir, double t_min,
                 double t_max, double* t_enter) const {
    for (int i = 0; i < 3; ++i) {
      double t0 = (min[i] - origin[i]) * inv_dir[i];
      double t1 = (max[i] - origin[i]) * inv_dir[i];
      if (t0 > t1) std::swap(t0, t1);
      // Written so that a NaN (0 * inf on a slab boundary) leaves the interval unchanged.
      t_min = t0 > t_min ? t0 : t_min;
      t_max = t1 < t_max ? t1 : t_max;
      if (t_min > t_max) return false;
    }
    *t_enter = t_min;
    return true;
  }
};

class Shape {
 public:
  virtual ~Shape() = default;

  // The nearest hit with t in (t_min, t_max): fills *hit, returns true.
  virtual bool intersect(const Ray& ray, double t_min, double t_max, Hit* hit) const = 0;

  // Whether any hit with t in (t_min, t_max) exists (visibility and shadow queries); meshes
  // override it to stop at the first triangle instead of searching for the nearest.
  virtual bool any_hit(const Ray& ray, double t_min, double t_max) const {
    Hit hit;
    return intersect(ray, t_min, t_max, &hit);
  }

  // Conservative bounding box in the local frame (used for culling, so never too small).
  virtual Aabb bounds() const = 0;

  // A fine, closed mesh of the surface in the local frame, counter-clockwise seen from outside.
  // Mesh shapes return themselves; curved primitives a tessellation whose distance to every point
  // the shape can return is about 0.5 mm per metre of radius at most, so that back-projected depth
  // can be checked against it at the millimetre.
  virtual TriangleMesh surface_mesh() const = 0;

  virtual std::string type_name() const = 0;
};

using ShapePtr = std::shared_ptr<const Shape>;

}  // namespace dqo::sim
