#pragma once
// Helpers shared by the sim/ tests: small scenes built by hand, an independent point-to-triangle
// distance, the path of the shipped scenes.

#include <Eigen/Core>
#include <cmath>
#include <limits>
#include <memory>
#include <string>

#include "dqo_map/common/triangle_mesh.h"
#include "dqo_map/sim/primitives.h"
#include "dqo_map/sim/scene.h"
#include "dqo_map/sim/trajectory.h"

namespace dqo::sim::testing {

inline std::string scene_path(const std::string& name) {
  return std::string(DQO_SOURCE_DIR) + "/config/scenes/" + name + ".yaml";
}

// A scene with a camera, white ambient light, one class, no room and a single frame at T_wc.
inline Scene empty_scene(int width, int height, double f, const SE3& T_wc) {
  Scene s;
  s.name = "test";
  s.camera.width = width;
  s.camera.height = height;
  s.camera.fx = f;
  s.camera.fy = f;
  s.camera.cx = 0.5 * (width - 1);
  s.camera.cy = 0.5 * (height - 1);
  s.classes = {{1, "thing"}, {2, "other"}, {3, "third"}};
  s.lighting.ambient = Eigen::Vector3f::Constant(1.0f);
  s.trajectory.push_back({0.0, T_wc});
  s.noise.enabled = false;
  return s;
}

inline SceneObject make_object(uint32_t id, ShapePtr shape, const SE3& T_wo, double scale = 1.0) {
  SceneObject o;
  o.id = id;
  o.class_id = id == 0 ? 0 : 1;
  o.class_name = id == 0 ? "" : "thing";
  o.shape = std::move(shape);
  o.T_wo = T_wo;
  o.scale = scale;
  o.material.colour_a = Eigen::Vector3f(0.5f, 0.5f, 0.5f);
  return o;
}

// Distance from p to the triangle abc (closest point by regions, Ericson, Real-Time Collision
// Detection §5.1.5): independent of the renderer's ray-triangle code.
inline double point_triangle_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                      const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return (p - a).norm();
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return (p - b).norm();
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return (p - (a + d1 / (d1 - d3) * ab)).norm();
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return (p - c).norm();
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return (p - (a + d2 / (d2 - d6) * ac)).norm();
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    return (p - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b))).norm();
  }
  const double denom = 1.0 / (va + vb + vc);
  return (p - (a + ab * (vb * denom) + ac * (vc * denom))).norm();
}

inline double point_mesh_distance(const Eigen::Vector3d& p, const TriangleMesh& mesh) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& t : mesh.triangles) {
    best = std::min(best, point_triangle_distance(p, mesh.vertices[t[0]], mesh.vertices[t[1]],
                                                  mesh.vertices[t[2]]));
  }
  return best;
}

}  // namespace dqo::sim::testing
