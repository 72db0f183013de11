// Loop closing: the pose-graph edge residual against an independent computation and finite
// differences, a pose graph that spreads a loop's error, and on a synthetic keyframe map (a camera
// turning once around a ring of landmarks, drifting as it goes) place recognition that finds the
// loop where the camera comes back, a correction that brings the drifted keyframes back, and no
// loop where the camera never returns.
#include <cmath>
#include <random>
#include <vector>

#include <ceres/cost_function.h>
#include <gtest/gtest.h>

#include "loop_closing.h"
#include "pose_graph.h"
#include "residuals.h"

namespace {

using dqo::PinholeCamera;
using dqo::SE3;
using dqo::Vector6d;
using namespace dqo::tracking;

SE3 random_pose(std::mt19937* rng, double t_scale, double r_scale) {
  std::normal_distribution<double> n(0.0, 1.0);
  Vector6d xi;
  xi << t_scale * n(*rng), t_scale * n(*rng), t_scale * n(*rng), r_scale * n(*rng),
      r_scale * n(*rng), r_scale * n(*rng);
  return SE3::exp(xi);
}

// ---------------------------------------------------------------- the edge cost

TEST(PoseGraph, EdgeResidualMatchesAnIndependentComputation) {
  std::mt19937 rng(3);
  for (int trial = 0; trial < 20; ++trial) {
    const SE3 T_wa = random_pose(&rng, 1.0, 1.0), T_wb = random_pose(&rng, 1.0, 1.0);
    PoseGraphEdge edge;
    edge.T_from_to = T_wa.inverse() * T_wb * random_pose(&rng, 0.05, 0.05);
    Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Random();
    edge.information = A * A.transpose() + Eigen::Matrix<double, 6, 6>::Identity();
    const Eigen::Matrix<double, 6, 1> r = pose_graph_residual(T_wa, T_wb, edge);
    // E = T̂⁻¹ T_wa⁻¹ T_wb; δ = [t_E; 2 vec(q_E)] with w ≥ 0; ‖r‖² = δᵀ Λ δ.
    const SE3 E = edge.T_from_to.inverse() * T_wa.inverse() * T_wb;
    Eigen::Quaterniond q = E.quaternion();
    if (q.w() < 0.0) q.coeffs() = -q.coeffs();
    Eigen::Matrix<double, 6, 1> delta;
    delta << E.translation(), 2.0 * q.vec();
    EXPECT_NEAR(r.squaredNorm(), delta.dot(edge.information * delta), 1e-9 * (1.0 + r.squaredNorm()));
    // Small errors: δ is the SE(3) logarithm's [ρ; φ] to first order (rotation part exactly
    // 2 vec(q) ≈ φ; translation ≈ ρ).
    const Vector6d log = E.log();
    EXPECT_NEAR(delta.tail<3>().norm(), log.tail<3>().norm(), 2e-3);
  }
  // At the measurement the residual is zero.
  const SE3 T_wa = random_pose(&rng, 1.0, 1.0), T_wb = random_pose(&rng, 1.0, 1.0);
  PoseGraphEdge exact;
  exact.T_from_to = T_wa.inverse() * T_wb;
  EXPECT_LT(pose_graph_residual(T_wa, T_wb, exact).norm(), 1e-12);
}

TEST(PoseGraph, EdgeJacobiansMatchFiniteDifferences) {
  std::mt19937 rng(5);
  const SE3 T_wa = random_pose(&rng, 1.0, 1.0), T_wb = random_pose(&rng, 1.0, 1.0);
  const SE3 T_ab = T_wa.inverse() * T_wb * random_pose(&rng, 0.1, 0.1);
  const Eigen::Matrix<double, 6, 6> S = sqrt_information(isotropic_information(0.01, 0.02, 2.0));
  std::unique_ptr<ceres::CostFunction> cost(OdometryCost::Create(T_ab, S));
  const SE3 T_aw = T_wa.inverse(), T_bw = T_wb.inverse();
  std::vector<std::vector<double>> blocks = {
      {T_aw.quaternion().x(), T_aw.quaternion().y(), T_aw.quaternion().z(), T_aw.quaternion().w()},
      {T_aw.translation().x(), T_aw.translation().y(), T_aw.translation().z()},
      {T_bw.quaternion().x(), T_bw.quaternion().y(), T_bw.quaternion().z(), T_bw.quaternion().w()},
      {T_bw.translation().x(), T_bw.translation().y(), T_bw.translation().z()}};
  auto evaluate = [&](std::vector<std::vector<double>>& b, double* r, double** jacobians) {
    std::vector<const double*> p;
    for (auto& v : b) p.push_back(v.data());
    return cost->Evaluate(p.data(), r, jacobians);
  };
  std::vector<std::vector<double>> J(4);
  std::vector<double*> J_ptr(4);
  for (size_t i = 0; i < 4; ++i) {
    J[i].resize(6 * blocks[i].size());
    J_ptr[i] = J[i].data();
  }
  double r[6];
  ASSERT_TRUE(evaluate(blocks, r, J_ptr.data()));
  const double h = 1e-6;
  for (size_t i = 0; i < 4; ++i) {
    const size_t n = blocks[i].size();
    for (size_t j = 0; j < n; ++j) {
      auto plus = blocks, minus = blocks;
      plus[i][j] += h;
      minus[i][j] -= h;
      double rp[6], rm[6];
      ASSERT_TRUE(evaluate(plus, rp, nullptr));
      ASSERT_TRUE(evaluate(minus, rm, nullptr));
      for (int k = 0; k < 6; ++k) {
        const double numeric = (rp[k] - rm[k]) / (2.0 * h);
        EXPECT_NEAR(J[i][k * n + j], numeric, 1e-4 * (1.0 + std::abs(numeric)))
            << "block " << i << " parameter " << j << " residual " << k;
      }
    }
  }
}

// A square of four poses: odometry edges with a drift, an exact loop edge back to the start.
TEST(PoseGraph, LoopEdgeSpreadsTheDrift) {
  std::vector<SE3> truth;
  for (int k = 0; k < 8; ++k) {
    const double a = 2.0 * M_PI * k / 8.0;
    truth.push_back(SE3(Eigen::Quaterniond(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ())),
                        Eigen::Vector3d(std::cos(a), std::sin(a), 0.0)));
  }
  Vector6d drift_xi;
  drift_xi << 0.03, -0.02, 0.01, 0.0, 0.0, 0.02;
  const SE3 drift = SE3::exp(drift_xi);  // per step
  std::vector<PoseGraphNode> nodes;
  std::vector<PoseGraphEdge> edges;
  SE3 T = truth[0];
  for (int k = 0; k < 8; ++k) {
    if (k > 0) {
      const SE3 step = truth[k - 1].inverse() * truth[k] * drift;
      T = T * step;
      edges.push_back({k - 1, k, step, isotropic_information(0.01, 0.01, 1.0)});
    }
    nodes.push_back({static_cast<uint64_t>(k + 1), T, k == 0});
  }
  edges.push_back({0, 7, truth[0].inverse() * truth[7], isotropic_information(0.01, 0.01, 1.0)});
  auto error = [&](const std::vector<SE3>& poses) {
    double sum = 0.0;
    for (int k = 0; k < 8; ++k) sum += (poses[k].translation() - truth[k].translation()).norm();
    return sum / 8.0;
  };
  std::vector<SE3> before;
  for (const auto& n : nodes) before.push_back(n.T_wc);
  const PoseGraphResult r = optimise_pose_graph(nodes, edges, 50);
  ASSERT_TRUE(r.ok);
  // Eight equal edges share the loop's error: about an eighth of the cost is left.
  EXPECT_LT(r.final_cost, 0.2 * r.initial_cost);
  EXPECT_TRUE(r.T_wc[0].translation().isApprox(truth[0].translation()));  // the fixed node
  EXPECT_GT(error(before), 0.05);
  EXPECT_LT(error(r.T_wc), 0.6 * error(before));
  // The last pose, tied to the first by the loop, lands near its truth.
  EXPECT_LT((r.T_wc[7].translation() - truth[7].translation()).norm(), 0.03);
}

