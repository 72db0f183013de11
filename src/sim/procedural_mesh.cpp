#include "dqo_map/sim/procedural_mesh.h"

#include <algorithm>
#include <cmath>

#include "catmull_rom.h"

namespace dqo::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Connects consecutive rings of vertices: a ring of one vertex is a pole (fan), otherwise every
// ring has the same count n and consecutive rings are joined by quads. Fans and quads are wound
// alike (each shared edge is walked once each way), so one flip orients the whole mesh. Two poles
// in a row make nothing (a stretch along the axis has no area).
TriangleMesh mesh_from_rings(const std::vector<std::vector<Eigen::Vector3d>>& rings) {
  TriangleMesh mesh;
  std::vector<int> first(rings.size());
  for (size_t k = 0; k < rings.size(); ++k) {
    first[k] = static_cast<int>(mesh.vertices.size());
    mesh.vertices.insert(mesh.vertices.end(), rings[k].begin(), rings[k].end());
  }
  for (size_t k = 0; k + 1 < rings.size(); ++k) {
    const int na = static_cast<int>(rings[k].size());
    const int nb = static_cast<int>(rings[k + 1].size());
    const int a = first[k], b = first[k + 1];
    if (na == 1 && nb == 1) continue;
    if (na == 1) {
      for (int j = 0; j < nb; ++j) mesh.triangles.push_back({a, b + (j + 1) % nb, b + j});
    } else if (nb == 1) {
      for (int j = 0; j < na; ++j) mesh.triangles.push_back({a + j, a + (j + 1) % na, b});
    } else {
      for (int j = 0; j < na; ++j) {
        const int j1 = (j + 1) % na;
        mesh.triangles.push_back({a + j, a + j1, b + j1});
        mesh.triangles.push_back({a + j, b + j1, b + j});
      }
    }
  }
  return mesh;
}

void flip(TriangleMesh* mesh) {
  for (auto& tri : mesh->triangles) std::swap(tri[1], tri[2]);
}

// Makes the winding outward: a closed mesh wound inward has a negative volume.
void orient_outward(TriangleMesh* mesh) {
  if (signed_volume(*mesh) < 0.0) flip(mesh);
}

double cross2(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

double polygon_area(const std::vector<Eigen::Vector2d>& poly) {
  double a = 0.0;
  for (size_t i = 0; i < poly.size(); ++i) a += cross2(poly[i], poly[(i + 1) % poly.size()]);
  return 0.5 * a;
}

bool in_triangle(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                 const Eigen::Vector2d& c) {
  return cross2(b - a, p - a) >= 0.0 && cross2(c - b, p - b) >= 0.0 && cross2(a - c, p - c) >= 0.0;
}

// Ear clipping of a counter-clockwise simple polygon; O(n^2), fine for hand-written outlines.
std::vector<std::array<int, 3>> triangulate(const std::vector<Eigen::Vector2d>& poly) {
  std::vector<std::array<int, 3>> tris;
  std::vector<int> idx(poly.size());
  for (size_t i = 0; i < idx.size(); ++i) idx[i] = static_cast<int>(i);
  while (idx.size() > 3) {
    const size_t m = idx.size();
    bool clipped = false;
    for (size_t i = 0; i < m && !clipped; ++i) {
      const int a = idx[(i + m - 1) % m], b = idx[i], c = idx[(i + 1) % m];
      if (cross2(poly[b] - poly[a], poly[c] - poly[b]) <= 0.0) continue;  // reflex or flat
      bool empty = true;
      for (size_t j = 0; j < m && empty; ++j) {
        const int p = idx[j];
        if (p == a || p == b || p == c) continue;
        if (in_triangle(poly[p], poly[a], poly[b], poly[c])) empty = false;
      }
      if (!empty) continue;
      tris.push_back({a, b, c});
      idx.erase(idx.begin() + static_cast<long>(i));
      clipped = true;
    }
    if (!clipped) break;  // not simple: leave the rest as a fan below
  }
  for (size_t i = 1; i + 1 < idx.size(); ++i) tris.push_back({idx[0], idx[i], idx[i + 1]});
  return tris;
}

double spow(double x, double e) { return std::copysign(std::pow(std::abs(x), e), x); }

}  // namespace

TriangleMesh make_quad_mesh(const Eigen::Vector2d& size) {
  const double hx = 0.5 * size.x(), hy = 0.5 * size.y();
  TriangleMesh mesh;
  mesh.vertices = {{-hx, -hy, 0.0}, {hx, -hy, 0.0}, {hx, hy, 0.0}, {-hx, hy, 0.0}};
  mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
  return mesh;
}

