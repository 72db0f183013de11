#include "dqo_map/mesh/support_closure.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

namespace dqo::mesh {
namespace {

// Points of the object's surface from its renders, every `step`-th pixel.
std::vector<Eigen::Vector3d> object_points(const std::vector<FusionView>& views, int step) {
  std::vector<Eigen::Vector3d> out;
  for (const FusionView& v : views) {
    const PinholeCamera& c = v.camera;
    for (int y = 0; y < c.height; y += step) {
      for (int x = 0; x < c.width; x += step) {
        const float d = v.depth[static_cast<size_t>(y) * c.width + x];
        if (std::isfinite(d) && d > 0.f) out.push_back(v.T_wc * c.back_project(x, y, d));
      }
    }
  }
  return out;
}

struct Plane {
  Eigen::Vector3d n = Eigen::Vector3d::UnitZ();
  double offset = 0.0;
  int inliers = 0;
  double distance(const Eigen::Vector3d& p) const { return n.dot(p) - offset; }
};

// RANSAC over point triples, then a least-squares refit to the inliers of the best.
Plane fit_plane(const std::vector<Eigen::Vector3d>& pts, const SupportClosureParams& params) {
  Plane best;
  if (pts.size() < 3) return best;
  std::mt19937_64 rng(params.seed);
  std::uniform_int_distribution<size_t> pick(0, pts.size() - 1);
  for (int it = 0; it < params.iterations; ++it) {
    const Eigen::Vector3d &a = pts[pick(rng)], &b = pts[pick(rng)], &c = pts[pick(rng)];
    Eigen::Vector3d n = (b - a).cross(c - a);
    if (n.norm() < 1e-9) continue;
    n.normalize();
    Plane p{n, n.dot(a), 0};
    for (const Eigen::Vector3d& q : pts) p.inliers += std::abs(p.distance(q)) <= params.plane_inlier;
    if (p.inliers > best.inliers) best = p;
  }
  if (best.inliers < 3) return best;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> in;
  for (const Eigen::Vector3d& q : pts) {
    if (std::abs(best.distance(q)) <= params.plane_inlier) in.push_back(q);
  }
  for (const Eigen::Vector3d& q : in) mean += q;
  mean /= static_cast<double>(in.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& q : in) cov += (q - mean) * (q - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  Eigen::Vector3d n = eig.eigenvectors().col(0);
  if (n.dot(best.n) < 0) n = -n;
  return Plane{n, n.dot(mean), static_cast<int>(in.size())};
}

// The convex hull of 2D points (Andrew's monotone chain), counter-clockwise.
std::vector<Eigen::Vector2d> convex_hull(std::vector<Eigen::Vector2d> p) {
  std::sort(p.begin(), p.end(), [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  if (p.size() < 3) return p;
  auto cross = [](const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
  };
  std::vector<Eigen::Vector2d> hull(2 * p.size());
  size_t k = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], p[i]) <= 0) --k;
    hull[k++] = p[i];
  }
  for (size_t i = p.size() - 1, t = k + 1; i > 0; --i) {
    while (k >= t && cross(hull[k - 2], hull[k - 1], p[i - 1]) <= 0) --k;
    hull[k++] = p[i - 1];
  }
  hull.resize(k - 1);
  return hull;
}

// Inside or on a counter-clockwise convex polygon.
bool inside_convex(const std::vector<Eigen::Vector2d>& hull, const Eigen::Vector2d& q) {
  for (size_t i = 0; i < hull.size(); ++i) {
    const Eigen::Vector2d& a = hull[i];
    const Eigen::Vector2d& b = hull[(i + 1) % hull.size()];
    if ((b.x() - a.x()) * (q.y() - a.y()) - (b.y() - a.y()) * (q.x() - a.x()) < -1e-12) return false;
  }
  return true;
}

}  // namespace

