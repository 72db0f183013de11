#include "object_surface.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <random>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

namespace dqo::objects {
namespace {

// The q-quantile of v (v reordered).
double quantile(std::vector<double>& v, double q) {
  if (v.empty()) return 0.0;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(std::floor(q * static_cast<double>(v.size() - 1) + 0.5)));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
  return v[k];
}

// Half extents of the ellipsoid's axis-aligned bounding box.
Eigen::Vector3d aligned_half_extents(const DualQuadric& q) {
  const Eigen::Matrix3d& R = q.rotation();
  const Eigen::Vector3d a2 = q.semi_axes().array().square();
  Eigen::Vector3d e;
  for (int i = 0; i < 3; ++i) e(i) = std::sqrt(R.row(i).array().square().matrix().dot(a2));
  return e;
}

// Inside the ellipsoid scaled by `scale`.
bool inside(const DualQuadric& q, const Eigen::Vector3d& p, double scale) {
  const Eigen::Vector3d x = q.rotation().transpose() * (p - q.centre());
  return (x.array() / (scale * q.semi_axes().array())).square().sum() <= 1.0;
}

struct Extent {
  double lo = 0.0, hi = 0.0;
};

// Trimmed extents of the points along the box frame's x and y (rotated by yaw about z, relative
// to `origin`) and z.
std::array<Extent, 3> trimmed_extents(const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& origin,
                                      double yaw, double trim) {
  const double c = std::cos(yaw), s = std::sin(yaw);
  std::array<std::vector<double>, 3> coords;
  for (auto& v : coords) v.reserve(points.size());
  for (const Eigen::Vector3d& p : points) {
    const Eigen::Vector3d d = p - origin;
    coords[0].push_back(c * d.x() + s * d.y());
    coords[1].push_back(-s * d.x() + c * d.y());
    coords[2].push_back(d.z());
  }
  std::array<Extent, 3> out;
  for (int i = 0; i < 3; ++i) {
    out[i].lo = quantile(coords[i], trim);
    out[i].hi = quantile(coords[i], 1.0 - trim);
  }
  return out;
}

double yaw_of(const Eigen::Matrix3d& R) { return std::atan2(R(1, 0), R(0, 0)); }

// Depth noise, one-sided tolerance at depth z (a Kinect's σ ≈ 1.5 mm · z², about 3σ): planes
// and offsets from them are judged against it (a floor 3 m away is no plane within 1.5 cm).
double depth_noise(double z) { return 0.005 * z * z; }

// The least-squares plane of `points` (at least 3): its mean, unit normal and rms distance.
struct PlaneFit {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Vector3d n = Eigen::Vector3d::UnitZ();
  double rms = 0.0;
};
PlaneFit fit_plane(const std::vector<Eigen::Vector3d>& points) {
  PlaneFit fit;
  for (const Eigen::Vector3d& p : points) fit.mean += p;
  fit.mean /= static_cast<double>(points.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& p : points) cov += (p - fit.mean) * (p - fit.mean).transpose();
  cov /= static_cast<double>(points.size());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  fit.n = eig.eigenvectors().col(0);
  fit.rms = std::sqrt(std::max(0.0, eig.eigenvalues()(0)));
  return fit;
}

}  // namespace

std::vector<Eigen::Vector3f> sample_box_points(const Box2d& box, const PinholeCamera& camera,
                                               const DepthView& depth, const SurfaceParams& params) {
  std::vector<Eigen::Vector3f> out;
  if (depth.data == nullptr || !box.valid() || params.samples_per_box <= 0) return out;
  const double x0 = std::max(0.0, box.x_min), y0 = std::max(0.0, box.y_min);
  const double x1 = std::min<double>(depth.width, box.x_max), y1 = std::min<double>(depth.height, box.y_max);
  if (!(x1 > x0) || !(y1 > y0)) return out;
  const double step = std::max(1.0, std::sqrt((x1 - x0) * (y1 - y0) / params.samples_per_box));
  for (double v = y0 + 0.5 * step; v < y1; v += step) {
    for (double u = x0 + 0.5 * step; u < x1; u += step) {
      const int iu = static_cast<int>(u), iv = static_cast<int>(v);
      if (iu < 0 || iv < 0 || iu >= depth.width || iv >= depth.height) continue;
      const float z = depth.at(iu, iv);
      if (!std::isfinite(z) || z < params.min_depth || z > params.max_depth) continue;
      out.push_back(camera.back_project(iu, iv, z).cast<float>());
    }
  }
  return out;
}

