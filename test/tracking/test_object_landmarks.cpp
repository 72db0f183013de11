// Objects as landmarks (issue 25, item 1): the box cost against the geometry library's projection
// (an independent computation), its derivatives against central differences, and local BA where a
// keyframe pushed off the truth is pulled back by confirmed objects, but not by objects the store
// must refuse (unconfirmed, low confidence, too few views, the wrong ID).
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "dqo_map/geometry/conic.h"
#include "dqo_map/tracking/object_landmarks.h"
#include "dqo_map/tracking/tracker.h"
#include "local_ba.h"
#include "object_box_cost.h"
#include "object_factors.h"

namespace {

using dqo::Box2d;
using dqo::DualQuadric;
using dqo::PinholeCamera;
using dqo::SE3;
using namespace dqo::tracking;

PinholeCamera test_camera() { return PinholeCamera{525.0, 525.0, 319.5, 239.5, 640, 480}; }

SE3 pose(const Eigen::Vector3d& axis_angle, const Eigen::Vector3d& t) {
  const double a = axis_angle.norm();
  const Eigen::Quaterniond q =
      a > 0.0 ? Eigen::Quaterniond(Eigen::AngleAxisd(a, axis_angle / a)) : Eigen::Quaterniond::Identity();
  return SE3(q, t);
}

// The box through the geometry library: C* = P Q* Pᵀ with P = K [R_fw | t_fw], conic.h's box.
Box2d reference_box(const DualQuadric& q, const PinholeCamera& camera, const SE3& T_fw) {
  Eigen::Matrix3d K;
  K << camera.fx, 0.0, camera.cx, 0.0, camera.fy, camera.cy, 0.0, 0.0, 1.0;
  Eigen::Matrix<double, 3, 4> Rt;
  Rt.leftCols<3>() = T_fw.rotation();
  Rt.col(3) = T_fw.translation();
  const auto box = dqo::conic_bounding_box(dqo::project_quadric(q, K * Rt));
  EXPECT_TRUE(box.has_value());
  return box ? *box : Box2d{};
}

std::vector<DualQuadric> scene_objects() {
  std::vector<DualQuadric> out;
  const Eigen::Vector3d centres[4] = {{-0.55, -0.35, 2.2}, {0.6, -0.3, 2.4}, {-0.5, 0.4, 2.0}, {0.5, 0.35, 2.3}};
  for (int i = 0; i < 4; ++i) {
    const Eigen::Matrix3d R = pose(Eigen::Vector3d(0.1 * i, 0.3, -0.2 * i), Eigen::Vector3d::Zero()).rotation();
    out.push_back(DualQuadric::from_params(centres[i], R, Eigen::Vector3d(0.16, 0.1, 0.12 + 0.02 * i)));
  }
  return out;
}

TEST(ObjectBoxCost, MatchesTheProjectedConicsBox) {
  const PinholeCamera camera = test_camera();
  const std::vector<DualQuadric> objects = scene_objects();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int checked = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const SE3 T_wk = pose(Eigen::Vector3d(0.1 * u(rng), 0.1 * u(rng), 0.1 * u(rng)),
                          Eigen::Vector3d(0.2 * u(rng), 0.2 * u(rng), 0.2 * u(rng)));
    const SE3 T_kf = pose(Eigen::Vector3d(0.05 * u(rng), 0.05 * u(rng), 0.0),
                          Eigen::Vector3d(0.05 * u(rng), 0.0, 0.05 * u(rng)));
    const DualQuadric& q = objects[trial % objects.size()];
    const SE3 T_fw = T_kf.inverse() * T_wk.inverse();
    const Box2d expected = reference_box(q, camera, T_fw);
    const Box2d detection{100.0, 80.0, 220.0, 190.0};
    const double scale = 0.37;
    const std::array<bool, 4> use{{true, true, false, true}};
    const ObjectBoxCost cost(Intrinsics(camera), T_kf.inverse(), q.centre(),
                             q.rotation() * q.semi_axes().asDiagonal(), detection, use, scale);
    const SE3 T_kw = T_wk.inverse();
    const Eigen::Vector4d q_cw = T_kw.quaternion().coeffs();
    const Eigen::Vector3d t_cw = T_kw.translation();
    double r[4];
    ASSERT_TRUE(cost(q_cw.data(), t_cw.data(), r));
    EXPECT_NEAR(r[0], (expected.x_min - detection.x_min) * scale, 1e-6);
    EXPECT_NEAR(r[1], (expected.y_min - detection.y_min) * scale, 1e-6);
    EXPECT_EQ(r[2], 0.0);  // an edge at the border: no measurement
    EXPECT_NEAR(r[3], (expected.y_max - detection.y_max) * scale, 1e-6);
    ++checked;
  }
  EXPECT_EQ(checked, 40);
}