// ---------------------------------------------------------------- a synthetic keyframe map

PinholeCamera camera() { return PinholeCamera{525.0, 525.0, 319.5, 239.5, 640, 480}; }

struct Landmark {
  Eigen::Vector3d p_w;
  Descriptor descriptor;
};

// Landmarks on a cylinder of radius 3 m around the z axis (a room's walls), each with its own
// random descriptor.
std::vector<Landmark> ring_of_landmarks(int n, std::mt19937* rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::uniform_int_distribution<uint64_t> bits;
  std::vector<Landmark> out(n);
  for (Landmark& l : out) {
    const double a = 2.0 * M_PI * u(*rng);
    const double r = 3.0 + 0.3 * u(*rng);
    l.p_w = Eigen::Vector3d(r * std::cos(a), r * std::sin(a), -1.0 + 2.0 * u(*rng));
    for (uint64_t& w : l.descriptor) w = bits(*rng);
  }
  return out;
}

// A camera at the origin's ring of radius 0.3 m looking outwards (optical axis z_c along the
// radius, y_c down) at yaw `a`.
SE3 looking_out(double a) {
  const Eigen::Vector3d z(std::cos(a), std::sin(a), 0.0);
  const Eigen::Vector3d y(0.0, 0.0, -1.0);
  const Eigen::Vector3d x = y.cross(z);
  Eigen::Matrix3d R;
  R << x, y, z;
  return SE3::from_rotation_translation(R, 0.3 * z);
}

