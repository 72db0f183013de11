// Object pose metrics: the matching against a brute-force optimum, the admissibility rules (class,
// radius), counts, and the IoUs and CDE against hand computations.
#include "dqo_map/eval/object_metrics.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <numeric>
#include <random>
#include <tuple>

#include <gtest/gtest.h>

namespace {

using dqo::OrientedBox;
using dqo::PinholeCamera;
using dqo::SE3;
using dqo::eval::evaluate_objects;
using dqo::eval::EvalView;
using dqo::eval::ObjectEstimate;
using dqo::eval::ObjectMetrics;
using dqo::eval::Projection2d;

ObjectEstimate object(uint64_t id, int class_id, const Eigen::Vector3d& centre,
                      const Eigen::Vector3d& half_extents,
                      const Eigen::Matrix3d& rotation = Eigen::Matrix3d::Identity()) {
  ObjectEstimate o;
  o.id = id;
  o.class_id = class_id;
  o.box.centre = centre;
  o.box.rotation = rotation;
  o.box.half_extents = half_extents;
  return o;
}

std::map<uint64_t, uint64_t> gt_of_est(const ObjectMetrics& m) {
  std::map<uint64_t, uint64_t> pairs;
  for (const auto& match : m.matches) pairs[match.est_id] = match.gt_id;
  return pairs;
}

// Independent optimum: every partial one-to-one assignment of admissible pairs, enumerated
// recursively; the best has the most pairs, then the least total distance.
struct Best {
  int count = -1;
  double total = 0.0;
  std::map<uint64_t, uint64_t> pairs;
};

void enumerate(const std::vector<ObjectEstimate>& est, const std::vector<ObjectEstimate>& gt,
               size_t i, std::vector<bool>& gt_used, std::map<uint64_t, uint64_t>& pairs,
               double total, Best* best) {
  if (i == est.size()) {
    const int count = static_cast<int>(pairs.size());
    if (count > best->count || (count == best->count && total < best->total - 1e-12)) {
      *best = {count, total, pairs};
    }
    return;
  }
  enumerate(est, gt, i + 1, gt_used, pairs, total, best);  // estimate i left unmatched
  for (size_t j = 0; j < gt.size(); ++j) {
    const double d = (est[i].box.centre - gt[j].box.centre).norm();
    if (gt_used[j] || est[i].class_id != gt[j].class_id || d > gt[j].box.half_extents.maxCoeff()) {
      continue;
    }
    gt_used[j] = true;
    pairs[est[i].id] = gt[j].id;
    enumerate(est, gt, i + 1, gt_used, pairs, total + d, best);
    pairs.erase(est[i].id);
    gt_used[j] = false;
  }
}

Best brute_force(const std::vector<ObjectEstimate>& est, const std::vector<ObjectEstimate>& gt) {
  Best best;
  std::vector<bool> used(gt.size(), false);
  std::map<uint64_t, uint64_t> pairs;
  enumerate(est, gt, 0, used, pairs, 0.0, &best);
  return best;
}

// Taking admissible pairs nearest first: what the exact assignment must beat where it can.
Best nearest_first(const std::vector<ObjectEstimate>& est, const std::vector<ObjectEstimate>& gt) {
  std::vector<std::tuple<double, size_t, size_t>> pairs;
  for (size_t i = 0; i < est.size(); ++i) {
    for (size_t j = 0; j < gt.size(); ++j) {
      const double d = (est[i].box.centre - gt[j].box.centre).norm();
      if (est[i].class_id == gt[j].class_id && d <= gt[j].box.half_extents.maxCoeff()) {
        pairs.emplace_back(d, i, j);
      }
    }
  }
  std::sort(pairs.begin(), pairs.end());
  Best greedy;
  greedy.count = 0;
  std::vector<bool> est_used(est.size(), false), gt_used(gt.size(), false);
  for (const auto& [d, i, j] : pairs) {
    if (est_used[i] || gt_used[j]) continue;
    est_used[i] = gt_used[j] = true;
    ++greedy.count;
    greedy.total += d;
  }
  return greedy;
}

TEST(ObjectMetrics, MatchingIsTheBruteForceOptimumUnderPermutation) {
  std::mt19937_64 rng(17);
  // Dense enough that estimates compete for ground truth (several admissible pairs each).
  std::uniform_real_distribution<double> pos(-0.4, 0.4), size(0.2, 0.6);
  std::uniform_int_distribution<int> cls(0, 1), count(0, 6);
  int total_matches = 0, contested = 0, greedy_worse = 0;
  for (int trial = 0; trial < 300; ++trial) {
    std::vector<ObjectEstimate> gt, est;
    const int n_gt = count(rng), n_est = count(rng);
    for (int j = 0; j < n_gt; ++j) {
      gt.push_back(
          object(100 + j, cls(rng), {pos(rng), pos(rng), 0.0}, {size(rng), size(rng), size(rng)}));
    }
    for (int i = 0; i < n_est; ++i) {
      est.push_back(
          object(i + 1, cls(rng), {pos(rng), pos(rng), 0.0}, {size(rng), size(rng), size(rng)}));
    }
    const Best best = brute_force(est, gt);
    for (const auto& e : est) {
      int admissible = 0;
      for (const auto& g : gt) {
        admissible += e.class_id == g.class_id &&
                      (e.box.centre - g.box.centre).norm() <= g.box.half_extents.maxCoeff();
      }
      contested += admissible >= 2;
    }
    const Best greedy = nearest_first(est, gt);
    greedy_worse += greedy.count < best.count || greedy.total > best.total + 1e-12;
    const ObjectMetrics m = evaluate_objects(est, gt);
    ASSERT_EQ(m.num_matched, best.count) << "trial " << trial;
    double total = 0.0;
    for (const auto& match : m.matches) total += match.centre_distance;
    EXPECT_NEAR(total, best.total, 1e-9) << "trial " << trial;
    EXPECT_EQ(m.num_spurious, n_est - best.count);
    EXPECT_EQ(static_cast<int>(m.unmatched_gt.size()), n_gt - best.count);
    total_matches += m.num_matched;

    // The inputs' order changes nothing (ties aside, which random reals do not have).
    std::shuffle(est.begin(), est.end(), rng);
    std::shuffle(gt.begin(), gt.end(), rng);
    EXPECT_EQ(gt_of_est(evaluate_objects(est, gt)), gt_of_est(m)) << "trial " << trial;
  }
  // The trials exercise matching with choices, not just empty or obvious sets.
  EXPECT_GT(total_matches, 300);
  EXPECT_GT(contested, 150);
  EXPECT_GT(greedy_worse, 10);  // trials where taking the nearest pair first is not optimal
  std::printf(
      "%d matches, %d estimates with several admissible partners, %d trials where "
      "nearest-first is worse\n",
      total_matches, contested, greedy_worse);
}

TEST(ObjectMetrics, MatchingPrefersMoreMatchesToTheNearestPair) {
  // Estimate 1 is nearest to B but may also take A; estimate 2 may only take B. Taking the nearest
  // pair first (1-B) would leave 2 unmatched.
  const std::vector<ObjectEstimate> gt = {object(10, 0, {0, 0, 0}, {1.2, 0.3, 0.3}),
                                          object(11, 0, {1.5, 0, 0}, {0.6, 0.3, 0.3})};
  const std::vector<ObjectEstimate> est = {object(1, 0, {1.1, 0, 0}, {0.5, 0.3, 0.3}),
                                           object(2, 0, {2.0, 0, 0}, {0.5, 0.3, 0.3})};
  const ObjectMetrics m = evaluate_objects(est, gt);
  EXPECT_EQ(m.num_matched, 2);
  EXPECT_EQ(gt_of_est(m), (std::map<uint64_t, uint64_t>{{1, 10}, {2, 11}}));
  EXPECT_EQ(m.num_spurious, 0);
}

TEST(ObjectMetrics, ClassMismatchNeverMatches) {
  const std::vector<ObjectEstimate> gt = {object(5, 3, {0, 0, 1}, {0.2, 0.3, 0.4})};
  const std::vector<ObjectEstimate> est = {object(8, 4, {0, 0, 1}, {0.2, 0.3, 0.4})};
  const ObjectMetrics m = evaluate_objects(est, gt);
  EXPECT_EQ(m.num_matched, 0);
  EXPECT_EQ(m.num_gt, 1);
  EXPECT_EQ(m.unmatched_gt, std::vector<uint64_t>{5});
  EXPECT_EQ(m.spurious, std::vector<uint64_t>{8});
  EXPECT_EQ(m.num_spurious, 1);
  EXPECT_EQ(m.mean_iou_3d, 0.0);
  EXPECT_TRUE(std::isnan(m.mean_cde));
}

TEST(ObjectMetrics, CentreMustLieWithinHalfTheLargestExtent) {
  // Largest full extent 0.6 m: admissible radius 0.3 m, in any direction (not per axis).
  const Eigen::Vector3d half(0.1, 0.3, 0.2);
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.3, 1.0, -0.2).normalized()).toRotationMatrix();
  const std::vector<ObjectEstimate> gt = {object(1, 0, {1, 2, 3}, half, R)};
  const Eigen::Vector3d direction = Eigen::Vector3d(1, 1, 0).normalized();
  for (const double d : {0.0, 0.1, 0.29, 0.31, 0.5, 3.0}) {
    const std::vector<ObjectEstimate> est = {
        object(2, 0, Eigen::Vector3d(1, 2, 3) + d * direction, half, R)};
    const ObjectMetrics m = evaluate_objects(est, gt);
    EXPECT_EQ(m.num_matched, d <= 0.3 ? 1 : 0) << "distance " << d;
    EXPECT_EQ(m.num_spurious, d <= 0.3 ? 0 : 1) << "distance " << d;
    if (m.num_matched == 1) {
      EXPECT_NEAR(m.matches[0].centre_distance, d, 1e-12);
    }
  }
}