TEST(ObjectBoxCost, RefusesAnObjectBehindOrAroundTheCamera) {
  const PinholeCamera camera = test_camera();
  const DualQuadric q = scene_objects()[0];
  const ObjectBoxCost cost(Intrinsics(camera), SE3(), q.centre(),
                           q.rotation() * q.semi_axes().asDiagonal(), Box2d{0, 0, 10, 10},
                           {{true, true, true, true}}, 1.0);
  double r[4];
  // Turned around (the object behind), and standing inside it.
  const SE3 behind = pose(Eigen::Vector3d(0.0, M_PI, 0.0), Eigen::Vector3d::Zero()).inverse();
  const SE3 inside = SE3(Eigen::Quaterniond::Identity(), q.centre()).inverse();
  for (const SE3& T_kw : {behind, inside}) {
    const Eigen::Vector4d q_cw = T_kw.quaternion().coeffs();
    const Eigen::Vector3d t_cw = T_kw.translation();
    EXPECT_FALSE(cost(q_cw.data(), t_cw.data(), r));
  }
}

TEST(ObjectBoxCost, DerivativesMatchCentralDifferences) {
  const PinholeCamera camera = test_camera();
  const std::vector<DualQuadric> objects = scene_objects();
  for (size_t i = 0; i < objects.size(); ++i) {
    const DualQuadric& q = objects[i];
    const SE3 T_kf = pose(Eigen::Vector3d(0.0, 0.03, 0.01), Eigen::Vector3d(0.02, -0.01, 0.0));
    const std::unique_ptr<ceres::CostFunction> cost(ObjectBoxCost::Create(
        Intrinsics(camera), T_kf.inverse(), q.centre(), q.rotation() * q.semi_axes().asDiagonal(),
        Box2d{100.0, 80.0, 220.0, 190.0}, {{true, true, true, true}}, 0.2));
    const SE3 T_kw = pose(Eigen::Vector3d(0.02, -0.05, 0.03), Eigen::Vector3d(0.1, 0.05, -0.1));
    double params[7];
    for (int k = 0; k < 4; ++k) params[k] = T_kw.quaternion().coeffs()[k];
    for (int k = 0; k < 3; ++k) params[4 + k] = T_kw.translation()[k];
    const double* blocks[2] = {params, params + 4};
    double r[4], J_q[16], J_t[12];
    double* jacobians[2] = {J_q, J_t};
    ASSERT_TRUE(cost->Evaluate(blocks, r, jacobians));
    const double h = 1e-6;
    for (int p = 0; p < 7; ++p) {
      double plus[7], minus[7];
      std::copy(params, params + 7, plus);
      std::copy(params, params + 7, minus);
      plus[p] += h;
      minus[p] -= h;
      double r_plus[4], r_minus[4];
      const double* bp[2] = {plus, plus + 4};
      const double* bm[2] = {minus, minus + 4};
      ASSERT_TRUE(cost->Evaluate(bp, r_plus, nullptr));
      ASSERT_TRUE(cost->Evaluate(bm, r_minus, nullptr));
      for (int e = 0; e < 4; ++e) {
        const double numeric = (r_plus[e] - r_minus[e]) / (2.0 * h);
        const double analytic = p < 4 ? J_q[e * 4 + p] : J_t[e * 3 + (p - 4)];
        EXPECT_NEAR(analytic, numeric, 1e-4 * std::max(1.0, std::abs(numeric)))
            << "object " << i << " parameter " << p << " edge " << e;
      }
    }
  }
}