TriangleMesh make_box_mesh(const Eigen::Vector3d& size) {
  const Eigen::Vector3d h = 0.5 * size;
  TriangleMesh mesh;
  // Corner k: the sign of axis i is bit i of k (clear: minus), as box_corners() in geometry/.
  for (int k = 0; k < 8; ++k) {
    mesh.vertices.emplace_back((k & 1) ? h.x() : -h.x(), (k & 2) ? h.y() : -h.y(),
                               (k & 4) ? h.z() : -h.z());
  }
  // Each face as a cycle of its four corners; the winding is chosen from the face's outward axis.
  const int faces[6][4] = {{0, 2, 6, 4}, {1, 3, 7, 5},   // -x, +x
                           {0, 1, 5, 4}, {2, 3, 7, 6},   // -y, +y
                           {0, 1, 3, 2}, {4, 5, 7, 6}};  // -z, +z
  for (int f = 0; f < 6; ++f) {
    Eigen::Vector3d outward = Eigen::Vector3d::Zero();
    outward[f / 2] = (f % 2) ? 1.0 : -1.0;
    const auto& c = faces[f];
    const Eigen::Vector3d n = (mesh.vertices[c[1]] - mesh.vertices[c[0]])
                                  .cross(mesh.vertices[c[2]] - mesh.vertices[c[0]]);
    if (n.dot(outward) > 0.0) {
      mesh.triangles.push_back({c[0], c[1], c[2]});
      mesh.triangles.push_back({c[0], c[2], c[3]});
    } else {
      mesh.triangles.push_back({c[0], c[2], c[1]});
      mesh.triangles.push_back({c[0], c[3], c[2]});
    }
  }
  return mesh;
}

TriangleMesh make_ellipsoid_mesh(const Eigen::Vector3d& radii, int segments) {
  segments = std::max(4, segments);
  const int n_lat = std::max(2, segments / 2);
  std::vector<std::vector<Eigen::Vector3d>> rings;
  rings.push_back({Eigen::Vector3d(0.0, 0.0, -radii.z())});
  for (int i = 1; i < n_lat; ++i) {
    const double theta = -0.5 * kPi + kPi * i / n_lat;
    std::vector<Eigen::Vector3d> ring;
    for (int j = 0; j < segments; ++j) {
      const double phi = 2.0 * kPi * j / segments;
      ring.emplace_back(radii.x() * std::cos(theta) * std::cos(phi),
                        radii.y() * std::cos(theta) * std::sin(phi), radii.z() * std::sin(theta));
    }
    rings.push_back(std::move(ring));
  }
  rings.push_back({Eigen::Vector3d(0.0, 0.0, radii.z())});
  TriangleMesh mesh = mesh_from_rings(rings);
  orient_outward(&mesh);
  return mesh;
}

TriangleMesh make_cylinder_mesh(double radius, double height, int segments) {
  const double h = 0.5 * height;
  return make_lathe_mesh({{0.0, -h}, {radius, -h}, {radius, h}, {0.0, h}}, segments);
}

TriangleMesh make_lathe_mesh(const std::vector<Eigen::Vector2d>& profile, int segments) {
  segments = std::max(3, segments);
  std::vector<std::vector<Eigen::Vector3d>> rings;
  for (const Eigen::Vector2d& rz : profile) {
    if (rz.x() <= 0.0) {
      rings.push_back({Eigen::Vector3d(0.0, 0.0, rz.y())});
      continue;
    }
    std::vector<Eigen::Vector3d> ring;
    for (int j = 0; j < segments; ++j) {
      const double phi = 2.0 * kPi * j / segments;
      ring.emplace_back(rz.x() * std::cos(phi), rz.x() * std::sin(phi), rz.y());
    }
    rings.push_back(std::move(ring));
  }
  TriangleMesh mesh = mesh_from_rings(rings);
  orient_outward(&mesh);
  return mesh;
}