TEST(ObjectMetrics, IouAndCdeOfShiftedBoxes) {
  // Same box shifted by s along its first axis (full extent 2 h): overlap (2h − s) of (2h + s).
  const double h = 0.25, s = 0.1;
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Vector3d c(0.5, -0.2, 1.0);
  const std::vector<ObjectEstimate> gt = {object(1, 2, c, {h, 0.1, 0.2}, R),
                                          object(2, 2, {5, 5, 5}, {0.3, 0.3, 0.3})};
  const std::vector<ObjectEstimate> est = {
      object(7, 2, c + s * R.col(0), {h, 0.1, 0.2}, R),
      object(9, 2, {5, 5, 5}, {0.3, 0.3, 0.3}),  // identical to ground truth 2
      object(11, 1, {-4, 0, 0}, {0.3, 0.3, 0.3})};
  const ObjectMetrics m = evaluate_objects(est, gt);
  ASSERT_EQ(m.num_matched, 2);
  EXPECT_EQ(m.num_spurious, 1);
  EXPECT_EQ(m.spurious, std::vector<uint64_t>{11});
  EXPECT_TRUE(m.unmatched_gt.empty());
  const double expected = (2 * h - s) / (2 * h + s);
  EXPECT_EQ(m.matches[0].est_id, 7u);
  EXPECT_NEAR(m.matches[0].iou_3d, expected, 1e-9);
  EXPECT_NEAR(m.matches[0].centre_distance, s, 1e-12);
  EXPECT_EQ(m.matches[1].est_id, 9u);
  EXPECT_NEAR(m.matches[1].iou_3d, 1.0, 1e-12);
  EXPECT_EQ(m.matches[1].centre_distance, 0.0);
  EXPECT_NEAR(m.mean_iou_3d, (expected + 1.0) / 2.0, 1e-9);
  EXPECT_NEAR(m.mean_cde, s / 2.0, 1e-12);
  // No views: no 2D IoU.
  EXPECT_TRUE(std::isnan(m.mean_iou_2d));
  EXPECT_EQ(m.matches[0].views_2d, 0);
}