// Two keyframes: 0 fixed at the origin, 1 free, tied to 0 only by a weak odometry that says it is
// 3 cm and 1.5 degrees off its true pose. Keyframe 1's registered frame (offset from it) saw four
// objects; the problem's points are seen by keyframe 0 alone (bundle adjustment needs some).
struct Scene {
  PinholeCamera camera = test_camera();
  SE3 T_w1_true = pose(Eigen::Vector3d(0.0, 0.05, 0.0), Eigen::Vector3d(0.1, 0.0, 0.0));
  SE3 T_w1_off = T_w1_true * pose(Eigen::Vector3d(0.0, 0.0, 0.026), Eigen::Vector3d(0.03, -0.01, 0.0));
  SE3 T_kf = pose(Eigen::Vector3d(0.0, 0.02, 0.0), Eigen::Vector3d(0.02, 0.0, 0.01));  // frame in kf 1
  std::vector<DualQuadric> objects = scene_objects();
  std::vector<ObjectLandmark> landmarks;
  std::vector<ObjectSighting> sightings;
  LocalBaProblem problem;

  Scene() {
    for (size_t i = 0; i < objects.size(); ++i) {
      ObjectLandmark l;
      l.id = 10 + i;
      l.quadric = objects[i];
      l.confirmed = true;
      l.confidence = 0.9;
      l.observations = 8;
      landmarks.push_back(l);
      sightings.push_back({l.id, reference_box(objects[i], camera, (T_w1_true * T_kf).inverse()), 0.8});
    }
    problem.keyframes.push_back({1, SE3(), true});
    problem.keyframes.push_back({2, T_w1_off, false});
    for (int i = 0; i < 6; ++i) {
      const Eigen::Vector3d p(-0.3 + 0.12 * i, 0.05 * i - 0.1, 2.0);
      problem.points.push_back({static_cast<uint64_t>(100 + i), p});
      BaObservation o;
      o.keyframe = 0;
      o.point = i;
      o.uv = camera.project(p);
      o.depth = p.z();
      problem.observations.push_back(o);
    }
    BaOdometry odometry;
    odometry.from = 0;
    odometry.to = 1;
    odometry.T_from_to = T_w1_off;
    odometry.information.diagonal() << 4.0, 4.0, 4.0, 10.0, 10.0, 10.0;  // σ 0.5 m, 0.3 rad
    problem.odometry.push_back(odometry);
  }

  // Files the sightings under keyframe 2 and solves; returns keyframe 2's translation error.
  double solve(const ObjectLandmarkStore& store, size_t* used) {
    ObjectLandmarkParams params;
    params.box_sigma_px = 2.0;
    LocalBaProblem p = problem;
    store.observations(2, 1, T_w1_off, camera, params, &p.objects);
    *used = p.objects.size();
    const LocalBaResult r = solve_local_ba(p, camera, LocalBaParams{}, PoseOptimiserParams{}, nullptr);
    EXPECT_TRUE(r.ok);
    for (const auto& [id, T_wc] : r.keyframes)
      if (id == 2) return (T_wc.translation() - T_w1_true.translation()).norm();
    ADD_FAILURE() << "keyframe 2 not in the result";
    return 1e9;
  }
};