struct SyntheticMap {
  MapStore map;
  std::vector<SE3> truth;  // per keyframe, in ID order (IDs 1..n)
};

// Keyframes at the given yaws. The tracker's estimate drifts: each step between keyframes is
// measured as the true step times `drift_per_keyframe`.
// A landmark seen again within `memory` keyframes of its map point's last sighting is matched to
// it (what tracking against the local map does); otherwise a new map point is made from this
// keyframe's (drifted) pose, as the tracker would when it comes back to a place it forgot.
SyntheticMap build_map(const std::vector<double>& yaws, const SE3& drift_per_keyframe, int memory,
                       uint64_t seed) {
  std::mt19937 rng(static_cast<unsigned>(seed));
  std::normal_distribution<double> n(0.0, 1.0);
  std::uniform_int_distribution<int> bit(0, 255);
  const std::vector<Landmark> landmarks = ring_of_landmarks(1500, &rng);
  const PinholeCamera cam = camera();
  const ScalePyramid scales(1.2f, 8);
  SyntheticMap out;
  std::vector<uint64_t> point_of(landmarks.size(), kNoId);
  std::vector<int> last_seen(landmarks.size(), -1000);
  SE3 T_est;
  for (size_t k = 0; k < yaws.size(); ++k) {
    const SE3 T_true = looking_out(yaws[k]);
    // Odometry: each step as measured, a little off.
    T_est = k == 0 ? T_true
                   : T_est * looking_out(yaws[k - 1]).inverse() * T_true * drift_per_keyframe;
    KeyFrame kf;
    kf.frame_number = k * 10;
    kf.T_wc = T_est;
    std::vector<int> seen;
    for (size_t i = 0; i < landmarks.size(); ++i) {
      const Eigen::Vector3d p_c = T_true.inverse() * landmarks[i].p_w;
      if (p_c.z() < 0.5) continue;
      const Eigen::Vector2d uv = cam.project(p_c) + 0.5 * Eigen::Vector2d(n(rng), n(rng));
      if (!cam.in_image(uv)) continue;
      Keypoint kp;
      kp.uv = uv.cast<float>();
      kp.depth = static_cast<float>(p_c.z() + 0.002 * p_c.z() * p_c.z() * n(rng));
      Descriptor d = landmarks[i].descriptor;
      for (int flip = 0; flip < 6; ++flip) {  // a few bits differ between views
        const int b = bit(rng);
        d[b / 64] ^= uint64_t{1} << (b % 64);
      }
      kf.features.keypoints.push_back(kp);
      kf.features.descriptors.push_back(d);
      seen.push_back(static_cast<int>(i));
    }
    kf.map_points.assign(kf.features.size(), kNoId);
    const uint64_t id = out.map.add_keyframe(std::move(kf));
    for (size_t j = 0; j < seen.size(); ++j) {
      const int i = seen[j];
      if (point_of[i] == kNoId || out.map.map_point(point_of[i]) == nullptr ||
          static_cast<int>(k) - last_seen[i] > memory) {
        MapPoint p;
        p.p_w = T_est * out.map.keyframe(id)->features.point_c(static_cast<int>(j), cam);
        p.descriptor = out.map.keyframe(id)->features.descriptors[j];
        p.first_keyframe = id;
        point_of[i] = out.map.add_map_point(p);
      }
      out.map.add_observation(point_of[i], id, static_cast<int>(j));
      last_seen[i] = static_cast<int>(k);
    }
    for (size_t j = 0; j < seen.size(); ++j) out.map.update_point_appearance(point_of[seen[j]], scales);
    out.map.update_covisibility(id);
    out.truth.push_back(T_true);
  }
  return out;
}

