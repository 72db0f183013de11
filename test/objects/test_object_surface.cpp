// The object's own surface (src/objects/object_surface.h) and the refinement's upright and support
// priors: the support under an object found from its boxes' points, the box from the points where
// cameras looked and from the detections where none did, and priors that hold an upright object
// upright on few noisy views while many views still tilt a tilted one.
#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "../../src/objects/object_surface.h"
#include "dqo_map/geometry/conic.h"
#include "dqo_map/geometry/oriented_box.h"
#include "dqo_map/objects/object_refinement.h"
#include "object_test_util.h"

namespace dqo::objects {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Points on the faces of `box` that a camera at one of `cameras` faces (about 1 cm apart), plus a
// table top at `table_z` around it (a 0.8 m square), with depth-like noise of sigma metres.
std::vector<Eigen::Vector3d> scene_points(const OrientedBox& box, const std::vector<Eigen::Vector3d>& cameras,
                                          double table_z, double sigma, std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, sigma);
  std::vector<Eigen::Vector3d> out;
  const Eigen::Vector3d& h = box.half_extents;
  for (int axis = 0; axis < 3; ++axis) {
    for (const int sign : {-1, 1}) {
      const Eigen::Vector3d normal = sign * box.rotation.col(axis);
      const Eigen::Vector3d face = box.centre + sign * h(axis) * box.rotation.col(axis);
      bool faced = false;
      for (const Eigen::Vector3d& c : cameras) faced = faced || (c - face).dot(normal) > 0.0;
      if (!faced || (axis == 2 && sign < 0)) continue;  // the bottom rests on the table
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      for (double a = -h(u); a <= h(u); a += 0.01) {
        for (double b = -h(v); b <= h(v); b += 0.01) {
          Eigen::Vector3d local = Eigen::Vector3d::Zero();
          local(axis) = sign * h(axis);
          local(u) = a;
          local(v) = b;
          out.push_back(box.centre + box.rotation * local + Eigen::Vector3d(n(rng), n(rng), n(rng)));
        }
      }
    }
  }
  for (double x = -0.4; x <= 0.4; x += 0.01) {
    for (double y = -0.4; y <= 0.4; y += 0.01) {
      const Eigen::Vector3d p(box.centre.x() + x, box.centre.y() + y, table_z + n(rng));
      if (contains(box, Eigen::Vector3d(p.x(), p.y(), box.centre.z()))) continue;  // under the object
      out.push_back(p);
    }
  }
  return out;
}

OrientedBox truth_box() {
  OrientedBox b;
  b.centre = Eigen::Vector3d(0.3, -0.2, 0.75 + 0.08);
  b.rotation = Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  b.half_extents = Eigen::Vector3d(0.15, 0.1, 0.08);
  return b;
}

std::vector<Eigen::Vector3d> ring(const Eigen::Vector3d& target, double from, double to, int n, double height) {
  std::vector<Eigen::Vector3d> out;
  for (int k = 0; k < n; ++k) {
    const double a = from + (to - from) * k / std::max(1, n - 1);
    out.push_back(target + Eigen::Vector3d(1.2 * std::cos(a), 1.2 * std::sin(a), height));
  }
  return out;
}

// Three cameras on `ring` within ±0.2 rad of `axis` (horizontal) from `target`: a box seen from one
// side only.
std::vector<Eigen::Vector3d> facing(const Eigen::Vector3d& target, const Eigen::Vector3d& axis) {
  const double yaw = std::atan2(axis.y(), axis.x());
  return ring(target, yaw - 0.2, yaw + 0.2, 3, 0.5);
}

