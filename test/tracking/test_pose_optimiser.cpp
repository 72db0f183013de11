// Pose-only refinement: the Ceres residuals' Jacobians against numeric differences
// (GradientChecker), a known pose recovered from 3D-2D correspondences with outliers, the dense
// prior holding the pose alone and fusing with features.
#include <random>

#include <ceres/gradient_checker.h>
#include <ceres/manifold.h>
#include <gtest/gtest.h>

#include "pose_optimiser.h"
#include "residuals.h"

namespace {

using dqo::PinholeCamera;
using dqo::SE3;
using dqo::Vector6d;
using namespace dqo::tracking;

PinholeCamera test_camera() { return PinholeCamera{525.0, 520.0, 319.5, 239.5, 640, 480}; }

SE3 random_pose(std::mt19937* rng, double t_scale, double angle) {
  std::normal_distribution<double> n(0.0, 1.0);
  Vector6d xi;
  xi << t_scale * n(*rng), t_scale * n(*rng), t_scale * n(*rng), angle * n(*rng), angle * n(*rng),
      angle * n(*rng);
  return SE3::exp(xi);
}

double angle_deg(const SE3& a, const SE3& b) {
  const double w = std::min(1.0, std::abs((a.inverse() * b).quaternion().w()));
  return 2.0 * std::acos(w) * 180.0 / M_PI;
}

// Checks a cost function over (q_cw, t_cw[, p_w]) against numeric differences.
void expect_jacobians_match(const ceres::CostFunction* cost, const SE3& T_cw,
                            const Eigen::Vector3d* p_w) {
  ceres::EigenQuaternionManifold quaternion;
  std::vector<const ceres::Manifold*> manifolds = {&quaternion, nullptr};
  if (p_w != nullptr) manifolds.push_back(nullptr);
  ceres::NumericDiffOptions numeric;
  ceres::GradientChecker checker(cost, &manifolds, numeric);
  Eigen::Quaterniond q = T_cw.quaternion();
  Eigen::Vector3d t = T_cw.translation();
  Eigen::Vector3d p = p_w != nullptr ? *p_w : Eigen::Vector3d::Zero();
  std::vector<const double*> parameters = {q.coeffs().data(), t.data()};
  if (p_w != nullptr) parameters.push_back(p.data());
  ceres::GradientChecker::ProbeResults results;
  checker.Probe(parameters.data(), 1e-6, &results);
  ASSERT_TRUE(results.return_value);
  // Entries that are zero analytically come out as ±1e-14 from both sides, which the checker's
  // purely relative test rejects: compare relative to the block's scale instead.
  for (size_t b = 0; b < results.local_jacobians.size(); ++b) {
    const ceres::Matrix& analytic = results.local_jacobians[b];
    const ceres::Matrix& numeric = results.local_numeric_jacobians[b];
    const double scale = std::max(1.0, analytic.cwiseAbs().maxCoeff());
    EXPECT_LT((analytic - numeric).cwiseAbs().maxCoeff(), 1e-6 * scale)
        << "block " << b << "\nanalytic\n" << analytic << "\nnumeric\n" << numeric;
  }
}

TEST(Residuals, JacobiansMatchNumericDifferences) {
  std::mt19937 rng(3);
  const Intrinsics K(test_camera());
  for (int trial = 0; trial < 5; ++trial) {
    const SE3 T_cw = random_pose(&rng, 0.3, 0.3);
    const Eigen::Vector3d p_c(0.2 * trial - 0.4, 0.1, 1.5 + 0.2 * trial);
    const Eigen::Vector3d p_w = T_cw.inverse() * p_c;
    const Eigen::Vector2d uv(300.0 + trial, 200.0 - trial);
    std::unique_ptr<ceres::CostFunction> reprojection(ReprojectionCost::Create(K, p_w, uv, 0.8));
    std::unique_ptr<ceres::CostFunction> depth(DepthCost::Create(p_w, 1.6, 200.0));
    std::unique_ptr<ceres::CostFunction> ba_reprojection(BaReprojectionCost::Create(K, uv, 0.8));
    std::unique_ptr<ceres::CostFunction> ba_depth(BaDepthCost::Create(1.6, 200.0));
    Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Random();
    const Eigen::Matrix<double, 6, 6> information = A * A.transpose() * 100.0;
    std::unique_ptr<ceres::CostFunction> prior(DensePriorCost::Create(
        random_pose(&rng, 0.01, 0.01) * T_cw, sqrt_information(information)));
    expect_jacobians_match(reprojection.get(), T_cw, nullptr);
    expect_jacobians_match(depth.get(), T_cw, nullptr);
    expect_jacobians_match(ba_reprojection.get(), T_cw, &p_w);
    expect_jacobians_match(ba_depth.get(), T_cw, &p_w);
    expect_jacobians_match(prior.get(), T_cw, nullptr);
  }
}

TEST(Residuals, OdometryJacobiansMatchAndVanishAtTheMeasurement) {
  std::mt19937 rng(7);
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Random();
  const Eigen::Matrix<double, 6, 6> information = A * A.transpose() * 100.0;
  for (int trial = 0; trial < 5; ++trial) {
    const SE3 T_wa = random_pose(&rng, 0.5, 0.5), T_wb = random_pose(&rng, 0.5, 0.5);
    const SE3 T_ab = T_wa.inverse() * T_wb;
    std::unique_ptr<ceres::CostFunction> cost(
        OdometryCost::Create(T_ab * random_pose(&rng, 0.01, 0.01), sqrt_information(information)));
    ceres::EigenQuaternionManifold quaternion;
    std::vector<const ceres::Manifold*> manifolds = {&quaternion, nullptr, &quaternion, nullptr};
    ceres::GradientChecker checker(cost.get(), &manifolds, ceres::NumericDiffOptions{});
    const SE3 T_aw = T_wa.inverse(), T_bw = T_wb.inverse();
    Eigen::Quaterniond qa = T_aw.quaternion(), qb = T_bw.quaternion();
    Eigen::Vector3d ta = T_aw.translation(), tb = T_bw.translation();
    const double* parameters[4] = {qa.coeffs().data(), ta.data(), qb.coeffs().data(), tb.data()};
    ceres::GradientChecker::ProbeResults results;
    checker.Probe(parameters, 1e-6, &results);
    ASSERT_TRUE(results.return_value);
    for (size_t b = 0; b < 4; ++b) {
      const double scale = std::max(1.0, results.local_jacobians[b].cwiseAbs().maxCoeff());
      EXPECT_LT((results.local_jacobians[b] - results.local_numeric_jacobians[b]).cwiseAbs().maxCoeff(),
                1e-6 * scale);
    }
    // Zero residual when the poses agree with the measurement.
    std::unique_ptr<ceres::CostFunction> exact(
        OdometryCost::Create(T_ab, sqrt_information(information)));
    Vector6d r;
    exact->Evaluate(parameters, r.data(), nullptr);
    EXPECT_LT(r.norm(), 1e-6);
  }
}

TEST(Residuals, DensePriorIsTheRightPerturbationMahalanobis) {
  // At T_wc = T̂_wc exp(δ) the prior's squared residual is δᵀΛδ (to first order).
  std::mt19937 rng(5);
  const SE3 T_wc_hat = random_pose(&rng, 0.5, 0.5);
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Random();
  const Eigen::Matrix<double, 6, 6> information = A * A.transpose() + Eigen::Matrix<double, 6, 6>::Identity();
  std::unique_ptr<ceres::CostFunction> prior(
      DensePriorCost::Create(T_wc_hat.inverse(), sqrt_information(information)));
  Vector6d delta;
  delta << 1e-4, -2e-4, 3e-4, 2e-4, 1e-4, -3e-4;
  const SE3 T_cw = (T_wc_hat * SE3::exp(delta)).inverse();
  Eigen::Quaterniond q = T_cw.quaternion();
  Eigen::Vector3d t = T_cw.translation();
  const double* parameters[2] = {q.coeffs().data(), t.data()};
  Vector6d r;
  prior->Evaluate(parameters, r.data(), nullptr);
  const double expected = delta.dot(information * delta);
  EXPECT_NEAR(r.squaredNorm(), expected, 1e-3 * expected);
}

TEST(Residuals, SqrtInformationSquaresBack) {
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Random();
  const Eigen::Matrix<double, 6, 6> information = A * A.transpose();
  const Eigen::Matrix<double, 6, 6> S = sqrt_information(information);
  EXPECT_LT((S.transpose() * S - information).norm(), 1e-9 * information.norm());
}

// Points in front of a camera at T_wc_true, observed with pixel noise; a share of them replaced
// by wrong pixels.
std::vector<PoseObservation> make_observations(const SE3& T_wc_true, const PinholeCamera& camera,
                                               int n, double outlier_share, std::mt19937* rng,
                                               std::vector<char>* is_outlier) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.5);
  std::vector<PoseObservation> out;
  is_outlier->clear();
  for (int i = 0; i < n; ++i) {
    const double z = 0.8 + 3.0 * u(*rng);
    const Eigen::Vector2d uv(20.0 + 600.0 * u(*rng), 20.0 + 440.0 * u(*rng));
    const Eigen::Vector3d p_c = camera.back_project(uv.x(), uv.y(), z);
    PoseObservation o;
    o.p_w = T_wc_true * p_c;
    o.uv = uv + Eigen::Vector2d(noise(*rng), noise(*rng));
    o.depth = z + 0.0015 * z * z * noise(*rng) * 2.0;
    o.inv_sigma = 1.0;
    const bool outlier = u(*rng) < outlier_share;
    if (outlier) {
      o.uv = Eigen::Vector2d(20.0 + 600.0 * u(*rng), 20.0 + 440.0 * u(*rng));
      o.depth = 0.8 + 3.0 * u(*rng);
    }
    is_outlier->push_back(outlier);
    out.push_back(o);
  }
  return out;
}