TEST(ObjectLandmarks, ConfirmedObjectsPullAKeyframeBackToTheTruth) {
  Scene s;
  ObjectLandmarkStore store;
  store.set_landmarks(s.landmarks);
  store.add_sightings(2, s.T_kf, s.sightings);
  size_t used = 0;
  const double error = s.solve(store, &used);
  EXPECT_EQ(used, 4u);
  const double before = (s.T_w1_off.translation() - s.T_w1_true.translation()).norm();
  EXPECT_GT(before, 0.03);
  EXPECT_LT(error, 0.002) << "from " << before;
}

TEST(ObjectLandmarks, WithoutObjectsTheKeyframeStaysWhereTheOdometrySays) {
  Scene s;
  ObjectLandmarkStore store;
  size_t used = 0;
  const double error = s.solve(store, &used);
  EXPECT_EQ(used, 0u);
  EXPECT_GT(error, 0.03);
}

TEST(ObjectLandmarks, UnconfirmedUncertainOrRarelySeenObjectsDoNotPull) {
  for (int variant = 0; variant < 3; ++variant) {
    Scene s;
    for (ObjectLandmark& l : s.landmarks) {
      if (variant == 0) l.confirmed = false;
      if (variant == 1) l.confidence = 0.2;  // below min_confidence
      if (variant == 2) l.observations = 2;  // below min_observations
    }
    ObjectLandmarkStore store;
    store.set_landmarks(s.landmarks);
    store.add_sightings(2, s.T_kf, s.sightings);
    size_t used = 0;
    EXPECT_GT(s.solve(store, &used), 0.03) << "variant " << variant;
    EXPECT_EQ(used, 0u) << "variant " << variant;
  }
}

TEST(ObjectLandmarks, WrongIdsDoNotPull) {
  Scene s;
  // Each detection associated with the next object (elsewhere in the image), and one with an ID
  // the object stage no longer has (merged away).
  for (size_t i = 0; i < s.sightings.size(); ++i)
    s.sightings[i].object_id = 10 + (i + 1) % s.objects.size();
  s.sightings.push_back({99, s.sightings[0].box, 0.9});
  ObjectLandmarkStore store;
  store.set_landmarks(s.landmarks);
  store.add_sightings(2, s.T_kf, s.sightings);
  size_t used = 0;
  EXPECT_GT(s.solve(store, &used), 0.03);
  EXPECT_EQ(used, 0u);
}

TEST(ObjectLandmarks, TheNewestObjectSetWins) {
  Scene s;
  ObjectLandmarkStore store;
  store.set_landmarks(s.landmarks);
  store.add_sightings(2, s.T_kf, s.sightings);
  // A later version drops two objects (removed by the object stage): their sightings go unused.
  std::vector<ObjectLandmark> newer(s.landmarks.begin(), s.landmarks.begin() + 2);
  store.set_landmarks(newer);
  size_t used = 0;
  s.solve(store, &used);
  EXPECT_EQ(used, 2u);
  EXPECT_EQ(store.num_landmarks(), 2u);
  store.clear();
  EXPECT_EQ(store.num_landmarks(), 0u);
  EXPECT_EQ(store.num_sightings(), 0u);
}

TEST(ObjectLandmarks, TheTrackerKeepsTheNewestSetAndForgetsItOnReset) {
  Scene s;
  Tracker tracker(s.camera, TrackerParams{});
  tracker.set_object_landmarks(s.landmarks);
  EXPECT_EQ(tracker.num_object_landmarks(), 4u);
  tracker.set_object_landmarks({s.landmarks[0]});
  EXPECT_EQ(tracker.num_object_landmarks(), 1u);
  // No frame registered under 5: nothing to file the sightings under, and nothing breaks.
  tracker.add_object_sightings(5, s.sightings);
  EXPECT_EQ(tracker.object_costs_applied(), 0u);
  tracker.reset();  // the objects belong to the old map's world
  EXPECT_EQ(tracker.num_object_landmarks(), 0u);
}

}  // namespace