double mean_position_error(const SyntheticMap& m) {
  double sum = 0.0;
  for (size_t k = 0; k < m.truth.size(); ++k)
    sum += (m.map.keyframe(k + 1)->T_wc.translation() - m.truth[k].translation()).norm();
  return sum / static_cast<double>(m.truth.size());
}

SE3 drift_step() {
  Vector6d xi;
  xi << 0.006, 0.003, -0.004, 0.001, -0.001, 0.0015;  // 7.8 mm and 0.12° per keyframe
  return SE3::exp(xi);
}

// 25 keyframes turning once around, the last 24 at yaws 0..345° and the 25th back at 5°.
std::vector<double> full_turn() {
  std::vector<double> yaws;
  for (int k = 0; k < 24; ++k) yaws.push_back(2.0 * M_PI * k / 24.0);
  yaws.push_back(2.0 * M_PI * 5.0 / 360.0 + 2.0 * M_PI);
  return yaws;
}

TEST(LoopClosing, FindsTheLoopWhereTheCameraComesBackAndCorrectsTheDrift) {
  SyntheticMap m = build_map(full_turn(), drift_step(), 3, 11);
  const ScalePyramid scales(1.2f, 8);
  const LoopParams params;
  const uint64_t last = m.truth.size();
  // Not covisible with where it started: the loop is there to be found, not already closed.
  EXPECT_EQ(m.map.keyframe(last)->covisibility.count(1), 0u);
  const LoopDetection loop = detect_loop(m.map, last, camera(), scales, PoseOptimiserParams{}, params);
  ASSERT_TRUE(loop.found) << loop.candidates << " candidates, best " << loop.best_matches;
  EXPECT_LE(loop.match, 2u);  // the first keyframes (yaw 0 and 15°) see what the last sees
  EXPECT_GE(static_cast<int>(loop.matches.size()), params.min_inliers);
  // The verified pose is the truth in the first keyframe's world (keyframe 1 has no drift).
  EXPECT_LT((loop.T_wc_query.translation() - m.truth.back().translation()).norm(), 0.02);

  const double before = mean_position_error(m);
  const double last_before = (m.map.keyframe(last)->T_wc.translation() - m.truth.back().translation()).norm();
  const LoopCorrection c = correct_loop(&m.map, loop, 1, scales, params);
  ASSERT_TRUE(c.ok);
  EXPECT_GT(c.fused_points, 50);
  const double after = mean_position_error(m);
  const double last_after = (m.map.keyframe(last)->T_wc.translation() - m.truth.back().translation()).norm();
  // The pose graph spreads the loop's error over the turn (the bundle adjustment below removes
  // the rest): the query comes back, the others part of the way.
  EXPECT_GT(before, 0.05);
  EXPECT_LT(after, 0.75 * before) << "mean keyframe error " << before << " -> " << after;
  EXPECT_GT(last_before, 0.07);
  EXPECT_LT(last_after, 0.02) << last_before << " -> " << last_after;
  // Fused: the last keyframe now shares points with the first ones.
  EXPECT_TRUE(m.map.keyframe(last)->covisibility.count(loop.match) != 0);
  // Found again right after, nothing is left to close.
  EXPECT_FALSE(detect_loop(m.map, last, camera(), scales, PoseOptimiserParams{}, params).found);
}