TEST(ObjectSurface, FindsTheTableUnderTheObjectNotItsOwnTop) {
  std::mt19937_64 rng(1);
  const OrientedBox truth = truth_box();
  const std::vector<Eigen::Vector3d> cams = ring(truth.centre, 0.0, 2.0 * kPi, 8, 0.5);
  const std::vector<Eigen::Vector3d> pts = scene_points(truth, cams, 0.75, 0.003, rng);
  // A loose ellipsoid around it, as the box-plane fit gives.
  const DualQuadric q = DualQuadric::from_params(truth.centre + Eigen::Vector3d(0.02, -0.01, 0.02), truth.rotation,
                                                 1.3 * truth.half_extents);
  const SurfaceParams params;
  const SupportEstimate s = find_support(pts, q, params);
  ASSERT_TRUE(s.found);
  EXPECT_NEAR(s.z, 0.75, 0.003);
  // A laptop's keyboard is a dense band too (2 cm above the table): the table under it wins.
  OrientedBox keyboard = truth;
  keyboard.half_extents.z() = 0.01;
  keyboard.centre.z() = 0.76;
  std::vector<Eigen::Vector3d> with_keyboard = scene_points(keyboard, cams, 0.75, 0.002, rng);
  with_keyboard.insert(with_keyboard.end(), pts.begin(), pts.end());
  const SupportEstimate k = find_support(with_keyboard, q, params);
  ASSERT_TRUE(k.found);
  EXPECT_NEAR(k.z, 0.75, 0.004);
  // Floating 20 cm above any surface: no support.
  OrientedBox floating = truth;
  floating.centre.z() += 0.2;
  const std::vector<Eigen::Vector3d> far = scene_points(floating, cams, 0.75, 0.003, rng);
  const DualQuadric qf = DualQuadric::from_params(floating.centre, floating.rotation, 1.3 * floating.half_extents);
  EXPECT_FALSE(find_support(far, qf, params).found);
}

TEST(ObjectSurface, BoxFromThePointsWhereCamerasLookedAndFromTheDetectionsElsewhere) {
  std::mt19937_64 rng(2);
  const OrientedBox truth = truth_box();
  const SurfaceParams params;
  // The detections' box: loose (15 % larger), yawed 10° off.
  OrientedBox detections = truth;
  detections.half_extents *= 1.15;
  detections.rotation = Eigen::AngleAxisd(0.5 + 10.0 * kPi / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const DualQuadric q = DualQuadric::from_params(truth.centre, truth.rotation, 1.3 * truth.half_extents);

  // Seen from all around and above: every face from the points, the box within about a centimetre.
  const std::vector<Eigen::Vector3d> all_round = ring(truth.centre, 0.0, 2.0 * kPi, 8, 0.5);
  std::vector<Eigen::Vector3d> pts = scene_points(truth, all_round, 0.75, 0.002, rng);
  SupportEstimate s = find_support(pts, q, params);
  ASSERT_TRUE(s.found);
  SurfaceBoxResult r = fit_surface_box(object_points(pts, q, s, params), detections, all_round, s, params);
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.faces_from_points, 5);  // not the bottom: no camera below the table
  EXPECT_LT((r.box.centre - truth.centre).norm(), 0.01);
  // The same box up to the order of its horizontal axes (a yaw of 90° more swaps them).
  const double a = r.box.half_extents.x(), b = r.box.half_extents.y();
  EXPECT_NEAR(std::max(a, b), truth.half_extents.x(), 0.01);
  EXPECT_NEAR(std::min(a, b), truth.half_extents.y(), 0.01);
  EXPECT_NEAR(r.box.half_extents.z(), truth.half_extents.z(), 0.01);
  EXPECT_GT(iou_3d(r.box, truth), 0.85);
  EXPECT_LT(iou_3d(detections, truth), 0.75) << "the points are what made it tight";

  // Seen from one side only (the box's +x side): the far side comes from the detections' box.
  const Eigen::Vector3d x_axis = truth.rotation.col(0);
  const std::vector<Eigen::Vector3d> one_side = facing(truth.centre, x_axis);
  pts = scene_points(truth, one_side, 0.75, 0.002, rng);
  s = find_support(pts, q, params);
  ASSERT_TRUE(s.found);
  r = fit_surface_box(object_points(pts, q, s, params), detections, one_side, s, params);
  ASSERT_TRUE(r.ok);
  // Along the box's x axis: the seen +x face from the points, the unseen -x face no nearer than
  // the detections' box reaches.
  double det_lo = 1e9;
  for (const Eigen::Vector3d& c : box_corners(detections)) det_lo = std::min(det_lo, x_axis.dot(c - truth.centre));
  double lo = 1e9, hi = -1e9;
  for (const Eigen::Vector3d& c : box_corners(r.box)) {
    lo = std::min(lo, x_axis.dot(c - truth.centre));
    hi = std::max(hi, x_axis.dot(c - truth.centre));
  }
  EXPECT_NEAR(hi, truth.half_extents.x(), 0.015);
  EXPECT_LE(lo, det_lo + 0.02);
  EXPECT_LT(lo, -truth.half_extents.x() + 0.005) << "the unseen back is not cut to the front face";
  // Its bottom on the table.
  EXPECT_NEAR(r.box.centre.z() - r.box.half_extents.z(), 0.75, 0.004);
}

