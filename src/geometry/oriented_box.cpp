#include "dqo_map/geometry/oriented_box.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "dqo_map/geometry/dual_quadric.h"

namespace dqo {

namespace {

constexpr double kContainsTol = 1e-12;

// Half-space {x : n·x <= d}.
struct Plane {
  Eigen::Vector3d n;
  double d;
};

// A closed polyhedral surface: faces are cycles of vertex ids, counter-clockwise seen from outside,
// stored back to back (face f is indices[face_begin[f]] .. indices[face_begin[f + 1] - 1]).
// Vertices are shared by id rather than repeated per face: that is what keeps the surface
// watertight through clipping, see clip().
struct Polyhedron {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<int> indices;
  std::vector<int> face_begin{0};

  int face_count() const { return static_cast<int>(face_begin.size()) - 1; }
  void clear() {
    vertices.clear();
    indices.clear();
    face_begin.assign(1, 0);
  }
  void close_face() { face_begin.push_back(static_cast<int>(indices.size())); }
};

// The box's surface in a frame whose origin is `origin`. Corner ids follow box_corners().
Polyhedron box_polyhedron(const OrientedBox& box, const Eigen::Vector3d& origin) {
  Polyhedron poly;
  for (const Eigen::Vector3d& corner : box_corners(box)) poly.vertices.push_back(corner - origin);
  for (int i = 0; i < 3; ++i) {
    const int j = (i + 1) % 3;
    const int k = (i + 2) % 3;
    // (e_j, e_k, e_i) is right-handed, so this (j, k) sign sequence turns counter-clockwise about
    // +e_i; the face on the minus side runs it backwards. Assumes det(rotation) = +1; a reflection
    // flips every face and only the sign of the volume, which intersection_volume drops.
    const int jk[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    for (int side = 0; side < 2; ++side) {
      for (int step = 0; step < 4; ++step) {
        const int* bits = jk[side == 1 ? step : 3 - step];
        poly.indices.push_back((side << i) | (bits[0] << j) | (bits[1] << k));
      }
      poly.close_face();
    }
  }
  return poly;
}

// The 6 face planes of `box`, in the same shifted frame.
std::array<Plane, 6> face_planes(const OrientedBox& box, const Eigen::Vector3d& origin) {
  const Eigen::Vector3d c = box.centre - origin;
  std::array<Plane, 6> planes;
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d axis = box.rotation.col(i);
    const double along = axis.dot(c);
    planes[2 * i] = {axis, along + box.half_extents[i]};
    planes[2 * i + 1] = {-axis, -along + box.half_extents[i]};
  }
  return planes;
}

// Keeps the part of `in` with n·x <= d, closing the cut with cap faces on the plane. Returns false
// when nothing is left.
//
// Why topology and not per-face polygon clipping: where the plane nearly contains a face (identical
// boxes, a box flush inside another, two faces a hair apart in angle), which side a vertex falls on
// is decided by rounding, and the edge-plane intersections move by up to eps / angle. Each vertex is
// classified once and each cut edge gets one new vertex shared by both its faces and the cap, so
// the surface stays closed whatever rounding decides, and a closed surface's divergence volume only
// changes by the thin slivers such moves sweep. Clipping faces independently instead leaves gaps
// and overlaps between them that cost up to ~1e-5 of the volume.
bool clip(const Polyhedron& in, const Plane& plane, Polyhedron& out) {
  const int n_in = static_cast<int>(in.vertices.size());
  std::vector<char> inside(n_in);
  std::vector<double> dist(n_in);
  bool any_in = false;
  bool any_out = false;
  for (int v = 0; v < n_in; ++v) {
    dist[v] = plane.n.dot(in.vertices[v]) - plane.d;
    inside[v] = dist[v] <= 0.0;
    any_in = any_in || inside[v];
    any_out = any_out || !inside[v];
  }
  out.clear();
  // Vertices cut off earlier stay in the list unused; they can only make these tests miss an early
  // exit, and the face loop below then drops or keeps faces exactly as it should.
  if (!any_in) return false;
  if (!any_out) {
    out = in;
    return true;
  }

  out.vertices = in.vertices;
  // One new vertex per cut edge, keyed by its (lower, higher) end ids.
  std::vector<std::pair<std::pair<int, int>, int>> cut_edges;
  auto cut_vertex = [&](int a, int b) {
    const std::pair<int, int> key(std::min(a, b), std::max(a, b));
    for (const auto& entry : cut_edges) {
      if (entry.first == key) return entry.second;
    }
    // dist has opposite signs at the two ends, so the denominator is never zero.
    const int lo = key.first;
    const int hi = key.second;
    const double t = dist[lo] / (dist[lo] - dist[hi]);
    out.vertices.push_back(in.vertices[lo] + t * (in.vertices[hi] - in.vertices[lo]));
    const int id = static_cast<int>(out.vertices.size()) - 1;
    cut_edges.push_back({key, id});
    return id;
  };

  // A face crossing the plane gains an edge exit → entry along the cut; the cap, its neighbour
  // across that edge, runs it entry → exit. cap_next[entry] = exit chains the cap's cycles.
  std::vector<std::pair<int, int>> cap_edges;  // (entry, exit)
  std::vector<std::pair<int, bool>> crossings;   // (new vertex, is exit) in face order
  for (int f = 0; f < in.face_count(); ++f) {
    const int begin = in.face_begin[f];
    const int size = in.face_begin[f + 1] - begin;
    crossings.clear();
    const int start = static_cast<int>(out.indices.size());
    for (int k = 0; k < size; ++k) {
      const int a = in.indices[begin + k];
      const int b = in.indices[begin + (k + 1) % size];
      if (inside[a]) out.indices.push_back(a);
      if (inside[a] != inside[b]) {
        const int x = cut_vertex(a, b);
        out.indices.push_back(x);
        crossings.push_back({x, inside[a] != 0});
      }
    }
    if (static_cast<int>(out.indices.size()) - start < 3) {
      out.indices.resize(start);  // wholly outside (or a degenerate sliver of no area)
      continue;
    }
    out.close_face();
    // Crossings alternate exit, entry around the face; pair each exit with the entry after it.
    const int m = static_cast<int>(crossings.size());
    for (int c = 0; c < m; ++c) {
      if (crossings[c].second) cap_edges.push_back({crossings[(c + 1) % m].first, crossings[c].first});
    }
  }

  std::vector<int> cap_next(out.vertices.size(), -1);
  for (const auto& [entry, exit] : cap_edges) cap_next[entry] = exit;
  for (const auto& [entry, exit_unused] : cap_edges) {
    (void)exit_unused;
    if (cap_next[entry] < 0) continue;  // already part of an emitted cap
    const int start = static_cast<int>(out.indices.size());
    int v = entry;
    // Bounded walk: a broken chain (impossible for a closed input) must not loop forever.
    for (std::size_t guard = 0; v >= 0 && guard <= cap_next.size(); ++guard) {
      const int next = cap_next[v];
      if (next < 0) break;
      out.indices.push_back(v);
      cap_next[v] = -1;
      v = next;
    }
    if (static_cast<int>(out.indices.size()) - start < 3) {
      out.indices.resize(start);
    } else {
      out.close_face();
    }
  }
  return true;
}

// Divergence theorem with the origin as apex: Σ over faces, fanned into triangles, of the signed
// tetrahedra (origin, p0, pk, pk+1). Exact for any closed surface, planar faces or not.
double signed_volume(const Polyhedron& poly) {
  double six_volume = 0.0;
  for (int f = 0; f < poly.face_count(); ++f) {
    const int begin = poly.face_begin[f];
    const int end = poly.face_begin[f + 1];
    const Eigen::Vector3d& p0 = poly.vertices[poly.indices[begin]];
    for (int k = begin + 1; k + 1 < end; ++k) {
      six_volume += p0.dot(poly.vertices[poly.indices[k]].cross(poly.vertices[poly.indices[k + 1]]));
    }
  }
  return six_volume / 6.0;
}

}  // namespace

double box_volume(const OrientedBox& box) {
  const Eigen::Vector3d h = box.half_extents.cwiseMax(0.0);
  return 8.0 * h.prod();
}

std::array<Eigen::Vector3d, 8> box_corners(const OrientedBox& box) {
  std::array<Eigen::Vector3d, 8> corners;
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector3d local((k & 1) ? box.half_extents.x() : -box.half_extents.x(),
                                (k & 2) ? box.half_extents.y() : -box.half_extents.y(),
                                (k & 4) ? box.half_extents.z() : -box.half_extents.z());
    corners[k] = box.centre + box.rotation * local;
  }
  return corners;
}