std::vector<Eigen::Vector3d> ring_points(const Box2d& box, const PinholeCamera& camera, const DepthView& depth,
                                         const SurfaceParams& params) {
  std::vector<Eigen::Vector3d> ring;
  if (depth.data == nullptr || !box.valid()) return ring;
  const double gx = std::max(8.0, 0.25 * box.width()), gy = std::max(8.0, 0.25 * box.height());
  const double x0 = std::max(0.0, box.x_min - gx), y0 = std::max(0.0, box.y_min - gy);
  const double x1 = std::min<double>(depth.width, box.x_max + gx), y1 = std::min<double>(depth.height, box.y_max + gy);
  const double ring_area = (x1 - x0) * (y1 - y0) - box.area();
  if (!(ring_area > 0.0)) return ring;
  const double step = std::max(1.0, std::sqrt(ring_area / 300.0));
  for (double v = y0 + 0.5 * step; v < y1; v += step) {
    for (double u = x0 + 0.5 * step; u < x1; u += step) {
      if (u >= box.x_min && u < box.x_max && v >= box.y_min && v < box.y_max) continue;
      const int iu = static_cast<int>(u), iv = static_cast<int>(v);
      const float z = depth.at(iu, iv);
      if (!std::isfinite(z) || z < params.min_depth || z > params.max_depth) continue;
      ring.push_back(camera.back_project(iu, iv, z));
    }
  }
  return ring;
}

namespace {

// The largest plane among `points` by a seeded RANSAC over triples, refined by least squares over
// its inliers; nullopt below `min_inliers`.
std::optional<RingPlane> largest_plane(const std::vector<Eigen::Vector3d>& points, size_t min_inliers,
                                       const SurfaceParams& params) {
  if (points.size() < std::max<size_t>(3, min_inliers)) return std::nullopt;
  auto tolerance = [&](const Eigen::Vector3d& p) { return params.plane_tolerance + depth_noise(p.z()); };
  std::mt19937 rng(7);
  std::uniform_int_distribution<size_t> pick(0, points.size() - 1);
  size_t best_count = 0;
  Eigen::Vector3d best_n = Eigen::Vector3d::UnitZ();
  double best_d = 0.0;
  for (int iteration = 0; iteration < 64; ++iteration) {
    const Eigen::Vector3d& a = points[pick(rng)];
    const Eigen::Vector3d& b = points[pick(rng)];
    const Eigen::Vector3d& c = points[pick(rng)];
    Eigen::Vector3d n = (b - a).cross(c - a);
    if (!(n.norm() > 1e-9)) continue;
    n.normalize();
    const double d = n.dot(a);
    size_t count = 0;
    for (const Eigen::Vector3d& p : points) count += std::abs(n.dot(p) - d) <= tolerance(p);
    if (count > best_count) best_count = count, best_n = n, best_d = d;
    if (5 * best_count >= 4 * points.size()) break;  // four fifths: no larger plane is left
  }
  if (best_count < min_inliers) return std::nullopt;
  std::vector<Eigen::Vector3d> inliers;
  for (const Eigen::Vector3d& p : points) {
    if (std::abs(best_n.dot(p) - best_d) <= tolerance(p)) inliers.push_back(p);
  }
  const PlaneFit fit = fit_plane(inliers);
  RingPlane plane;
  plane.n = fit.n;
  plane.d = plane.n.dot(fit.mean);
  if (plane.d < 0.0) plane.n = -plane.n, plane.d = -plane.d;  // facing away from the camera at the origin
  for (const Eigen::Vector3d& p : points) plane.inliers += std::abs(plane.n.dot(p) - plane.d) <= tolerance(p);
  return plane;
}

}  // namespace