// Seen from one side only, standing against a wall: the unseen back stops at the wall (a plane
// behind it, as find_back_plane gives), not at the detections' box that passes through it.
TEST(ObjectSurface, AnUnseenBackStopsAtAPlaneBehindTheObject) {
  std::mt19937_64 rng(4);
  const OrientedBox truth = truth_box();
  const SurfaceParams params;
  OrientedBox detections = truth;
  detections.half_extents *= 1.15;
  detections.half_extents.x() *= 1.6;  // too deep along the views, as few views from one side give
  const DualQuadric q = DualQuadric::from_params(truth.centre, truth.rotation, 1.3 * truth.half_extents);
  const Eigen::Vector3d x_axis = truth.rotation.col(0);
  const std::vector<Eigen::Vector3d> one_side = facing(truth.centre, x_axis);
  const std::vector<Eigen::Vector3d> pts = scene_points(truth, one_side, 0.75, 0.002, rng);
  const SupportEstimate s = find_support(pts, q, params);
  ASSERT_TRUE(s.found);
  const std::vector<Eigen::Vector3d> own = object_points(pts, q, s, params);
  auto back_of = [&](const SurfaceBoxResult& r) {
    double lo = 1e9;
    for (const Eigen::Vector3d& c : box_corners(r.box)) lo = std::min(lo, x_axis.dot(c - truth.centre));
    return lo;
  };
  // The wall 5 mm behind the back face, its normal pointing away from the cameras (-x).
  BackPlane wall;
  wall.n = -x_axis;
  wall.d = wall.n.dot(truth.centre - (truth.half_extents.x() + 0.005) * x_axis);
  const SurfaceBoxResult held = fit_surface_box(own, detections, one_side, s, params, {wall, wall});
  ASSERT_TRUE(held.ok);
  EXPECT_EQ(held.faces_from_back_planes, 1);
  EXPECT_NEAR(back_of(held), -truth.half_extents.x() - 0.005, 0.005);
  EXPECT_GT(iou_3d(held.box, truth), 0.85);
  // Without it the back reaches as far as the detections' box.
  const SurfaceBoxResult free = fit_surface_box(own, detections, one_side, s, params);
  ASSERT_TRUE(free.ok);
  EXPECT_EQ(free.faces_from_back_planes, 0);
  EXPECT_LT(back_of(free), -1.5 * truth.half_extents.x());
  // A plane at 60° to the axis is no wall behind that face; one behind a face a camera saw does
  // not move it.
  BackPlane slanted = wall;
  slanted.n = Eigen::AngleAxisd(60.0 * kPi / 180.0, Eigen::Vector3d::UnitZ()) * wall.n;
  EXPECT_EQ(fit_surface_box(own, detections, one_side, s, params, {slanted}).faces_from_back_planes, 0);
  BackPlane in_front = wall;
  in_front.n = x_axis;
  in_front.d = in_front.n.dot(truth.centre + 0.5 * truth.half_extents.x() * x_axis);
  EXPECT_EQ(fit_surface_box(own, detections, one_side, s, params, {in_front}).faces_from_back_planes, 0);
}