TEST(ObjectMetrics, MeanIou3dCountsUnmatchedGroundTruthAsZero) {
  const std::vector<ObjectEstimate> gt = {
      object(1, 0, {0, 0, 0}, {0.2, 0.2, 0.2}), object(2, 0, {3, 0, 0}, {0.2, 0.2, 0.2}),
      object(3, 0, {6, 0, 0}, {0.2, 0.2, 0.2}), object(4, 0, {9, 0, 0}, {0.2, 0.2, 0.2})};
  const std::vector<ObjectEstimate> est = {gt[0], gt[2]};
  const ObjectMetrics m = evaluate_objects(est, gt);
  EXPECT_EQ(m.num_matched, 2);
  EXPECT_EQ(m.unmatched_gt, (std::vector<uint64_t>{2, 4}));
  EXPECT_NEAR(m.mean_iou_3d, 0.5, 1e-12);
  EXPECT_NEAR(m.mean_iou_3d_matched, 1.0, 1e-12);
  EXPECT_EQ(m.mean_cde, 0.0);
}

// Independent 2D IoU of axis-aligned boxes given as {x0, y0, x1, y1}.
double box_iou(const std::array<double, 4>& a, const std::array<double, 4>& b) {
  const double w = std::max(0.0, std::min(a[2], b[2]) - std::max(a[0], b[0]));
  const double hgt = std::max(0.0, std::min(a[3], b[3]) - std::max(a[1], b[1]));
  const double inter = w * hgt;
  const double area_a = (a[2] - a[0]) * (a[3] - a[1]), area_b = (b[2] - b[0]) * (b[3] - b[1]);
  return inter / (area_a + area_b - inter);
}