TEST(PoseOptimiser, RecoversAKnownPoseDespiteOutliers) {
  const PinholeCamera camera = test_camera();
  std::mt19937 rng(11);
  for (int trial = 0; trial < 5; ++trial) {
    const SE3 T_wc_true = random_pose(&rng, 1.0, 0.5);
    std::vector<char> is_outlier;
    const std::vector<PoseObservation> obs =
        make_observations(T_wc_true, camera, 300, 0.3, &rng, &is_outlier);
    // A guess 5 cm and a few degrees off, as a motion model would give.
    const SE3 guess = T_wc_true * random_pose(&rng, 0.03, 0.04);
    const PoseOptimisationResult r = optimise_pose(guess, obs, camera, nullptr, {});
    EXPECT_LT((r.T_wc.translation() - T_wc_true.translation()).norm(), 2e-3) << "trial " << trial;
    EXPECT_LT(angle_deg(r.T_wc, T_wc_true), 0.1) << "trial " << trial;
    int caught = 0, outliers = 0, wrongly_rejected = 0;
    for (size_t i = 0; i < obs.size(); ++i) {
      outliers += is_outlier[i];
      caught += is_outlier[i] && !r.inlier[i];
      wrongly_rejected += !is_outlier[i] && !r.inlier[i];
    }
    EXPECT_GE(caught, outliers - 3);
    EXPECT_LT(wrongly_rejected, 0.1 * (obs.size() - outliers));
  }
}

