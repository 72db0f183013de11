// ATE: a trajectory seen through a rigid transform and noise has an ATE of the noise's RMS, a
// trajectory against itself has none, and too few associated pairs is an error.
#include <algorithm>
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "dqo_map/eval/ate.h"

namespace {

using dqo::SE3;
using dqo::eval::AteParams;
using dqo::eval::compute_ate;
using dqo::eval::StampedPose;

// A helix with turning orientation: not planar, so the alignment is well posed.
std::vector<StampedPose> helix(int n, double t0 = 0.0, double dt = 1.0 / 30.0) {
  std::vector<StampedPose> poses;
  for (int i = 0; i < n; ++i) {
    const double a = 0.05 * i;
    const Eigen::Vector3d p(std::cos(a), std::sin(a), 0.01 * i);
    const Eigen::Quaterniond q(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()));
    poses.emplace_back(t0 + i * dt, SE3(q, p));
  }
  return poses;
}

SE3 some_transform() {
  return SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized())),
             Eigen::Vector3d(0.5, -2.0, 1.25));
}

TEST(Ate, RigidTransformPlusNoiseGivesTheNoiseRms) {
  const auto gt = helix(600);
  const SE3 T_est_gt = some_transform();
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::vector<StampedPose> est;
  double noise_sq = 0.0;
  for (const auto& [t, T_wc] : gt) {
    const Eigen::Vector3d n(noise(rng), noise(rng), noise(rng));
    noise_sq += n.squaredNorm();
    est.emplace_back(t, SE3(T_est_gt.quaternion() * T_wc.quaternion(), T_est_gt * T_wc.translation() + n));
  }
  const double noise_rms = std::sqrt(noise_sq / gt.size());

  std::string error;
  const auto r = compute_ate(est, gt, AteParams{}, &error);
  ASSERT_TRUE(r) << error;
  EXPECT_EQ(r->matched, 600);
  EXPECT_NEAR(r->rmse_m, noise_rms, 0.02 * noise_rms);
  EXPECT_LT(r->mean_m, r->rmse_m);
  EXPECT_LE(r->rmse_m, r->max_m);
  EXPECT_GT(r->median_m, 0.0);
  EXPECT_EQ(r->errors.size(), 600u);
  EXPECT_EQ(r->scale, 1.0);
  // The alignment found is the inverse of the transform applied.
  const SE3 residual = r->T_gt_est * T_est_gt;
  EXPECT_LT(residual.translation().norm(), 5e-3);
  EXPECT_LT(residual.log().tail<3>().norm(), 1e-3);
}

TEST(Ate, TrajectoryAgainstItselfIsZero) {
  const auto gt = helix(50);
  const auto r = compute_ate(gt, gt, AteParams{}, nullptr);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->matched, 50);
  EXPECT_LT(r->rmse_m, 1e-9);
  EXPECT_LT(r->max_m, 1e-9);
  EXPECT_LT(r->T_gt_est.translation().norm(), 1e-9);
}

TEST(Ate, AssociatesByTimestamp) {
  // Ground truth at 100 Hz, the estimate at 30 Hz with a 3 ms offset: every estimate finds one
  // ground-truth pose, and the error is only what the nearest-pose mismatch leaves.
  const auto gt = helix(1000, 10.0, 0.01);
  std::vector<StampedPose> est;
  for (int i = 0; i < 300; ++i) {
    const double t = 10.003 + i / 30.0;
    est.emplace_back(t, gt[static_cast<size_t>(std::lround((t - 10.0) / 0.01))].second);
  }
  AteParams params;
  params.max_time_difference = 0.006;
  const auto r = compute_ate(est, gt, params, nullptr);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->matched, 300);
  EXPECT_LT(r->rmse_m, 1e-9);

  // Shuffled ground truth associates the same.
  auto shuffled = gt;
  std::shuffle(shuffled.begin(), shuffled.end(), std::mt19937(5));
  const auto r2 = compute_ate(est, shuffled, params, nullptr);
  ASSERT_TRUE(r2);
  EXPECT_EQ(r2->matched, 300);
  EXPECT_LT(r2->rmse_m, 1e-9);
}

TEST(Ate, EachGroundTruthPoseIsUsedOnce) {
  // Two estimates near one ground-truth pose: only the closer is matched.
  const auto gt = helix(10, 0.0, 1.0);
  auto est = gt;
  est.emplace_back(4.001, gt[4].second);
  std::sort(est.begin(), est.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  const auto r = compute_ate(est, gt, AteParams{}, nullptr);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->matched, 10);
}

TEST(Ate, RecoversScaleWhenAsked) {
  const auto gt = helix(100);
  std::vector<StampedPose> est;
  for (const auto& [t, T] : gt) est.emplace_back(t, SE3(T.quaternion(), 0.5 * T.translation()));
  AteParams params;
  params.with_scale = true;
  const auto r = compute_ate(est, gt, params, nullptr);
  ASSERT_TRUE(r);
  EXPECT_NEAR(r->scale, 2.0, 1e-9);
  EXPECT_LT(r->rmse_m, 1e-9);
  // Without scale the shrunken estimate leaves an error.
  const auto r2 = compute_ate(est, gt, AteParams{}, nullptr);
  ASSERT_TRUE(r2);
  EXPECT_GT(r2->rmse_m, 0.1);
}

TEST(Ate, TooFewPairsIsAnError) {
  const auto gt = helix(100);
  std::string error;
  EXPECT_FALSE(compute_ate(helix(2), gt, AteParams{}, &error));
  EXPECT_NE(error.find("2 of 2"), std::string::npos) << error;
  // Different time bases: nothing associates.
  EXPECT_FALSE(compute_ate(helix(100, 1000.0), gt, AteParams{}, &error));
  EXPECT_NE(error.find("0 of 100"), std::string::npos) << error;
  EXPECT_FALSE(compute_ate({}, gt, AteParams{}, &error));
}

}  // namespace
