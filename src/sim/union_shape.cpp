#include "dqo_map/sim/union_shape.h"

#include <utility>

#include "dqo_map/sim/procedural_mesh.h"

namespace dqo::sim {

Aabb transform_aabb(const Aabb& b, const Eigen::Matrix3d& R, const Eigen::Vector3d& t,
                    double scale) {
  Aabb out;
  if (b.empty()) return out;
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector3d c((k & 1) ? b.max.x() : b.min.x(), (k & 2) ? b.max.y() : b.min.y(),
                            (k & 4) ? b.max.z() : b.min.z());
    out.extend(R * (scale * c) + t);
  }
  return out;
}

UnionShape::UnionShape(std::vector<UnionPart> parts) {
  parts_.reserve(parts.size());
  for (auto& p : parts) {
    Part part;
    part.shape = std::move(p.shape);
    part.T_up = p.T_up;
    part.R_up = p.T_up.rotation();
    part.t_up = p.T_up.translation();
    part.rotated = !part.R_up.isIdentity(0.0);
    part.local_bounds = part.shape->bounds();
    bounds_.extend(transform_aabb(part.local_bounds, part.R_up, part.t_up));
    parts_.push_back(std::move(part));
  }
}

Ray UnionShape::to_part(const Part& part, const Ray& ray) {
  // A rigid change of frame: the ray parameter t is the same in the part's frame.
  Ray local;
  if (part.rotated) {
    local.origin = part.R_up.transpose() * (ray.origin - part.t_up);
    local.direction = part.R_up.transpose() * ray.direction;
  } else {
    local.origin = ray.origin - part.t_up;
    local.direction = ray.direction;
  }
  return local;
}

bool UnionShape::intersect(const Ray& ray, double t_min, double t_max, Hit* hit) const {
  bool found = false;
  double best = t_max;
  for (size_t i = 0; i < parts_.size(); ++i) {
    const Part& part = parts_[i];
    const Ray local = to_part(part, ray);
    double t_enter;
    if (!part.local_bounds.intersect(local.origin, local.direction.cwiseInverse(), t_min, best,
                                     &t_enter)) {
      continue;
    }
    Hit h;
    if (!part.shape->intersect(local, t_min, best, &h)) continue;
    best = h.t;
    *hit = h;
    hit->normal = part.rotated ? Eigen::Vector3d(part.R_up * h.normal) : h.normal;
    hit->part = static_cast<int>(i);
    found = true;
  }
  return found;
}

bool UnionShape::any_hit(const Ray& ray, double t_min, double t_max) const {
  for (const Part& part : parts_) {
    const Ray local = to_part(part, ray);
    double t_enter;
    if (!part.local_bounds.intersect(local.origin, local.direction.cwiseInverse(), t_min, t_max,
                                     &t_enter)) {
      continue;
    }
    if (part.shape->any_hit(local, t_min, t_max)) return true;
  }
  return false;
}

TriangleMesh UnionShape::surface_mesh() const {
  // The parts' surfaces side by side: where parts overlap, the inner pieces stay in the mesh
  // (a boolean union would need mesh CSG). Depth never lands on them, so checks against the mesh
  // are unaffected; only a surface-sampling metric would see a little extra area.
  TriangleMesh mesh;
  for (const Part& part : parts_) append_mesh(part.shape->surface_mesh(), part.T_up, 1.0, &mesh);
  return mesh;
}

}  // namespace dqo::sim