RingSurface fit_ring_surface(const std::vector<Eigen::Vector3d>& ring_c, const SurfaceParams& params) {
  RingSurface out;
  out.samples = ring_c.size();
  const size_t min_inliers = std::max<size_t>(30, ring_c.size() / 10);
  std::vector<Eigen::Vector3d> rest = ring_c;
  for (int k = 0; k < 2; ++k) {
    const std::optional<RingPlane> plane = largest_plane(rest, min_inliers, params);
    if (!plane) break;
    out.planes.push_back(*plane);
    // One plane that holds the ring as stand_out_share needs it: a second would change little
    // (a few samples) and cost a second RANSAC per detection.
    if (static_cast<double>(plane->inliers) >= params.ring_explained * static_cast<double>(ring_c.size())) break;
    const double tol = params.plane_tolerance;
    rest.erase(std::remove_if(rest.begin(), rest.end(),
                              [&](const Eigen::Vector3d& p) {
                                return std::abs(plane->n.dot(p) - plane->d) <= tol + depth_noise(p.z());
                              }),
               rest.end());
  }
  return out;
}

double stand_out_share(const std::vector<Eigen::Vector3f>& box_points_c, const RingSurface& ring,
                       const SurfaceParams& params) {
  if (box_points_c.empty() || ring.samples < 30 || ring.planes.empty()) return std::nan("");
  size_t explained = 0;  // the planes' inliers are disjoint (the second is found among the rest)
  for (const RingPlane& plane : ring.planes) explained += plane.inliers;
  if (static_cast<double>(explained) < params.ring_explained * static_cast<double>(ring.samples)) return std::nan("");
  int out = 0;
  for (const Eigen::Vector3f& pf : box_points_c) {
    const Eigen::Vector3d p = pf.cast<double>();
    const double limit = params.stand_out_distance + depth_noise(p.z());
    bool off_all = true;
    for (const RingPlane& plane : ring.planes) off_all = off_all && std::abs(plane.n.dot(p) - plane.d) > limit;
    out += off_all;
  }
  return static_cast<double>(out) / static_cast<double>(box_points_c.size());
}

std::optional<BackPlane> find_back_plane(const std::vector<Eigen::Vector3f>& box_points_c, const RingSurface& ring,
                                         const SurfaceParams& params) {
  if (box_points_c.size() < 10 || ring.planes.empty()) return std::nullopt;
  const RingPlane& largest = ring.planes[0];
  if (largest.inliers < std::max<size_t>(30, ring.samples / 3)) return std::nullopt;
  BackPlane plane;
  plane.n = largest.n;
  plane.d = largest.d;
  // The box's content in front of it (towards the camera): the object stands before the plane,
  // not in it (clutter on a wall) nor behind it (the ring is something in front of the object).
  std::vector<double> signed_distance;
  signed_distance.reserve(box_points_c.size());
  for (const Eigen::Vector3f& p : box_points_c) signed_distance.push_back(plane.n.dot(p.cast<double>()) - plane.d);
  if (!(quantile(signed_distance, 0.5) < -params.stand_out_distance)) return std::nullopt;
  return plane;
}

SupportEstimate find_support(const std::vector<Eigen::Vector3d>& points_w, const DualQuadric& q,
                             const SurfaceParams& params) {
  SupportEstimate out;
  if (!q.is_valid()) return out;
  const Eigen::Vector3d c = q.centre();
  const Eigen::Vector3d e = aligned_half_extents(q);
  // The object's lowest reach: a low quantile of the points inside its grown ellipsoid.
  std::vector<double> own;
  // 1 cm height bins below the centre, within the footprint grown by support_reach, of the points
  // well outside the ellipsoid (grown by half): a plane that extends around the object. The
  // object's own near-horizontal parts (the cap of a round object, a laptop's keyboard) lie inside.
  std::map<long, int> bins;
  for (const Eigen::Vector3d& p : points_w) {
    if (inside(q, p, params.ellipsoid_margin)) own.push_back(p.z());
    if (p.z() >= c.z() || std::abs(p.x() - c.x()) > e.x() + params.support_reach ||
        std::abs(p.y() - c.y()) > e.y() + params.support_reach || inside(q, p, 1.5)) {
      continue;
    }
    ++bins[static_cast<long>(std::floor(p.z() / 0.01))];
  }
  if (own.size() < 10) return out;
  const double lowest = quantile(own, params.trim_quantile);
  // The lowest dense band from support_max_gap below the object's lowest reach up to its bottom:
  // what it stands on, not its own top (a book's, seen past its corners) nor a laptop's keyboard
  // just above the table.
  for (auto it = bins.begin(); it != bins.end(); ++it) {
    const long bin = it->first;
    const auto next = bins.find(bin + 1);
    const int band = it->second + (next != bins.end() ? next->second : 0);  // 2 cm: noise spreads a plane
    const double z = 0.01 * (bin + 1);  // the band's middle
    if (z < lowest - params.support_max_gap) continue;  // too far below: the object does not rest on it
    if (z > lowest + params.support_band) break;        // above the object's bottom: not under it
    if (band < params.min_support_points) continue;
    // The plane's height: the mean of the band's points.
    double sum = 0.0;
    int count = 0;
    for (const Eigen::Vector3d& p : points_w) {
      if (p.z() >= 0.01 * bin && p.z() < 0.01 * (bin + 2) && std::abs(p.x() - c.x()) <= e.x() + params.support_reach &&
          std::abs(p.y() - c.y()) <= e.y() + params.support_reach && !inside(q, p, 1.5)) {
        sum += p.z();
        ++count;
      }
    }
    out.found = true;
    out.z = count > 0 ? sum / count : z;
    out.points = band;
    break;
  }
  return out;
}

