#include "dqo_map/sim/mesh_shape.h"

#include <cmath>
#include <utility>

namespace dqo::sim {
namespace {

// Triangles smaller than this (in m^2) have no reliable normal and add nothing to the picture.
constexpr double kMinArea2 = 1e-24;  // |cross|^2

TriangleMesh drop_degenerate(TriangleMesh mesh) {
  std::vector<std::array<int, 3>> kept;
  kept.reserve(mesh.triangles.size());
  const int n = static_cast<int>(mesh.vertices.size());
  for (const auto& t : mesh.triangles) {
    if (t[0] < 0 || t[1] < 0 || t[2] < 0 || t[0] >= n || t[1] >= n || t[2] >= n) continue;
    const Eigen::Vector3d c = (mesh.vertices[t[1]] - mesh.vertices[t[0]])
                                  .cross(mesh.vertices[t[2]] - mesh.vertices[t[0]]);
    if (c.squaredNorm() > kMinArea2) kept.push_back(t);
  }
  mesh.triangles = std::move(kept);
  return mesh;
}

}  // namespace

MeshShape::MeshShape(TriangleMesh mesh, std::string name, double crease_deg)
    : mesh_(drop_degenerate(std::move(mesh))), name_(std::move(name)), bvh_(mesh_) {
  const size_t nt = mesh_.triangles.size();
  const size_t nv = mesh_.vertices.size();
  face_normals_.resize(nt);
  std::vector<Eigen::Vector3d> area_normals(nt);  // length = twice the area: area weighting
  for (size_t i = 0; i < nt; ++i) {
    const auto& t = mesh_.triangles[i];
    area_normals[i] = (mesh_.vertices[t[1]] - mesh_.vertices[t[0]])
                          .cross(mesh_.vertices[t[2]] - mesh_.vertices[t[0]]);
    face_normals_[i] = area_normals[i].normalized();
  }
  // Triangles around each vertex (compressed rows).
  std::vector<int> start(nv + 1, 0);
  for (const auto& t : mesh_.triangles) {
    for (int k = 0; k < 3; ++k) ++start[t[k] + 1];
  }
  for (size_t v = 0; v < nv; ++v) start[v + 1] += start[v];
  std::vector<int> incident(start[nv]);
  std::vector<int> fill(start.begin(), start.end() - 1);
  for (size_t i = 0; i < nt; ++i) {
    for (int k = 0; k < 3; ++k) incident[fill[mesh_.triangles[i][k]]++] = static_cast<int>(i);
  }
  // A corner averages only the faces around its vertex that bend less than the crease angle from
  // its own face: smooth across a bottle's facets, sharp at a cup's rim.
  const double cos_crease = std::cos(crease_deg * 3.14159265358979323846 / 180.0);
  corner_normals_.resize(nt);
  for (size_t i = 0; i < nt; ++i) {
    for (int k = 0; k < 3; ++k) {
      const int v = mesh_.triangles[i][k];
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (int j = start[v]; j < start[v + 1]; ++j) {
        const int f = incident[j];
        if (face_normals_[f].dot(face_normals_[i]) >= cos_crease) sum += area_normals[f];
      }
      corner_normals_[i][k] = sum.squaredNorm() > 0.0 ? sum.normalized() : face_normals_[i];
    }
  }
}

bool MeshShape::intersect(const Ray& ray, double t_min, double t_max, Hit* hit) const {
  TriangleHit th;
  if (!bvh_.intersect(ray, t_min, t_max, &th)) return false;
  const auto& cn = corner_normals_[th.triangle];
  Eigen::Vector3d n = (1.0 - th.u - th.v) * cn[0] + th.u * cn[1] + th.v * cn[2];
  const Eigen::Vector3d& face = face_normals_[th.triangle];
  // Near a silhouette the interpolated normal can face away from the viewer while the face itself
  // does not; the renderer turns normals by the viewer's side, so keep the two on the same side.
  if (n.squaredNorm() < 1e-20 || n.dot(ray.direction) * face.dot(ray.direction) < 0.0) {
    n = face;
  } else {
    n.normalize();
  }
  hit->t = th.t;
  hit->normal = n;
  hit->tex_point = ray.origin + th.t * ray.direction;
  hit->tex_normal = face;
  hit->part = -1;
  return true;
}

bool MeshShape::any_hit(const Ray& ray, double t_min, double t_max) const {
  return bvh_.any_hit(ray, t_min, t_max);
}

}  // namespace dqo::sim