std::vector<Eigen::Vector2d> smooth_profile(const std::vector<Eigen::Vector2d>& points,
                                            int subdivisions) {
  if (subdivisions <= 0 || points.size() < 3) return points;
  // A turn sharper than this is a corner (a bottle's base edge): the curve is split there so that
  // it does not overshoot below the base or outside the wall.
  const double kCornerCos = std::cos(50.0 * kPi / 180.0);
  const size_t n = points.size();
  auto is_corner = [&](size_t i) {
    if (i == 0 || i + 1 == n) return true;
    const Eigen::Vector2d a = (points[i] - points[i - 1]).normalized();
    const Eigen::Vector2d b = (points[i + 1] - points[i]).normalized();
    return a.dot(b) < kCornerCos;
  };
  std::vector<Eigen::Vector2d> out;
  for (size_t i = 0; i + 1 < n; ++i) {
    out.push_back(points[i]);
    // Neighbours across a corner are replaced by reflections, which makes the tangent at the
    // corner follow the segment itself.
    const Eigen::Vector2d p0 = is_corner(i) ? 2.0 * points[i] - points[i + 1] : points[i - 1];
    const Eigen::Vector2d p3 = is_corner(i + 1) ? 2.0 * points[i + 1] - points[i] : points[i + 2];
    for (int s = 1; s <= subdivisions; ++s) {
      Eigen::Vector2d p = detail::catmull_rom(p0, points[i], points[i + 1], p3,
                                              static_cast<double>(s) / (subdivisions + 1));
      p.x() = std::max(0.0, p.x());
      out.push_back(p);
    }
  }
  out.push_back(points.back());
  return out;
}

TriangleMesh make_extrusion_mesh(const std::vector<Eigen::Vector2d>& polygon, double depth) {
  TriangleMesh mesh;
  if (polygon.size() < 3) return mesh;
  std::vector<Eigen::Vector2d> poly = polygon;
  if (polygon_area(poly) < 0.0) std::reverse(poly.begin(), poly.end());
  if (std::abs(polygon_area(poly)) <= 0.0) return mesh;
  const int n = static_cast<int>(poly.size());
  const double h = 0.5 * depth;
  for (const auto& p : poly) mesh.vertices.emplace_back(p.x(), p.y(), -h);
  for (const auto& p : poly) mesh.vertices.emplace_back(p.x(), p.y(), h);
  for (const auto& t : triangulate(poly)) {
    mesh.triangles.push_back({t[0], t[2], t[1]});              // bottom, seen from -z
    mesh.triangles.push_back({t[0] + n, t[1] + n, t[2] + n});  // top
  }
  for (int i = 0; i < n; ++i) {
    const int j = (i + 1) % n;
    mesh.triangles.push_back({i, j, j + n});
    mesh.triangles.push_back({i, j + n, i + n});
  }
  orient_outward(&mesh);
  return mesh;
}

TriangleMesh make_superquadric_mesh(const Eigen::Vector3d& radii, double e1, double e2,
                                    int segments) {
  segments = std::max(4, segments);
  const int n_lat = std::max(2, segments / 2);
  std::vector<std::vector<Eigen::Vector3d>> rings;
  rings.push_back({Eigen::Vector3d(0.0, 0.0, -radii.z())});
  for (int i = 1; i < n_lat; ++i) {
    const double eta = -0.5 * kPi + kPi * i / n_lat;
    const double ce = spow(std::cos(eta), e1), se = spow(std::sin(eta), e1);
    std::vector<Eigen::Vector3d> ring;
    for (int j = 0; j < segments; ++j) {
      const double omega = -kPi + 2.0 * kPi * j / segments;
      ring.emplace_back(radii.x() * ce * spow(std::cos(omega), e2),
                        radii.y() * ce * spow(std::sin(omega), e2), radii.z() * se);
    }
    rings.push_back(std::move(ring));
  }
  rings.push_back({Eigen::Vector3d(0.0, 0.0, radii.z())});
  TriangleMesh mesh = mesh_from_rings(rings);
  orient_outward(&mesh);
  return mesh;
}

void append_mesh(const TriangleMesh& part, const SE3& T, double scale, TriangleMesh* out) {
  const int offset = static_cast<int>(out->vertices.size());
  const Eigen::Matrix3d R = T.rotation();
  const Eigen::Vector3d& t = T.translation();
  for (const auto& v : part.vertices) out->vertices.push_back(R * (scale * v) + t);
  for (const auto& tri : part.triangles) {
    out->triangles.push_back({tri[0] + offset, tri[1] + offset, tri[2] + offset});
  }
  if (!part.colours.empty() && out->colours.size() + part.colours.size() == out->vertices.size()) {
    out->colours.insert(out->colours.end(), part.colours.begin(), part.colours.end());
  }
}

double signed_volume(const TriangleMesh& mesh) {
  double v = 0.0;
  for (const auto& t : mesh.triangles) {
    v += mesh.vertices[t[0]].dot(mesh.vertices[t[1]].cross(mesh.vertices[t[2]]));
  }
  return v / 6.0;
}

}  // namespace dqo::sim