std::vector<Eigen::Vector3d> object_points(const std::vector<Eigen::Vector3d>& points_w, const DualQuadric& q,
                                           const SupportEstimate& support, const SurfaceParams& params) {
  std::vector<Eigen::Vector3d> out;
  for (const Eigen::Vector3d& p : points_w) {
    if (!inside(q, p, params.ellipsoid_margin)) continue;
    if (support.found && p.z() < support.z + params.support_band) continue;
    out.push_back(p);
  }
  return out;
}

double trimmed_spread(const std::vector<Eigen::Vector3d>& points_w, const Eigen::Vector3d& direction, double trim) {
  if (points_w.empty()) return 0.0;
  std::vector<double> d;
  d.reserve(points_w.size());
  for (const Eigen::Vector3d& p : points_w) d.push_back(p.dot(direction));
  const double lo = quantile(d, trim);
  return quantile(d, 1.0 - trim) - lo;
}

bool flat_patch(const std::vector<Eigen::Vector3d>& points_w, const SurfaceParams& params) {
  if (static_cast<int>(points_w.size()) < params.min_points) return false;
  return trimmed_spread(points_w, Eigen::Vector3d::UnitZ(), params.trim_quantile) <= 2.0 * params.support_band;
}

SurfaceBoxResult fit_surface_box(const std::vector<Eigen::Vector3d>& points_w, const OrientedBox& detections_box,
                                 const std::vector<Eigen::Vector3d>& camera_centres_w,
                                 const SupportEstimate& support, const SurfaceParams& params,
                                 const std::vector<BackPlane>& back_planes_w) {
  SurfaceBoxResult out;
  out.points = static_cast<int>(points_w.size());
  if (out.points < params.min_points) return out;
  const Eigen::Vector3d origin = detections_box.centre;
  // The trimmed footprint's area at a yaw (x and y only; two nth_elements per axis).
  std::vector<double> u(points_w.size()), v(points_w.size());
  auto area = [&](double yaw) {
    const double c = std::cos(yaw), s = std::sin(yaw);
    for (size_t i = 0; i < points_w.size(); ++i) {
      const double dx = points_w[i].x() - origin.x(), dy = points_w[i].y() - origin.y();
      u[i] = c * dx + s * dy;
      v[i] = -s * dx + c * dy;
    }
    const double wu = quantile(u, 1.0 - params.trim_quantile) - quantile(u, params.trim_quantile);
    const double wv = quantile(v, 1.0 - params.trim_quantile) - quantile(v, params.trim_quantile);
    return wu * wv;
  };
  // The footprint's yaw: the smallest trimmed footprint over 2° steps, where it is clearly smaller
  // than the detections' box yaw's (round objects keep that one).
  const double yaw_detections = yaw_of(detections_box.rotation);
  double best_yaw = yaw_detections, best_area = area(yaw_detections);
  const double detections_area = best_area;
  double worst_area = best_area;
  for (int k = 1; k < 45; ++k) {
    const double yaw = yaw_detections + k * M_PI / 90.0;
    const double a = area(yaw);
    if (a < best_area) best_area = a, best_yaw = yaw;
    worst_area = std::max(worst_area, a);
  }
  double yaw = best_area < 0.9 * detections_area ? best_yaw : yaw_detections;
  // A round footprint (a bottle, a bowl) has no yaw of its own: the smallest and the largest
  // trimmed footprint within round_footprint of each other. Its box is then aligned with the map's
  // axes, a convention (the area is the same for every yaw) that keeps it from turning with noise.
  if (best_area >= params.round_footprint * worst_area) yaw = 0.0;
  const std::array<Extent, 3> p = trimmed_extents(points_w, origin, yaw, params.trim_quantile);
  // The detections' box in the same frame: its corners' extent.
  OrientedBox frame;
  frame.rotation = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  std::array<Extent, 3> b{Extent{1e300, -1e300}, Extent{1e300, -1e300}, Extent{1e300, -1e300}};
  for (const Eigen::Vector3d& corner : box_corners(detections_box)) {
    const Eigen::Vector3d l = frame.rotation.transpose() * (corner - origin);
    for (int i = 0; i < 3; ++i) b[i].lo = std::min(b[i].lo, l(i)), b[i].hi = std::max(b[i].hi, l(i));
  }
  std::array<Extent, 3> r;
  std::array<bool, 3> held_axis{false, false, false};
  for (int i = 0; i < 3; ++i) {
    bool seen_lo = false, seen_hi = false;
    for (const Eigen::Vector3d& cam : camera_centres_w) {
      const double l = (frame.rotation.transpose() * (cam - origin))(i);
      seen_lo = seen_lo || l < p[i].lo;
      seen_hi = seen_hi || l > p[i].hi;
    }
    r[i].lo = seen_lo ? p[i].lo : std::min(p[i].lo, b[i].lo);
    r[i].hi = seen_hi ? p[i].hi : std::max(p[i].hi, b[i].hi);
    out.faces_from_points += static_cast<int>(seen_lo) + static_cast<int>(seen_hi);
    // An unseen horizontal face stops at a vertical plane behind the object (the median of the
    // views' planes whose normal lies along this axis): the detections' box, from views all on
    // one side, reaches through the wall a sofa stands against.
    bool held = false;
    for (const int side : {-1, 1}) {
      if (i == 2 || (side < 0 ? seen_lo : seen_hi) || params.back_plane_max_angle_deg <= 0.0) continue;
      const Eigen::Vector3d axis = side * frame.rotation.col(i);
      std::vector<double> limits;  // along `axis` from the origin
      for (const BackPlane& plane : back_planes_w) {
        const double along = plane.n.dot(axis);
        if (along < std::cos(params.back_plane_max_angle_deg * M_PI / 180.0)) continue;
        limits.push_back((plane.d - plane.n.dot(origin)) / along);
      }
      if (limits.empty()) continue;
      const double limit = quantile(limits, 0.5);
      if (side > 0 && limit < r[i].hi) r[i].hi = std::max(p[i].hi, limit), held = true;
      if (side < 0 && -limit > r[i].lo) r[i].lo = std::min(p[i].lo, -limit), held = true;
    }
    out.faces_from_back_planes += held;
    held_axis[i] = held;
  }
  if (support.found) r[2].lo = support.z - origin.z();
  if (!(r[2].hi > r[2].lo)) return out;
  const Eigen::Vector3d mid((r[0].lo + r[0].hi) / 2, (r[1].lo + r[1].hi) / 2, (r[2].lo + r[2].hi) / 2);
  out.box.rotation = frame.rotation;
  out.box.centre = origin + frame.rotation * mid;
  out.box.half_extents = Eigen::Vector3d((r[0].hi - r[0].lo) / 2, (r[1].hi - r[1].lo) / 2, (r[2].hi - r[2].lo) / 2);
  out.ok = out.box.centre.allFinite() && out.box.half_extents.allFinite() && out.box.half_extents.minCoeff() > 0.0;
  out.min_extent_ratio = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 3; ++i) {
    if (!held_axis[i]) out.min_extent_ratio = std::min(out.min_extent_ratio, (r[i].hi - r[i].lo) / std::max(1e-9, b[i].hi - b[i].lo));
  }
  return out;
}

}  // namespace dqo::objects