bool contains(const OrientedBox& box, const Eigen::Vector3d& p_w) {
  const Eigen::Vector3d p_b = box.rotation.transpose() * (p_w - box.centre);
  const double tol = kContainsTol * std::max(box.half_extents.maxCoeff(), box.centre.norm());
  return (p_b.cwiseAbs() - box.half_extents).maxCoeff() <= tol;
}

// a ∩ b is a's surface clipped by b's six face planes in turn (see clip() for why the clipping
// keeps the surface topology). Identical boxes, shared faces and touching boxes need no special
// case: they differ from the exact answer by rounding-sized slivers only.
double intersection_volume(const OrientedBox& a, const OrientedBox& b) {
  if (a.half_extents.minCoeff() <= 0.0 || b.half_extents.minCoeff() <= 0.0) return 0.0;

  // Quick rejection on bounding spheres.
  const double ra = a.half_extents.norm();
  const double rb = b.half_extents.norm();
  if ((a.centre - b.centre).norm() > ra + rb) return 0.0;

  // Origin at a's centre: every vertex then lies within ra of it, so rounding in the plane offsets
  // and in the divergence sum scales with the boxes, not with their distance from the map origin.
  const Eigen::Vector3d origin = a.centre;
  Polyhedron current = box_polyhedron(a, origin);
  Polyhedron next;
  for (const Plane& plane : face_planes(b, origin)) {
    if (!clip(current, plane, next)) return 0.0;
    std::swap(current, next);
  }
  // abs: a reflected rotation turns the surface inside out, not the box. The clamp removes rounding
  // past the physical bounds (a vanishing overlap slightly negative, a full one slightly too big).
  const double volume = std::abs(signed_volume(current));
  return std::clamp(volume, 0.0, std::min(box_volume(a), box_volume(b)));
}