// The wall behind an object, from the ring of depth around its box; nothing where the ring is no
// plane behind the box's content.
TEST(ObjectSurface, FindsTheWallBehindAnObject) {
  const PinholeCamera camera = test::test_camera();
  const SE3 T_wc = SE3::identity();
  const DualQuadric object = DualQuadric::from_params(Eigen::Vector3d(0.1, 0.0, 1.5), Eigen::Matrix3d::Identity(),
                                                      Eigen::Vector3d(0.2, 0.25, 0.15));
  const auto box = test::exact_box(object, camera, T_wc);
  ASSERT_TRUE(box);
  const SurfaceParams params;
  // A wall facing the camera 2.5 m away (render_depth's background depth).
  const DepthImage depth = test::render_depth({object}, camera, T_wc, 2.5f);
  const std::vector<Eigen::Vector3f> points = sample_box_points(*box, camera, test::view_of(depth), params);
  const std::optional<BackPlane> wall =
      find_back_plane(points, fit_ring_surface(ring_points(*box, camera, test::view_of(depth), params), params), params);
  ASSERT_TRUE(wall);
  EXPECT_NEAR(wall->n.z(), 1.0, 1e-6);
  EXPECT_NEAR(wall->d, 2.5, 1e-4);
  // No depth around the object (a window): no plane.
  const DepthImage open = test::render_depth({object}, camera, T_wc, 0.0f);
  EXPECT_FALSE(find_back_plane(sample_box_points(*box, camera, test::view_of(open), params),
                               fit_ring_surface(ring_points(*box, camera, test::view_of(open), params), params), params));
  // A box drawn on the wall itself (clutter): its content is the wall, not in front of it.
  const DepthImage bare = test::render_depth({}, camera, T_wc, 2.5f);
  const Box2d patch{250, 180, 330, 260};
  EXPECT_FALSE(find_back_plane(sample_box_points(patch, camera, test::view_of(bare), params),
                               fit_ring_surface(ring_points(patch, camera, test::view_of(bare), params), params), params));
}