std::optional<FusionView> support_closure_view(const std::vector<FusionView>& object_views,
                                               const std::vector<Eigen::Vector3d>& background,
                                               const OrientedBox& object_box, double voxel_size,
                                               const SupportClosureParams& params,
                                               SupportClosureInfo* info) {
  SupportClosureInfo local;
  SupportClosureInfo& r = info ? *info : local;
  r = SupportClosureInfo();
  auto give_up = [&r](const char* why) {
    r.reason = why;
    return std::nullopt;
  };
  if (!params.enabled) return give_up("disabled");
  if (!(voxel_size > 0.0)) return give_up("no voxel size");
  const Plane plane = fit_plane(background, params);
  r.plane_inliers = plane.inliers;
  if (plane.inliers < params.min_inliers) return give_up("no plane in the background around it");

  const std::vector<Eigen::Vector3d> surface = object_points(object_views, 2);
  if (surface.empty()) return give_up("no object surface");
  // The plane's normal points to the object: most of the object lies on the positive side.
  double mean_side = 0.0;
  for (const Eigen::Vector3d& p : surface) mean_side += plane.distance(p);
  const double sign = mean_side >= 0.0 ? 1.0 : -1.0;
  const Eigen::Vector3d n = sign * plane.n;
  const double offset = sign * plane.offset;
  r.normal = n;
  r.offset = offset;
  std::vector<Eigen::Vector3d> contact;
  size_t penetrating = 0;
  for (const Eigen::Vector3d& p : surface) {
    const double d = n.dot(p) - offset;
    if (d < -params.max_penetration) ++penetrating;
    if (std::abs(d) <= params.contact_distance) contact.push_back(p);
  }
  r.contact_points = static_cast<int>(contact.size());
  r.penetrating_fraction = static_cast<double>(penetrating) / surface.size();
  if (penetrating > params.max_penetrating_fraction * surface.size()) {
    return give_up("the plane cuts through the object");
  }
  if (static_cast<int>(contact.size()) < params.min_contact_points) {
    return give_up("the object does not reach the plane");
  }

  // Plane basis and the footprint grid (cells of the voxel size).
  const Eigen::Vector3d e1 = n.unitOrthogonal();
  const Eigen::Vector3d e2 = n.cross(e1);
  const Eigen::Vector3d origin = object_box.centre - (n.dot(object_box.centre) - offset) * n;
  double a0 = 1e300, a1 = -1e300, b0 = 1e300, b1 = -1e300;
  for (const Eigen::Vector3d& p : contact) {
    const double a = e1.dot(p - origin), b = e2.dot(p - origin);
    a0 = std::min(a0, a);
    a1 = std::max(a1, a);
    b0 = std::min(b0, b);
    b1 = std::max(b1, b);
  }
  // The footprint is the convex hull of the contact points: a side no view saw leaves a gap in
  // the contact ring (a book's far edge), which the hull bridges; a cup's ring becomes its disc.
  std::vector<Eigen::Vector2d> planar;
  planar.reserve(contact.size());
  for (const Eigen::Vector3d& p : contact) {
    planar.emplace_back(e1.dot(p - origin) - a0, e2.dot(p - origin) - b0);
  }
  const std::vector<Eigen::Vector2d> hull = convex_hull(planar);
  if (hull.size() < 3) return give_up("the contact points are collinear");
  const int pad = 2;
  const double cell = voxel_size;
  const int w = static_cast<int>(std::ceil((a1 - a0) / cell)) + 1 + 2 * pad;
  const int h = static_cast<int>(std::ceil((b1 - b0) / cell)) + 1 + 2 * pad;
  if (w > 4096 || h > 4096) return give_up("footprint too large");
  std::vector<uint8_t> mask(static_cast<size_t>(w) * h, 0);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const Eigen::Vector2d q((x - pad) * cell, (y - pad) * cell);
      mask[static_cast<size_t>(y) * w + x] = inside_convex(hull, q) ? 1 : 0;
    }
  }
  r.footprint_cells = static_cast<int>(std::count(mask.begin(), mask.end(), 1));
  if (r.footprint_cells == 0) return give_up("empty footprint");
  // The contacts must outline the footprint: a cup's or a book's contact runs along most of the
  // hull's boundary (a side never seen leaves a gap), a table's or a chair's legs touch it at a few
  // corners only, and closing their hull would lay a floor patch under them.
  {
    std::vector<uint8_t> near_contact(mask.size(), 0);
    const int k = params.rim_cells;
    for (const Eigen::Vector2d& q : planar) {
      const int cx = static_cast<int>(std::lround(q.x() / cell)) + pad;
      const int cy = static_cast<int>(std::lround(q.y() / cell)) + pad;
      for (int dy = -k; dy <= k; ++dy) {
        for (int dx = -k; dx <= k; ++dx) {
          const int x = cx + dx, y = cy + dy;
          if (x >= 0 && y >= 0 && x < w && y < h) near_contact[static_cast<size_t>(y) * w + x] = 1;
        }
      }
    }
    int boundary = 0, covered = 0;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const size_t i = static_cast<size_t>(y) * w + x;
        if (!mask[i]) continue;
        const bool edge = x == 0 || y == 0 || x + 1 == w || y + 1 == h || !mask[i - 1] ||
                          !mask[i + 1] || !mask[i - w] || !mask[i + w];
        if (!edge) continue;
        ++boundary;
        covered += near_contact[i];
      }
    }
    r.rim_coverage = boundary > 0 ? static_cast<double>(covered) / boundary : 0.0;
    if (r.rim_coverage < params.min_rim_coverage) {
      return give_up("the contacts do not outline a footprint (legs?)");
    }
  }

  // The virtual camera: under the plane, optical axis along the normal, one pixel per cell at the
  // plane (fx = distance / cell), so every footprint pixel sees the plane at depth `distance`.
  Eigen::Vector3f colour = Eigen::Vector3f::Zero();
  {
    // The object's colour near the contact: the mean of its render there.
    double count = 0;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (const FusionView& v : object_views) {
      const PinholeCamera& c = v.camera;
      for (int y = 0; y < c.height; y += 2) {
        for (int x = 0; x < c.width; x += 2) {
          const size_t i = static_cast<size_t>(y) * c.width + x;
          const float d = v.depth[i];
          if (!(std::isfinite(d) && d > 0.f)) continue;
          const Eigen::Vector3d p = v.T_wc * c.back_project(x, y, d);
          if (std::abs(n.dot(p) - offset) > params.contact_distance) continue;
          sum += Eigen::Vector3d(v.rgb[3 * i], v.rgb[3 * i + 1], v.rgb[3 * i + 2]);
          count += 1;
        }
      }
    }
    if (count > 0) colour = (sum / count).cast<float>();
  }
  const double D = params.camera_distance;
  FusionView view;
  view.camera.width = w;
  view.camera.height = h;
  view.camera.fx = view.camera.fy = D / cell;
  view.camera.cx = -(a0 / cell) + pad;
  view.camera.cy = -(b0 / cell) + pad;
  Eigen::Matrix3d R_wc;
  R_wc.col(0) = e1;
  R_wc.col(1) = e2;
  R_wc.col(2) = n;
  view.T_wc = SE3::from_rotation_translation(R_wc, origin - D * n);
  view.depth.assign(static_cast<size_t>(w) * h, 0.f);
  view.rgb.assign(3 * static_cast<size_t>(w) * h, 0.f);
  for (size_t i = 0; i < mask.size(); ++i) {
    if (!mask[i]) continue;
    view.depth[i] = static_cast<float>(D);
    for (int c = 0; c < 3; ++c) view.rgb[3 * i + c] = colour[c];
  }
  r.closed = true;
  return view;
}

}  // namespace dqo::mesh