double iou_3d(const OrientedBox& a, const OrientedBox& b) {
  const double inter = intersection_volume(a, b);
  const double uni = box_volume(a) + box_volume(b) - inter;
  if (uni <= 0.0) return 0.0;
  return std::clamp(inter / uni, 0.0, 1.0);
}

double monte_carlo_iou_3d(const OrientedBox& a, const OrientedBox& b, int samples,
                          std::mt19937_64& rng) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (const OrientedBox* box : {&a, &b}) {
    for (const Eigen::Vector3d& c : box_corners(*box)) {
      lo = lo.cwiseMin(c);
      hi = hi.cwiseMax(c);
    }
  }
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  long in_both = 0;
  long in_either = 0;
  for (int s = 0; s < samples; ++s) {
    const Eigen::Vector3d p(lo.x() + unit(rng) * (hi.x() - lo.x()),
                            lo.y() + unit(rng) * (hi.y() - lo.y()),
                            lo.z() + unit(rng) * (hi.z() - lo.z()));
    const bool in_a = contains(a, p);
    const bool in_b = contains(b, p);
    in_both += (in_a && in_b) ? 1 : 0;
    in_either += (in_a || in_b) ? 1 : 0;
  }
  return in_either == 0 ? 0.0 : static_cast<double>(in_both) / static_cast<double>(in_either);
}

double centre_distance(const OrientedBox& a, const OrientedBox& b) {
  return (a.centre - b.centre).norm();
}

OrientedBox box_from_quadric(const DualQuadric& q) {
  OrientedBox box;
  box.centre = q.centre();
  box.rotation = q.rotation();
  box.half_extents = q.semi_axes();
  return box;
}

void canonical_axes(Eigen::Matrix3d* R, Eigen::Vector3d* extents) {
  const Eigen::Matrix3d in = *R;
  const Eigen::Vector3d e = *extents;
  int z = 0;
  for (int k = 1; k < 3; ++k) {
    if (std::abs(in(2, k)) > std::abs(in(2, z))) z = k;
  }
  const int a = (z + 1) % 3, b = (z + 2) % 3;
  // The longer of the other two; where they are equal (to rounding), the one nearer the map's x.
  const double tie = 1e-9 * std::max(e(a), e(b));
  int x = e(a) > e(b) ? a : b;
  if (std::abs(e(a) - e(b)) <= tie) x = std::abs(in(0, a)) >= std::abs(in(0, b)) ? a : b;
  const int y = x == a ? b : a;
  Eigen::Vector3d vz = in.col(z), vx = in.col(x);
  if (vz.z() < 0.0) vz = -vz;
  if (vx.x() < -1e-12 || (std::abs(vx.x()) <= 1e-12 && vx.y() < 0.0)) vx = -vx;
  R->col(0) = vx;
  R->col(1) = vz.cross(vx);
  R->col(2) = vz;
  *extents = Eigen::Vector3d(e(x), e(y), e(z));
}

}  // namespace dqo