// The camera at the origin looking along world +z (T_wc = identity), so p_c = p_w.
EvalView front_view() {
  EvalView v;
  v.camera.fx = 500;
  v.camera.fy = 400;
  v.camera.cx = 320;
  v.camera.cy = 240;
  v.camera.width = 640;
  v.camera.height = 480;
  return v;
}

// Image box of an axis-aligned box's 8 corners, by hand: u = fx x / z + cx, v = fy y / z + cy.
std::array<double, 4> hand_projected(const EvalView& v, const Eigen::Vector3d& c,
                                     const Eigen::Vector3d& h) {
  std::array<double, 4> b = {1e9, 1e9, -1e9, -1e9};
  for (const double sx : {-1.0, 1.0}) {
    for (const double sy : {-1.0, 1.0}) {
      for (const double sz : {-1.0, 1.0}) {
        const double x = c.x() + sx * h.x(), y = c.y() + sy * h.y(), z = c.z() + sz * h.z();
        const double u = v.camera.fx * x / z + v.camera.cx, w = v.camera.fy * y / z + v.camera.cy;
        b = {std::min(b[0], u), std::min(b[1], w), std::max(b[2], u), std::max(b[3], w)};
      }
    }
  }
  return b;
}

TEST(ObjectMetrics, Iou2dMatchesHandProjectedCorners) {
  const EvalView view = front_view();
  const Eigen::Vector3d gc(0.1, -0.05, 2.0), gh(0.3, 0.2, 0.25);
  const Eigen::Vector3d ec(0.15, -0.02, 2.1), eh(0.28, 0.22, 0.2);
  const std::vector<ObjectEstimate> gt = {object(1, 0, gc, gh)};
  const std::vector<ObjectEstimate> est = {object(2, 0, ec, eh)};
  const ObjectMetrics m = evaluate_objects(est, gt, {view});
  ASSERT_EQ(m.num_matched, 1);
  EXPECT_EQ(m.matches[0].views_2d, 1);
  const auto g = hand_projected(view, gc, gh), e = hand_projected(view, ec, eh);
  // Both boxes lie inside the 640 x 480 image, so clipping changes nothing.
  ASSERT_GT(g[0], 0.0);
  ASSERT_LT(g[2], 640.0);
  const double expected = box_iou(g, e);
  EXPECT_GT(expected, 0.3);
  EXPECT_LT(expected, 0.95);
  EXPECT_NEAR(m.matches[0].iou_2d, expected, 1e-12);
  EXPECT_NEAR(m.mean_iou_2d, expected, 1e-12);
  EXPECT_EQ(m.num_gt_in_views, 1);

  // The same scene seen from a camera moved and turned: projecting world points through T_cw.
  EvalView moved = view;
  moved.T_wc = SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitY())),
                   Eigen::Vector3d(0.3, 0.1, -0.5));
  // A view behind the objects does not count.
  EvalView behind = view;
  behind.T_wc = SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 5));
  const ObjectMetrics m2 = evaluate_objects(est, gt, {view, behind});
  EXPECT_EQ(m2.matches[0].views_2d, 1);
  EXPECT_NEAR(m2.matches[0].iou_2d, expected, 1e-12);
  // Moving the camera and the objects together changes nothing.
  std::vector<ObjectEstimate> gt_moved = gt, est_moved = est;
  for (auto* o : {&gt_moved[0], &est_moved[0]}) {
    o->box.centre = moved.T_wc * o->box.centre;
    o->box.rotation = moved.T_wc.rotation() * o->box.rotation;
  }
  const ObjectMetrics m3 = evaluate_objects(est_moved, gt_moved, {moved});
  EXPECT_NEAR(m3.matches[0].iou_2d, expected, 1e-9);
}

TEST(ObjectMetrics, Iou2dClipsToTheImageAndAverages) {
  const EvalView view = front_view();
  // The ground truth reaches past the right border: only its part in the image counts.
  const Eigen::Vector3d gc(1.2, 0.0, 2.0), gh(0.3, 0.2, 0.1);
  const Eigen::Vector3d ec(1.25, 0.0, 2.0), eh(0.3, 0.2, 0.1);
  const auto clip = [](std::array<double, 4> b) {
    return std::array<double, 4>{std::max(b[0], 0.0), std::max(b[1], 0.0), std::min(b[2], 640.0),
                                 std::min(b[3], 480.0)};
  };
  const auto g = clip(hand_projected(view, gc, gh)), e = clip(hand_projected(view, ec, eh));
  ASSERT_LT(hand_projected(view, gc, gh)[0], 640.0);
  ASSERT_GT(hand_projected(view, gc, gh)[2], 640.0);
  const double in_view = box_iou(g, e);
  // A view turned away sees nothing and does not count; the same view twice averages to itself.
  EvalView away = view;
  away.T_wc = SE3(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY())),
                  Eigen::Vector3d::Zero());
  const ObjectMetrics m =
      evaluate_objects({object(2, 0, ec, eh)}, {object(1, 0, gc, gh)}, {view, away, view});
  ASSERT_EQ(m.num_matched, 1);
  EXPECT_EQ(m.matches[0].views_2d, 2);
  EXPECT_NEAR(m.matches[0].iou_2d, in_view, 1e-12);
}