TEST(LoopClosing, RankingInTwoStepsFindsTheSameLoop) {
  const SyntheticMap m = build_map(full_turn(), drift_step(), 3, 15);
  const ScalePyramid scales(1.2f, 8);
  const uint64_t last = m.truth.size();
  LoopParams all;
  all.sample_descriptors = 0;
  all.max_verify = 1;
  LoopParams sampled = all;
  sampled.sample_descriptors = 50;  // a shortlist of 4 of the candidates, from 50 descriptors
  const LoopDetection a = detect_loop(m.map, last, camera(), scales, PoseOptimiserParams{}, all);
  const LoopDetection b = detect_loop(m.map, last, camera(), scales, PoseOptimiserParams{}, sampled);
  ASSERT_GT(a.candidates, 4);
  ASSERT_TRUE(a.found);
  ASSERT_TRUE(b.found);
  EXPECT_EQ(a.match, b.match);
  EXPECT_EQ(a.best_matches, b.best_matches);
}

TEST(LoopClosing, GlobalBundleAdjustmentKeepsTheLoopClosed) {
  SyntheticMap m = build_map(full_turn(), drift_step(), 3, 12);
  const ScalePyramid scales(1.2f, 8);
  const LoopParams params;
  const uint64_t last = m.truth.size();
  const LoopDetection loop = detect_loop(m.map, last, camera(), scales, PoseOptimiserParams{}, params);
  ASSERT_TRUE(loop.found);
  const double drifted = mean_position_error(m);
  ASSERT_TRUE(correct_loop(&m.map, loop, 1, scales, params).ok);
  const double corrected = mean_position_error(m);
  const LocalBaProblem problem = global_ba_problem(m.map, 1, scales, PoseOptimiserParams{}, 1);
  EXPECT_EQ(problem.keyframes.size(), m.truth.size());
  EXPECT_EQ(problem.points.size(), m.map.num_map_points());
  LocalBaParams ba;
  ba.iterations = 10;
  const LocalBaResult r = solve_local_ba(problem, camera(), ba, PoseOptimiserParams{}, nullptr);
  ASSERT_TRUE(r.ok);
  for (const auto& [id, T_wc] : r.keyframes) m.map.keyframe(id)->T_wc = T_wc;
  const double adjusted = mean_position_error(m);
  EXPECT_LT(adjusted, corrected) << drifted << " -> " << corrected << " -> " << adjusted;
  EXPECT_LT(adjusted, 0.3 * drifted) << drifted << " -> " << corrected << " -> " << adjusted;
}

TEST(LoopClosing, NoLoopWhereTheCameraNeverComesBack) {
  // Half a turn: every keyframe sees new walls; old ones are never revisited.
  std::vector<double> yaws;
  for (int k = 0; k < 25; ++k) yaws.push_back(M_PI * k / 24.0);
  const SyntheticMap m = build_map(yaws, drift_step(), 3, 13);
  const ScalePyramid scales(1.2f, 8);
  const LoopParams params;
  int candidates = 0;
  for (uint64_t id = 1; id <= m.truth.size(); ++id) {
    const LoopDetection loop = detect_loop(m.map, id, camera(), scales, PoseOptimiserParams{}, params);
    EXPECT_FALSE(loop.found) << "keyframe " << id << " matched " << loop.match;
    candidates += loop.candidates;
  }
  EXPECT_GT(candidates, 40);  // old keyframes were there to be (wrongly) matched
}

TEST(LoopClosing, CandidatesAreOldAndNotCovisible) {
  const SyntheticMap m = build_map(full_turn(), drift_step(), 3, 14);
  LoopParams params;
  params.min_keyframe_gap = 10;
  const uint64_t last = m.truth.size();
  const std::vector<uint64_t> c = loop_candidates(m.map, last, params);
  ASSERT_FALSE(c.empty());
  const KeyFrame* q = m.map.keyframe(last);
  for (const uint64_t id : c) {
    EXPECT_LE(id + 10, last);
    EXPECT_EQ(q->covisibility.count(id), 0u) << id;
  }
  EXPECT_EQ(c.front(), 1u);
  params.min_keyframe_gap = 1000;
  EXPECT_TRUE(loop_candidates(m.map, last, params).empty());
}

}  // namespace
