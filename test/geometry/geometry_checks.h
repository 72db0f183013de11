#pragma once
// The randomised checks of the geometry library, shared by the unit tests (a few seeds each) and
// bench_geometry (a thousand seeds each), so both test exactly the same thing. Each check builds a
// random case from its seed and returns one error measure, to compare with its threshold; the
// generators are independent of the code under test where they can be (sampled silhouettes, cell
// counts, closed forms).

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "dqo_map/geometry/box2d.h"
#include "dqo_map/geometry/conic.h"
#include "dqo_map/geometry/dual_quadric.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/quadric_distance.h"
#include "dqo_map/geometry/quadric_init.h"
#include "dqo_map/geometry/se3.h"

namespace dqo {
namespace checks {

constexpr double kPi = 3.14159265358979323846;
constexpr double kFail = std::numeric_limits<double>::infinity();

// ------------------------------------------------------------------ thresholds (tests and bench)
constexpr double kSe3Tolerance = 1e-9;
constexpr double kCameraTolerancePx = 1e-9;
constexpr double kQuadricRoundTripTolerance = 1e-9;
constexpr double kConicBoxTolerancePx = 0.5;
constexpr double kNoiseFreeInitTolerance = 1e-6;
constexpr double kNoisyCentreTolerance = 0.02;  // of the largest full extent
constexpr double kBoxTolerance = 1e-12;
constexpr double kPlaneTolerance = 1e-9;
constexpr double kDistanceTolerance = 1e-9;
constexpr double kDepthInitToleranceM = 1e-9;  // the scenes' depths are exact in float

// ------------------------------------------------------------------ random scene
inline double uniform(std::mt19937_64& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

inline Eigen::Matrix3d random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  return q.normalized().toRotationMatrix();
}

inline SE3 random_pose(std::mt19937_64& rng, double max_translation = 5.0) {
  const Eigen::Vector3d t(uniform(rng, -max_translation, max_translation),
                          uniform(rng, -max_translation, max_translation),
                          uniform(rng, -max_translation, max_translation));
  return SE3::from_rotation_translation(random_rotation(rng), t);
}

// The Kinect-like camera of the test scenes: 640x480, f = 525.
inline PinholeCamera test_camera() { return PinholeCamera{525.0, 525.0, 319.5, 239.5, 640, 480}; }

// Semi-axes in [0.05, 0.5] m (full sizes 0.1–1 m), centre within ±2 m of the origin.
inline DualQuadric random_quadric(std::mt19937_64& rng) {
  const Eigen::Vector3d centre(uniform(rng, -2, 2), uniform(rng, -2, 2), uniform(rng, -2, 2));
  const Eigen::Vector3d axes(uniform(rng, 0.05, 0.5), uniform(rng, 0.05, 0.5),
                             uniform(rng, 0.05, 0.5));
  return DualQuadric::from_params(centre, random_rotation(rng), axes);
}

// T_cw of a camera at `position` whose optical axis points at `target`, rolled by `roll`.
inline SE3 look_at(const Eigen::Vector3d& position, const Eigen::Vector3d& target, double roll) {
  const Eigen::Vector3d z = (target - position).normalized();
  Eigen::Vector3d helper = std::abs(z.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitX();
  Eigen::Vector3d x = helper.cross(z).normalized();
  Eigen::Vector3d y = z.cross(x);
  const double c = std::cos(roll), s = std::sin(roll);
  const Eigen::Vector3d xr = c * x + s * y;
  const Eigen::Vector3d yr = -s * x + c * y;
  Eigen::Matrix3d R_wc;
  R_wc << xr, yr, z;
  return SE3::from_rotation_translation(R_wc, position).inverse();
}

struct SyntheticView {
  SE3 T_cw;
  Box2d box;  // the exact conic box
};

// A camera 1–4 m from the object, azimuth `azimuth`, looking near (not exactly at) its centre, with
// the whole box at least `inner_margin` px inside the image. Retries distance and aim until it fits.
inline bool random_view(std::mt19937_64& rng, const DualQuadric& q, const PinholeCamera& cam,
                        double azimuth, double inner_margin, SyntheticView* out) {
  for (int attempt = 0; attempt < 200; ++attempt) {
    const double elevation = uniform(rng, -0.3, 1.0);
    const double distance = uniform(rng, 1.0, 4.0);
    const Eigen::Vector3d dir(std::cos(elevation) * std::cos(azimuth),
                              std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
    const Eigen::Vector3d position = q.centre() + distance * dir;
    const Eigen::Vector3d aim =
        q.centre() + 0.08 * distance *
                         Eigen::Vector3d(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
    const SE3 T_cw = look_at(position, aim, uniform(rng, -kPi, kPi));
    const std::optional<ProjectedBox> pb = projected_box(q, cam, T_cw, 0.05);
    if (!pb) continue;
    const Box2d& b = pb->unclipped;
    if (b.x_min < inner_margin || b.y_min < inner_margin || b.x_max > cam.width - inner_margin ||
        b.y_max > cam.height - inner_margin) {
      continue;
    }
    out->T_cw = T_cw;
    out->box = b;
    return true;
  }
  return false;
}

// n views spread over an azimuth arc of 90°–360° (so that the parallax is real), boxes inside the
// image by more than the border margin.
inline std::vector<SyntheticView> random_views(std::mt19937_64& rng, const DualQuadric& q,
                                               const PinholeCamera& cam, int n) {
  const double start = uniform(rng, -kPi, kPi);
  const double span = uniform(rng, 0.5 * kPi, 2.0 * kPi);
  std::vector<SyntheticView> views;
  for (int i = 0; i < n; ++i) {
    const double az = start + span * i / n + uniform(rng, -0.1, 0.1);
    SyntheticView v;
    if (random_view(rng, q, cam, az, 10.0, &v)) views.push_back(v);
  }
  return views;
}

inline std::vector<BoxObservation> to_observations(const std::vector<SyntheticView>& views,
                                                   const PinholeCamera& cam) {
  std::vector<BoxObservation> obs;
  for (const SyntheticView& v : views) {
    obs.push_back(BoxObservation{cam.projection_matrix(v.T_cw), v.box, cam.width, cam.height});
  }
  return obs;
}

inline Eigen::Matrix4d normalised(const Eigen::Matrix4d& Q) { return Q / (-Q(3, 3)); }

inline Eigen::Vector3d sorted_desc(Eigen::Vector3d v) {
  std::sort(v.data(), v.data() + 3, [](double a, double b) { return a > b; });
  return v;
}

// ------------------------------------------------------------------ checks
// Max error of composition, inverse, matrix form and exp/log on random poses and points.
inline double se3_error(uint64_t seed) {
  std::mt19937_64 rng(seed);
  const SE3 T_ab = random_pose(rng), T_bc = random_pose(rng);
  const Eigen::Vector3d p_c(uniform(rng, -3, 3), uniform(rng, -3, 3), uniform(rng, -3, 3));
  double err = ((T_ab * T_bc) * p_c - T_ab * (T_bc * p_c)).norm();
  err = std::max(err, ((T_ab * T_bc).matrix() - T_ab.matrix() * T_bc.matrix()).cwiseAbs().maxCoeff());
  err = std::max(err, ((T_ab * T_ab.inverse()).matrix() - Eigen::Matrix4d::Identity()).cwiseAbs().maxCoeff());
  err = std::max(err, (T_ab.inverse() * (T_ab * p_c) - p_c).norm());
  err = std::max(err, (SE3::from_matrix(T_ab.matrix()).matrix() - T_ab.matrix()).cwiseAbs().maxCoeff());
  err = std::max(err, (SE3::exp(T_ab.log()).matrix() - T_ab.matrix()).cwiseAbs().maxCoeff());
  Vector6d xi;
  for (int i = 0; i < 6; ++i) xi(i) = uniform(rng, -2.0, 2.0);  // |phi| <= 3.46 may exceed pi
  if (xi.tail<3>().norm() < kPi - 1e-3) err = std::max(err, (SE3::exp(xi).log() - xi).norm());
  return err;
}

// Pixels: project(back_project(u, v, d)) against (u, v), and P [p; 1] against project(T_cw p).
inline double camera_error(uint64_t seed) {
  std::mt19937_64 rng(seed);
  const PinholeCamera cam{uniform(rng, 300, 900), uniform(rng, 300, 900), uniform(rng, 200, 400),
                          uniform(rng, 150, 300), 640, 480};
  const double u = uniform(rng, 0, 640), v = uniform(rng, 0, 480), d = uniform(rng, 0.2, 10.0);
  const Eigen::Vector3d p_c = cam.back_project(u, v, d);
  double err = (cam.project(p_c) - Eigen::Vector2d(u, v)).norm();
  err = std::max(err, std::abs(p_c.z() - d));
  const SE3 T_cw = random_pose(rng);
  const Eigen::Vector3d p_w = T_cw.inverse() * Eigen::Vector3d(uniform(rng, -2, 2), uniform(rng, -2, 2),
                                                               uniform(rng, 0.5, 8.0));
  const Eigen::Vector3d x = cam.projection_matrix(T_cw) * p_w.homogeneous();
  err = std::max(err, (x.hnormalized() - cam.project(T_cw * p_w)).norm());
  return err;
}

// from_params → matrix → (random scale, either sign) → from_matrix: matrices, centre, sorted axes and
// the axis directions (up to sign) must agree.
inline double quadric_round_trip_error(uint64_t seed) {
  std::mt19937_64 rng(seed);
  const DualQuadric q = random_quadric(rng);
  const double scale = (seed % 2 ? -1.0 : 1.0) * std::pow(10.0, uniform(rng, -3, 3));
  const std::optional<DualQuadric> back = DualQuadric::from_matrix(scale * q.matrix());
  if (!back || !back->is_valid()) return kFail;
  double err = (back->matrix() - q.matrix()).cwiseAbs().maxCoeff();
  err = std::max(err, (back->centre() - q.centre()).norm());
  // Match axes by size (from_matrix returns them in descending order).
  std::array<int, 3> order{0, 1, 2};
  std::sort(order.begin(), order.end(),
            [&q](int a, int b) { return q.semi_axes()(a) > q.semi_axes()(b); });
  for (int i = 0; i < 3; ++i) {
    err = std::max(err, std::abs(back->semi_axes()(i) - q.semi_axes()(order[i])));
    const double cos_angle = std::abs(back->rotation().col(i).dot(q.rotation().col(order[i])));
    err = std::max(err, 1.0 - cos_angle);
  }
  return err;
}

// transformed(T) against T Q* Tᵀ, and is_valid / is_ellipsoid rejecting broken matrices.
inline double quadric_transform_error(uint64_t seed) {
  std::mt19937_64 rng(seed);
  const DualQuadric q = random_quadric(rng);
  const SE3 T = random_pose(rng);
  const Eigen::Matrix4d expected = T.matrix() * q.matrix() * T.matrix().transpose();
  double err = (q.transformed(T).matrix() - normalised(expected)).cwiseAbs().maxCoeff();
  // A hyperboloid (one negative axis²), a point at infinity and NaN are not ellipsoids.
  Eigen::Matrix4d Tm = Eigen::Matrix4d::Identity();
  Tm.topLeftCorner<3, 3>() = q.rotation();
  Tm.topRightCorner<3, 1>() = q.centre();
  const Eigen::Vector3d a2 = q.semi_axes().cwiseAbs2();
  const Eigen::Matrix4d hyperboloid =
      Tm * Eigen::Vector4d(a2(0), a2(1), -a2(2), -1.0).asDiagonal() * Tm.transpose();
  Eigen::Matrix4d at_infinity = q.matrix();
  at_infinity(3, 3) = 0.0;
  Eigen::Matrix4d with_nan = q.matrix();
  with_nan(1, 2) = std::nan("");
  if (!is_ellipsoid(q.matrix()) || is_ellipsoid(hyperboloid) || is_ellipsoid(at_infinity) ||
      is_ellipsoid(with_nan) || DualQuadric::from_matrix(hyperboloid) ||
      DualQuadric::from_matrix(with_nan)) {
    return kFail;
  }
  DualQuadric bad = DualQuadric::from_params(q.centre(), q.rotation(), Eigen::Vector3d(0.1, -0.2, 0.3));
  if (bad.is_valid() || !q.is_valid()) return kFail;
  return err;
}

// The closed-form conic box against the box of 200 x 400 projected surface points. The sampled box
// must lie inside the conic box (to 1e-6 px, else kFail) and the gap is the error.
inline double conic_box_error(uint64_t seed) {
  std::mt19937_64 rng(seed);
  const PinholeCamera cam = test_camera();
  const DualQuadric q = random_quadric(rng);
  SyntheticView view;
  if (!random_view(rng, q, cam, uniform(rng, -kPi, kPi), -300.0, &view)) return kFail;
  const std::optional<Box2d> conic =
      conic_bounding_box(project_quadric(q, cam.projection_matrix(view.T_cw)));
  if (!conic) return kFail;
  Box2d sampled{kFail, kFail, -kFail, -kFail};
  const int n_theta = 200, n_phi = 400;
  for (int i = 0; i <= n_theta; ++i) {
    const double theta = kPi * i / n_theta;
    for (int j = 0; j < n_phi; ++j) {
      const double phi = 2.0 * kPi * j / n_phi;
      const Eigen::Vector3d unit(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                                 std::cos(theta));
      const Eigen::Vector3d p_w = q.centre() + q.rotation() * q.semi_axes().cwiseProduct(unit);
      const Eigen::Vector2d uv = cam.project(view.T_cw * p_w);
      sampled.x_min = std::min(sampled.x_min, uv.x());
      sampled.y_min = std::min(sampled.y_min, uv.y());
      sampled.x_max = std::max(sampled.x_max, uv.x());
      sampled.y_max = std::max(sampled.y_max, uv.y());
    }
  }
  const std::array<double, 4> gaps{sampled.x_min - conic->x_min, sampled.y_min - conic->y_min,
                                   conic->x_max - sampled.x_max, conic->y_max - sampled.y_max};
  double worst = 0.0;
  for (double g : gaps) {
    if (g < -1e-6) return kFail;
    worst = std::max(worst, g);
  }
  return worst;
}


// 3–8 noise-free views: the recovered Q* (normalised), centre (relative to the largest semi-axis)
// and sorted semi-axes (relative) against the truth.
inline double init_noise_free_error(uint64_t seed) {
  std::mt19937_64 rng(seed);
  const PinholeCamera cam = test_camera();
  const DualQuadric q = random_quadric(rng);
  const int n = 3 + static_cast<int>(seed % 6);
  const std::vector<SyntheticView> views = random_views(rng, q, cam, n);
  if (static_cast<int>(views.size()) < n) return kFail;
  const QuadricInitResult r = initialise_from_boxes(to_observations(views, cam));
  if (!r.ok) return kFail;
  const double size = q.semi_axes().maxCoeff();
  const Eigen::Matrix4d Qt = q.matrix(), Qr = r.quadric.matrix();
  double err = (Qr - Qt).cwiseAbs().maxCoeff() / Qt.cwiseAbs().maxCoeff();
  err = std::max(err, (r.quadric.centre() - q.centre()).norm() / size);
  err = std::max(err, ((sorted_desc(r.quadric.semi_axes()) - sorted_desc(q.semi_axes()))
                           .cwiseQuotient(sorted_desc(q.semi_axes())))
                          .cwiseAbs()
                          .maxCoeff());
  return err;
}

// 10 views, every box edge moved by uniform noise in [−2, 2] px: centre error over the object's
// largest full extent.
inline double init_noisy_centre_error(uint64_t seed) {
  std::mt19937_64 rng(seed);
  const PinholeCamera cam = test_camera();
  const DualQuadric q = random_quadric(rng);
  const std::vector<SyntheticView> views = random_views(rng, q, cam, 10);
  if (views.size() < 10) return kFail;
  std::vector<BoxObservation> obs = to_observations(views, cam);
  for (BoxObservation& o : obs) {
    o.box.x_min += uniform(rng, -2, 2);
    o.box.x_max += uniform(rng, -2, 2);
    o.box.y_min += uniform(rng, -2, 2);
    o.box.y_max += uniform(rng, -2, 2);
  }
  const QuadricInitResult r = initialise_from_boxes(obs);
  if (!r.ok) return kFail;
  return (r.quadric.centre() - q.centre()).norm() / (2.0 * q.semi_axes().maxCoeff());
}

// The degenerate inputs must fail (the first three with their own status): 1 when any does not.
inline double init_degenerate_failures(uint64_t seed) {
  std::mt19937_64 rng(seed);
  const PinholeCamera cam = test_camera();
  const DualQuadric q = random_quadric(rng);
  std::vector<SyntheticView> views = random_views(rng, q, cam, 6);
  if (views.size() < 6) return 1.0;
  std::vector<BoxObservation> obs = to_observations(views, cam);

  // < 3 views.
  const std::vector<BoxObservation> two(obs.begin(), obs.begin() + 2);
  if (initialise_from_boxes(two).status != InitStatus::kTooFewViews) return 1.0;

  // Every box reaching the border on all four sides (an object filling the view).
  std::vector<BoxObservation> at_border = obs;
  for (BoxObservation& o : at_border) o.box = Box2d{1.0, 2.0, 638.0, 479.0};
  if (initialise_from_boxes(at_border).status != InitStatus::kBoxesTouchBorder) return 1.0;

  // All cameras at one place (the first view's), turned differently, all seeing the object.
  const Eigen::Vector3d position = views[0].T_cw.inverse().translation();
  std::vector<BoxObservation> one_place;
  for (int i = 0; i < 6; ++i) {
    for (int attempt = 0; attempt < 100; ++attempt) {
      const Eigen::Vector3d aim =
          q.centre() + 0.1 * Eigen::Vector3d(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
      const SE3 T_cw = look_at(position, aim, uniform(rng, -kPi, kPi));
      const std::optional<ProjectedBox> pb = projected_box(q, cam, T_cw);
      if (pb && pb->box.valid() && !pb->unclipped.touches_border(cam.width, cam.height, 6.0)) {
        one_place.push_back(BoxObservation{cam.projection_matrix(T_cw), pb->unclipped, cam.width,
                                           cam.height});
        break;
      }
    }
  }
  if (one_place.size() < 3) return 1.0;
  if (initialise_from_boxes(one_place).status != InitStatus::kDegenerateGeometry) return 1.0;

  // Nearly one place: within 1 mm, boxes with 2 px noise. Any failure will do, but no ellipsoid.
  for (BoxObservation& o : one_place) {
    const SE3 T_cw = SE3::from_matrix((Eigen::Matrix4d() << cam.K().inverse() * o.P,
                                       Eigen::RowVector4d(0, 0, 0, 1)).finished());
    const Eigen::Vector3d jitter(uniform(rng, -1e-3, 1e-3), uniform(rng, -1e-3, 1e-3),
                                 uniform(rng, -1e-3, 1e-3));
    o.P = cam.projection_matrix(SE3(T_cw.quaternion(), T_cw.translation() + jitter));
    o.box.x_min += uniform(rng, -2, 2);
    o.box.x_max += uniform(rng, -2, 2);
    o.box.y_min += uniform(rng, -2, 2);
    o.box.y_max += uniform(rng, -2, 2);
  }
  if (initialise_from_boxes(one_place).ok) return 1.0;
  return 0.0;
}

// A synthetic depth image of an object in front of a wall, and the ellipsoid expected from the
// scene itself (not from the image's samples). By seed: a thin object (about a third of the box
// wide, a bottle: the reason for the robust rule), a wide one (most of the box), or only a
// fronto-parallel wall filling the box. The object's surface has two fronto-parallel steps (near
// and far, each 40-60 % of its columns); the wall behind it is slanted about the camera's y axis
// and lies beyond the object's reach everywhere; the image has a few holes. What the rule promises
// (quadric_init.h): the front surface is the nearest thing covering the box's centre, the depth
// semi-axis the object's own depth extent within its bounds, the centre one depth semi-axis
// behind the front on the box-centre ray. Every depth is exact in float, so the model is too.
inline double depth_init_error(uint64_t seed) {
  std::mt19937_64 rng(seed);
  const PinholeCamera cam = test_camera();
  const DepthInitParams params;
  const int kind = static_cast<int>(seed % 3);  // 0 thin object, 1 wide object, 2 wall only
  const double bw = std::round(uniform(rng, 120, 560)), bh = std::round(uniform(rng, 120, 420));
  const double bx = std::round(uniform(rng, 10, cam.width - 10 - bw));
  const double by = std::round(uniform(rng, 10, cam.height - 10 - bh));
  const Box2d box{bx, by, bx + bw, by + bh};
  // Depths as the image stores them (float), so that the model sees what the function sees.
  const auto as_float = [](double d) { return static_cast<double>(static_cast<float>(d)); };
  const double z_near = as_float(uniform(rng, 0.8, 3.0));
  const double lateral_max = 0.5 * std::max(bw / cam.fx, bh / cam.fy) * z_near;
  const double lateral_min = 0.5 * std::min(bw / cam.fx, bh / cam.fy) * z_near;
  const double z_far = kind == 2 ? z_near : as_float(z_near + uniform(rng, 0.01, 1.5) * lateral_max);
  // The object's columns [c0, c1) split at c_step, and rows [r0, r1), in pixels.
  const double a0 = kind == 0 ? uniform(rng, 0.30, 0.36) : uniform(rng, 0.10, 0.20);
  const double a1 = kind == 0 ? a0 + uniform(rng, 0.30, 0.36) : uniform(rng, 0.80, 0.90);
  const double split = uniform(rng, 0.4, 0.6);
  const bool near_left = uniform(rng, 0, 1) < 0.5;
  const double c0 = bx + std::round(a0 * bw), c1 = bx + std::round(a1 * bw);
  const double c_step = std::round(c0 + split * (c1 - c0));
  const double r0 = by + std::round(uniform(rng, 0.0, 0.2) * bh);
  const double r1 = by + std::round(uniform(rng, 0.8, 1.0) * bh);
  // Wall: depth zw0 / (1 − tan(s) x̂), x̂ = (u − cx)/fx in [−0.61, 0.61] over the image, so at
  // least zw0 / (1 + 0.62 |tan s|): beyond the object's reach behind its front surface.
  const double tan_s = std::tan(uniform(rng, -0.5, 0.5));
  const double zw0 = (z_near + params.max_depth_reach * lateral_max + uniform(rng, 0.1, 1.5)) *
                     (1.0 + 0.62 * std::abs(tan_s));
  std::vector<float> image(static_cast<size_t>(cam.width) * cam.height, 0.0f);
  for (int v = 0; v < cam.height; ++v) {
    for (int u = 0; u < cam.width; ++u) {
      double d = zw0 / (1.0 - tan_s * (u - cam.cx) / cam.fx);
      if (kind == 2) d = z_near;
      if (kind != 2 && u >= c0 && u < c1 && v >= r0 && v < r1) {
        d = ((u < c_step) == near_left) ? z_near : z_far;
      }
      const bool hole = ((u * 7 + v * 13) % 97) == 0;
      image[static_cast<size_t>(v) * cam.width + u] = hole ? std::nanf("") : static_cast<float>(d);
    }
  }
  const SE3 T_wc = random_pose(rng);
  const QuadricInitResult r =
      initialise_from_depth(box, cam, T_wc, DepthView{image.data(), cam.width, cam.height}, params);
  if (!r.ok) return kFail;
  const double c = std::clamp(z_far - z_near,
                              std::max(params.min_semi_axis, params.min_depth_axis_ratio * lateral_min),
                              std::max(params.min_semi_axis, params.max_depth_axis_ratio * lateral_max));
  const double z_c = z_near + c;
  const Eigen::Vector2d m = box.centre();
  const Eigen::Vector3d centre_c((m.x() - cam.cx) / cam.fx * z_c, (m.y() - cam.cy) / cam.fy * z_c, z_c);
  const Eigen::Vector3d axes(std::max(params.min_semi_axis, 0.5 * bw * z_c / cam.fx),
                             std::max(params.min_semi_axis, 0.5 * bh * z_c / cam.fy),
                             std::max(params.min_semi_axis, c));
  double err = (r.quadric.centre() - T_wc * centre_c).norm();
  err = std::max(err, (r.quadric.semi_axes() - axes).cwiseAbs().maxCoeff());
  err = std::max(err, (r.quadric.rotation() - T_wc.rotation()).cwiseAbs().maxCoeff());
  // No valid depth must fail, not invent an object; nor may depth only at the box's margins.
  std::vector<float> empty(image.size(), 0.0f);
  if (initialise_from_depth(box, cam, T_wc, DepthView{empty.data(), cam.width, cam.height}, params)
          .status != InitStatus::kNoValidDepth) {
    return kFail;
  }
  for (int v = 0; v < cam.height; ++v) {
    for (int u = 0; u < cam.width; ++u) {
      const bool central = u >= bx + 0.2 * bw && u < bx + 0.8 * bw && v >= by + 0.2 * bh && v < by + 0.8 * bh;
      if (central) image[static_cast<size_t>(v) * cam.width + u] = std::nanf("");
    }
  }
  if (initialise_from_depth(box, cam, T_wc, DepthView{image.data(), cam.width, cam.height}, params)
          .status != InitStatus::kNoValidDepth) {
    return kFail;
  }
  return err;
}

// IoU of boxes with integer corners against counting the unit cells they cover, plus symmetry,
// range, identity, disjointness and the overlap ratio; the largest deviation.
inline double box_iou_error(uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> coord(0, 40);
  const auto random_box = [&]() {
    int x0 = coord(rng), x1 = coord(rng), y0 = coord(rng), y1 = coord(rng);
    if (x0 == x1) ++x1;
    if (y0 == y1) ++y1;
    return Box2d{double(std::min(x0, x1)), double(std::min(y0, y1)), double(std::max(x0, x1)),
                 double(std::max(y0, y1))};
  };
  const Box2d a = random_box(), b = random_box();
  int in_a = 0, in_b = 0, in_both = 0;
  for (int y = 0; y < 42; ++y) {
    for (int x = 0; x < 42; ++x) {
      const double cx = x + 0.5, cy = y + 0.5;
      const bool ia = cx > a.x_min && cx < a.x_max && cy > a.y_min && cy < a.y_max;
      const bool ib = cx > b.x_min && cx < b.x_max && cy > b.y_min && cy < b.y_max;
      in_a += ia;
      in_b += ib;
      in_both += ia && ib;
    }
  }
  const double expected = double(in_both) / double(in_a + in_b - in_both);
  const double value = iou(a, b);
  double err = std::abs(value - expected);
  err = std::max(err, std::abs(value - iou(b, a)));
  if (value < 0.0 || value > 1.0) return kFail;
  err = std::max(err, std::abs(iou(a, a) - 1.0));
  const Box2d far{a.x_max + 1.0, a.y_min, a.x_max + 5.0, a.y_max};
  err = std::max(err, iou(a, far));
  err = std::max(err, std::abs(overlap_ratio(a, b) - double(in_both) / double(in_b)));
  return err;
}

// Points on the ray through a pixel of an image line lie on the plane Pᵀ l (relative |πᵀX|).
inline double plane_from_line_error(uint64_t seed) {
  std::mt19937_64 rng(seed);
  const PinholeCamera cam = test_camera();
  const SE3 T_cw = random_pose(rng);
  const Eigen::Matrix<double, 3, 4> P = cam.projection_matrix(T_cw);
  const Eigen::Vector3d l(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -300, 300));
  // A pixel on l: the foot of the perpendicular from the image centre, plus a step along l.
  const Eigen::Vector2d n = l.head<2>();
  const Eigen::Vector2d c(cam.cx, cam.cy);
  const Eigen::Vector2d foot = c - (n.dot(c) + l(2)) / n.squaredNorm() * n;
  const Eigen::Vector2d uv = foot + uniform(rng, -200, 200) * Eigen::Vector2d(-n.y(), n.x()).normalized();
  const Eigen::Vector4d pi = plane_from_line(P, l);
  double err = 0.0;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d X = T_cw.inverse() * cam.back_project(uv.x(), uv.y(), uniform(rng, 0.1, 10.0));
    err = std::max(err, std::abs(pi.dot(X.homogeneous())) / (pi.norm() * X.homogeneous().norm()));
  }
  return err;
}

// QD and W2: identity, symmetry, monotonic fall with centre offset, W2 closed form for ellipsoids
// with a common rotation (commuting shapes: W2² = ‖Δmu‖² + Σ (a_i − b_i)²).
inline double distance_error(uint64_t seed) {
  std::mt19937_64 rng(seed);
  const DualQuadric a = random_quadric(rng);
  double err = std::abs(quadric_distance(a, a, 1.0) - 1.0);
  err = std::max(err, std::abs(wasserstein_distance_sq(a, a)));
  err = std::max(err, std::abs(wasserstein_similarity(a, a) - 1.0));
  const DualQuadric b = random_quadric(rng);
  err = std::max(err, std::abs(wasserstein_distance_sq(a, b) - wasserstein_distance_sq(b, a)));
  err = std::max(err, std::abs(quadric_distance(a, b, 2.0) - quadric_distance(b, a, 2.0)));
  // Falls strictly as the centre moves away along a random direction.
  const Eigen::Vector3d dir = random_rotation(rng).col(0);
  double previous_qd = 1.0, previous_w = 1.0;
  for (int k = 1; k <= 5; ++k) {
    const DualQuadric moved = DualQuadric::from_params(a.centre() + 0.2 * k * dir, a.rotation(), a.semi_axes());
    const double qd = quadric_distance(a, moved, 1.0);
    const double w = wasserstein_similarity(a, moved);
    if (!(qd < previous_qd) || !(w < previous_w)) return kFail;
    previous_qd = qd;
    previous_w = w;
  }
  const DualQuadric c = DualQuadric::from_params(b.centre(), a.rotation(), b.semi_axes());
  const double closed = (a.centre() - c.centre()).squaredNorm() + (a.semi_axes() - c.semi_axes()).squaredNorm();
  err = std::max(err, std::abs(wasserstein_distance_sq(a, c) - closed));
  // QD by hand for the same pair.
  const double qd_hand = std::exp(-0.7 * ((a.centre() - c.centre()).norm() +
                                          (a.shape_matrix() - c.shape_matrix()).norm()));
  err = std::max(err, std::abs(quadric_distance(a, c, 0.7) - qd_hand));
  QuadricDistanceParams params;
  params.kind = QuadricDistanceKind::kWasserstein;
  err = std::max(err, std::abs(quadric_similarity(a, c, params) - std::exp(-std::sqrt(closed) / 10.0)));
  return err;
}

}  // namespace checks
}  // namespace dqo