// A pouf on the floor against a wall: its ring is two planes (no single one holds it), found with
// their normals; the pouf's content stands clearly out of both, a box on the bare corner does not,
// and a ring that two planes cannot explain (a third surface: a cabinet beside it) cannot tell.
TEST(ObjectSurface, TheRingOfABoxInAWallCornerIsTwoPlanes) {
  const PinholeCamera camera = test::test_camera(320, 240);
  const test::CornerScene corner;
  const DualQuadric &wall = corner.wall, &floor = corner.floor, &pouf = corner.pouf;
  const SE3 T_wc = test::look_at(Eigen::Vector3d(0.9, -0.5, 0.9), pouf.centre());
  const SE3 T_cw = T_wc.inverse();
  const auto box = test::exact_box(pouf, camera, T_wc);
  ASSERT_TRUE(box);
  const SurfaceParams params;
  auto judge = [&](const std::vector<DualQuadric>& scene, RingSurface* ring) {
    const DepthImage depth = test::render_depth(scene, camera, T_wc, 8.0f);
    *ring = fit_ring_surface(ring_points(*box, camera, test::view_of(depth), params), params);
    return stand_out_share(sample_box_points(*box, camera, test::view_of(depth), params), *ring, params);
  };
  RingSurface ring;
  const double pouf_share = judge({wall, floor, pouf}, &ring);
  ASSERT_EQ(ring.planes.size(), 2u);
  EXPECT_LT(ring.planes[0].inliers, params.ring_explained * ring.samples) << "no single plane holds the ring";
  EXPECT_GE(ring.planes[0].inliers + ring.planes[1].inliers, params.ring_explained * ring.samples);
  // The planes' normals in the world: the wall's x and the floor's z (either order).
  const Eigen::Vector3d n0 = T_wc.rotation() * ring.planes[0].n, n1 = T_wc.rotation() * ring.planes[1].n;
  EXPECT_GT(std::max(std::abs(n0.x()) * std::abs(n1.z()), std::abs(n0.z()) * std::abs(n1.x())), 0.999);
  // Each plane where it is: the wall's 1.49 m from the origin along x, the floor at z = 0.
  for (const RingPlane& p : ring.planes) {
    const Eigen::Vector3d n_w = T_wc.rotation() * p.n;
    const double d_w = p.d - p.n.dot(T_cw.translation());  // n_w·x_w = d_w
    if (std::abs(n_w.x()) > 0.99) {
      EXPECT_NEAR(std::abs(d_w), 1.49, 0.01);
    } else {
      EXPECT_NEAR(std::abs(n_w.z()), 1.0, 0.01);
      EXPECT_NEAR(std::abs(d_w), 0.0, 0.01);
    }
  }
  EXPECT_GE(pouf_share, 0.5);
  // The bare corner: the box's content is the wall and the floor.
  EXPECT_LT(judge({wall, floor}, &ring), params.min_stand_out);
  // Other surfaces beside the pouf (two cabinets' faces, a fifth of the ring): nothing to say.
  const DualQuadric left = DualQuadric::from_params(Eigen::Vector3d(-1.25, -0.46, 0.5), Eigen::Matrix3d::Identity(),
                                                    Eigen::Vector3d(0.3, 0.25, 0.5));
  const DualQuadric right = DualQuadric::from_params(Eigen::Vector3d(-1.25, 0.46, 0.5), Eigen::Matrix3d::Identity(),
                                                     Eigen::Vector3d(0.3, 0.25, 0.5));
  const double third = judge({wall, floor, pouf, left, right}, &ring);
  size_t explained = 0;
  for (const RingPlane& p : ring.planes) explained += p.inliers;
  EXPECT_LT(explained, params.ring_explained * ring.samples);
  EXPECT_TRUE(std::isnan(third));
}

// Recurring clutter on a table is a flat patch of it; a book lying on the table is not.
TEST(ObjectSurface, AFlatPatchOfTheTableIsNoObject) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n(0.0, 0.002);
  std::vector<Eigen::Vector3d> patch;
  for (double x = 0; x < 0.1; x += 0.005) {
    for (double y = 0; y < 0.08; y += 0.005) patch.push_back(Eigen::Vector3d(x, y, 0.75 + n(rng)));
  }
  const SurfaceParams params;
  EXPECT_TRUE(flat_patch(patch, params));
  OrientedBox book;
  book.centre = Eigen::Vector3d(0.05, 0.04, 0.77);
  book.half_extents = Eigen::Vector3d(0.1, 0.07, 0.02);
  const std::vector<Eigen::Vector3d> cams = ring(book.centre, 0.0, 2.0 * kPi, 6, 0.5);
  std::vector<Eigen::Vector3d> with_book = scene_points(book, cams, 0.75, 0.002, rng);
  EXPECT_FALSE(flat_patch(with_book, params));
  patch.resize(static_cast<size_t>(params.min_points - 1));
  EXPECT_FALSE(flat_patch(patch, params)) << "too few points say nothing";
}

