#pragma once
// Analytic test surfaces for the mesh/ tests: icospheres, plane patches, and depth views of
// spheres rendered by exact ray-sphere intersection (independent of any rasteriser).

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "dqo_map/common/triangle_mesh.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"
#include "dqo_map/mesh/tsdf_fusion.h"

namespace dqo::mesh::test_util {

// An icosahedron subdivided `levels` times, vertices pushed onto the sphere (20 * 4^levels
// triangles, counter-clockwise from outside).
inline TriangleMesh icosphere(const Eigen::Vector3d& centre, double radius, int levels) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Eigen::Vector3d> v = {{-1, t, 0}, {1, t, 0},  {-1, -t, 0}, {1, -t, 0},
                                    {0, -1, t}, {0, 1, t},  {0, -1, -t}, {0, 1, -t},
                                    {t, 0, -1}, {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  for (auto& p : v) p.normalize();
  std::vector<std::array<int, 3>> f = {{0, 11, 5}, {0, 5, 1},   {0, 1, 7},   {0, 7, 10},
                                       {0, 10, 11}, {1, 5, 9},  {5, 11, 4},  {11, 10, 2},
                                       {10, 7, 6}, {7, 1, 8},   {3, 9, 4},   {3, 4, 2},
                                       {3, 2, 6},  {3, 6, 8},   {3, 8, 9},   {4, 9, 5},
                                       {2, 4, 11}, {6, 2, 10},  {8, 6, 7},   {9, 8, 1}};
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<int, int>, int> midpoint;
    auto mid = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      const auto it = midpoint.find(key);
      if (it != midpoint.end()) return it->second;
      v.push_back((v[a] + v[b]).normalized());
      const int i = static_cast<int>(v.size()) - 1;
      midpoint.emplace(key, i);
      return i;
    };
    std::vector<std::array<int, 3>> g;
    for (const auto& tri : f) {
      const int ab = mid(tri[0], tri[1]), bc = mid(tri[1], tri[2]), ca = mid(tri[2], tri[0]);
      g.push_back({tri[0], ab, ca});
      g.push_back({tri[1], bc, ab});
      g.push_back({tri[2], ca, bc});
      g.push_back({ab, bc, ca});
    }
    f = std::move(g);
  }
  TriangleMesh m;
  for (const auto& p : v) m.vertices.push_back(centre + radius * p);
  m.triangles = f;
  return m;
}

// A square patch of side `size` in the plane z = `z`, centred on the z axis, n x n cells.
inline TriangleMesh plane_patch(double size, int n, double z) {
  TriangleMesh m;
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      m.vertices.emplace_back(size * (static_cast<double>(i) / n - 0.5),
                              size * (static_cast<double>(j) / n - 0.5), z);
    }
  }
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i;
      m.triangles.push_back({a, a + 1, a + n + 2});
      m.triangles.push_back({a, a + n + 2, a + n + 1});
    }
  }
  return m;
}

inline TriangleMesh merged(const TriangleMesh& a, const TriangleMesh& b) {
  TriangleMesh m = a;
  const int offset = static_cast<int>(a.vertices.size());
  m.vertices.insert(m.vertices.end(), b.vertices.begin(), b.vertices.end());
  for (const auto& t : b.triangles) {
    m.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
  }
  return m;
}

struct Sphere {
  Eigen::Vector3d centre;
  double radius;
};

// Camera at `position` looking at `target`; optical frame (x right, y down, z forward).
inline SE3 look_at(const Eigen::Vector3d& position, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - position).normalized();
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  if (std::abs(z.dot(up)) > 0.95) up = Eigen::Vector3d::UnitY();
  const Eigen::Vector3d x = z.cross(up).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R_wc;
  R_wc << x, y, z;
  return SE3::from_rotation_translation(R_wc, position);
}

// Exact depth (z in the camera) and constant colour of the nearest sphere per pixel.
inline FusionView render_spheres(const PinholeCamera& camera, const SE3& T_wc,
                                 const std::vector<Sphere>& spheres,
                                 const Eigen::Vector3d& colour) {
  FusionView view;
  view.camera = camera;
  view.T_wc = T_wc;
  const size_t pixels = static_cast<size_t>(camera.width) * camera.height;
  view.depth.assign(pixels, 0.0f);
  view.rgb.assign(3 * pixels, 0.0f);
  const Eigen::Matrix3d R_wc = T_wc.rotation();
  const Eigen::Vector3d o = T_wc.translation();
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      // Ray with unit z in the camera: the ray parameter is the depth.
      const Eigen::Vector3d d = R_wc * camera.back_project(u, v, 1.0);
      double best = std::numeric_limits<double>::infinity();
      for (const Sphere& s : spheres) {
        const Eigen::Vector3d oc = o - s.centre;
        const double a = d.squaredNorm(), b = 2.0 * d.dot(oc);
        const double c = oc.squaredNorm() - s.radius * s.radius;
        const double disc = b * b - 4.0 * a * c;
        if (disc < 0.0) continue;
        const double hit = (-b - std::sqrt(disc)) / (2.0 * a);
        if (hit > 0.0) best = std::min(best, hit);
      }
      if (!std::isfinite(best)) continue;
      const size_t i = static_cast<size_t>(v) * camera.width + u;
      view.depth[i] = static_cast<float>(best);
      for (int k = 0; k < 3; ++k) view.rgb[3 * i + k] = static_cast<float>(colour[k]);
    }
  }
  return view;
}

// `count` cameras at `distance` from `target`, directions spread over the sphere (Fibonacci).
inline std::vector<SE3> views_around(const Eigen::Vector3d& target, double distance, int count) {
  std::vector<SE3> poses;
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < count; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / count;
    const double r = std::sqrt(1.0 - z * z);
    const Eigen::Vector3d dir(r * std::cos(golden * i), r * std::sin(golden * i), z);
    poses.push_back(look_at(target + distance * dir, target));
  }
  return poses;
}

}  // namespace dqo::mesh::test_util