TEST(PoseOptimiser, DensePriorAloneHoldsThePose) {
  const PinholeCamera camera = test_camera();
  DensePrior prior;
  prior.T_w_ref = SE3::exp((Vector6d() << 0.3, -0.2, 0.1, 0.05, 0.1, -0.2).finished());
  prior.T_ref_cur = SE3::exp((Vector6d() << 0.02, 0.01, -0.01, 0.01, 0.0, 0.02).finished());
  prior.information = Eigen::Matrix<double, 6, 6>::Identity() * 1e6;
  const SE3 guess = prior.T_w_ref;
  const PoseOptimisationResult r = optimise_pose(guess, {}, camera, &prior, {});
  const SE3 expected = prior.T_w_ref * prior.T_ref_cur;
  EXPECT_LT((r.T_wc.translation() - expected.translation()).norm(), 1e-6);
  EXPECT_LT(angle_deg(r.T_wc, expected), 1e-4);
  EXPECT_LT(r.prior_chi2, 1e-6);
}

TEST(PoseOptimiser, FusionLiesBetweenFeaturesAndPrior) {
  // Features say T_true; the prior says T_true moved 1 cm along x. With the prior as confident
  // as the features the answer lies strictly between them and reports the disagreement.
  const PinholeCamera camera = test_camera();
  std::mt19937 rng(17);
  const SE3 T_wc_true = random_pose(&rng, 0.5, 0.3);
  std::vector<char> is_outlier;
  const std::vector<PoseObservation> obs =
      make_observations(T_wc_true, camera, 200, 0.0, &rng, &is_outlier);
  const PoseOptimisationResult features = optimise_pose(T_wc_true, obs, camera, nullptr, {});
  const double sigma = 1e-3;  // 1 mm: comparable to what 200 features give
  DensePrior prior;
  prior.T_w_ref = SE3();
  prior.T_ref_cur = T_wc_true * SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.01, 0, 0));
  prior.information = Eigen::Matrix<double, 6, 6>::Identity() / (sigma * sigma);
  const PoseOptimisationResult fused = optimise_pose(T_wc_true, obs, camera, &prior, {});
  const double shift = (T_wc_true.inverse() * fused.T_wc).translation().x();
  EXPECT_GT(shift, 0.5e-3);
  EXPECT_LT(shift, 9.5e-3);
  EXPECT_GT(fused.prior_chi2, 1.0);
  EXPECT_LT((features.T_wc.translation() - T_wc_true.translation()).norm(), 1e-3);
}

}  // namespace