// Views of an ellipsoid from a short arc with box noise: few views leave its tilt loosely held.
std::vector<BoxObservation> arc_views(const DualQuadric& truth, int n, double arc, double sigma_px, std::mt19937_64& rng) {
  const PinholeCamera cam = test::test_camera(640, 480);
  std::normal_distribution<double> noise(0.0, sigma_px);
  std::vector<BoxObservation> views;
  for (int i = 0; i < n; ++i) {
    const double a = arc * i / std::max(1, n - 1);
    const Eigen::Vector3d eye = truth.centre() + Eigen::Vector3d(1.5 * std::cos(a), 1.5 * std::sin(a), 0.6);
    BoxObservation v;
    v.P = cam.projection_matrix(test::look_at(eye, truth.centre()).inverse());
    v.width = cam.width;
    v.height = cam.height;
    v.box = *conic_bounding_box(project_quadric(truth, v.P));
    v.box.x_min += noise(rng);
    v.box.y_min += noise(rng);
    v.box.x_max += noise(rng);
    v.box.y_max += noise(rng);
    views.push_back(v);
  }
  return views;
}

double tilt_deg(const DualQuadric& q) {
  double best = 0.0;
  for (int j = 0; j < 3; ++j) best = std::max(best, std::abs(q.rotation()(2, j)));
  return std::acos(std::min(1.0, best)) * 180.0 / kPi;
}

TEST(RefinementPriors, HoldAnUprightObjectUprightAndLetManyViewsTiltATiltedOne) {
  const DualQuadric upright = DualQuadric::from_params(Eigen::Vector3d(0, 0, 0.9), Eigen::Matrix3d::Identity(),
                                                       Eigen::Vector3d(0.15, 0.1, 0.15));
  const double support_z = 0.75;
  RefinementPriors priors;
  priors.upright = true;
  priors.on_support = true;
  priors.support_z = support_z;
  int tilted_without = 0;
  double mean_without = 0.0, mean_with = 0.0;
  for (int seed = 0; seed < 8; ++seed) {
    std::mt19937_64 rng(100 + seed);
    const std::vector<BoxObservation> views = arc_views(upright, 4, 0.5, 3.0, rng);
    // Start tilted by 15° (a box-plane fit from a short baseline).
    const Eigen::Matrix3d tilt = Eigen::AngleAxisd(15.0 * kPi / 180.0, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
    const DualQuadric start = DualQuadric::from_params(upright.centre() + Eigen::Vector3d(0, 0, 0.03), tilt,
                                                       upright.semi_axes());
    const RefinementResult without = refine_quadric(start, views);
    const RefinementResult with = refine_quadric(start, views, RefinementParams(), priors);
    ASSERT_TRUE(without.ok && with.ok) << without.error << with.error;
    mean_without += tilt_deg(without.quadric) / 8;
    mean_with += tilt_deg(with.quadric) / 8;
    tilted_without += tilt_deg(without.quadric) > 5.0;
    EXPECT_LT(tilt_deg(with.quadric), 5.0) << "seed " << seed;
    const double bottom = with.quadric.centre().z() -
                          std::sqrt((with.quadric.rotation().row(2).array().square() *
                                     with.quadric.semi_axes().array().square().transpose()).sum());
    EXPECT_NEAR(bottom, support_z, 0.02) << "seed " << seed;
  }
  EXPECT_GT(tilted_without, 0) << "the views alone leave the tilt (mean " << mean_without << "°)";
  EXPECT_LT(mean_with, 0.5 * mean_without);

  // A truly tilted object (30°) seen all round: the views overcome the upright prior.
  const DualQuadric tilted = DualQuadric::from_params(
      Eigen::Vector3d(0, 0, 0.9), Eigen::AngleAxisd(30.0 * kPi / 180.0, Eigen::Vector3d::UnitX()).toRotationMatrix(),
      Eigen::Vector3d(0.25, 0.04, 0.15));
  std::mt19937_64 rng(7);
  const std::vector<BoxObservation> views = arc_views(tilted, 24, 2.0 * kPi * 23 / 24, 1.0, rng);
  RefinementPriors upright_only;
  upright_only.upright = true;
  const RefinementResult r = refine_quadric(tilted, views, RefinementParams(), upright_only);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_GT(tilt_deg(r.quadric), 20.0);
}

}  // namespace
}  // namespace dqo::objects