TEST(ObjectMetrics, Iou2dOfEllipsoidsMatchesTheTangentCone) {
  // Spheres on the optical axis at depth z: the tangent cone has sin α = r / z, so the image box is
  // a square of half width f tan α = f r / sqrt(z² − r²) about the principal point (fx = fy here).
  EvalView view = front_view();
  view.camera.fy = view.camera.fx;
  const double z = 3.0, r_gt = 0.4, r_est = 0.3;
  const double half_gt = view.camera.fx * r_gt / std::sqrt(z * z - r_gt * r_gt);
  const double half_est = view.camera.fx * r_est / std::sqrt(z * z - r_est * r_est);
  const double expected = (half_est * half_est) / (half_gt * half_gt);
  dqo::eval::ObjectEvalParams params;
  params.projection = Projection2d::kEllipsoids;
  const ObjectMetrics m =
      evaluate_objects({object(2, 0, {0, 0, z}, Eigen::Vector3d::Constant(r_est))},
                       {object(1, 0, {0, 0, z}, Eigen::Vector3d::Constant(r_gt))}, {view}, params);
  ASSERT_EQ(m.num_matched, 1);
  EXPECT_EQ(m.matches[0].views_2d, 1);
  EXPECT_NEAR(m.matches[0].iou_2d, expected, 1e-9);
  // As boxes the same pair projects the cubes' corners: a different, larger-box answer.
  const ObjectMetrics boxes =
      evaluate_objects({object(2, 0, {0, 0, z}, Eigen::Vector3d::Constant(r_est))},
                       {object(1, 0, {0, 0, z}, Eigen::Vector3d::Constant(r_gt))}, {view});
  const double front_gt = view.camera.fx * r_gt / (z - r_gt);
  const double front_est = view.camera.fx * r_est / (z - r_est);
  EXPECT_NEAR(boxes.matches[0].iou_2d, (front_est * front_est) / (front_gt * front_gt), 1e-9);
}

TEST(ObjectMetrics, IdenticalSetsScorePerfectly) {
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> pos(-1.0, 1.0), size(0.05, 0.3), angle(-M_PI, M_PI);
  std::vector<ObjectEstimate> gt;
  for (int j = 0; j < 8; ++j) {
    const Eigen::Matrix3d R =
        Eigen::AngleAxisd(angle(rng), Eigen::Vector3d(pos(rng), pos(rng), 1.0).normalized())
            .toRotationMatrix();
    gt.push_back(object(j + 1, j % 3, {pos(rng), pos(rng), 3.0 + pos(rng)},
                        {size(rng), size(rng), size(rng)}, R));
  }
  for (const Projection2d p : {Projection2d::kBoxes, Projection2d::kEllipsoids}) {
    dqo::eval::ObjectEvalParams params;
    params.projection = p;
    const ObjectMetrics m = evaluate_objects(gt, gt, {front_view()}, params);
    EXPECT_EQ(m.num_matched, 8);
    EXPECT_EQ(m.num_spurious, 0);
    EXPECT_NEAR(m.mean_iou_3d, 1.0, 1e-9);
    EXPECT_NEAR(m.mean_iou_2d, 1.0, 1e-12);
    EXPECT_EQ(m.mean_cde, 0.0);
    EXPECT_GT(m.num_gt_in_views, 0);
  }
}

TEST(ObjectMetrics, EmptyInputs) {
  const ObjectMetrics none = evaluate_objects({}, {});
  EXPECT_EQ(none.num_gt, 0);
  EXPECT_EQ(none.num_matched, 0);
  EXPECT_EQ(none.mean_iou_3d, 0.0);
  const ObjectMetrics no_estimate =
      evaluate_objects({}, {object(1, 0, {0, 0, 2}, {0.1, 0.1, 0.1})}, {front_view()});
  EXPECT_EQ(no_estimate.unmatched_gt, std::vector<uint64_t>{1});
  EXPECT_EQ(no_estimate.num_gt_in_views, 1);
  EXPECT_EQ(no_estimate.mean_iou_2d, 0.0);  // seen, not matched: counts as 0
}

}  // namespace
