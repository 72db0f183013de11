// The final trajectory refinement: the acceleration residual against known motions, and the smoother on a synthetic trajectory with per-frame noise and one frame far
// off (reported degraded): closer to the truth than the measurements, the degraded frame carried
// by its neighbours; frames further apart than max_gap_s are left as measured.
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "trajectory_refiner.h"

namespace {

using dqo::SE3;
using dqo::Vector6d;
using namespace dqo::tracking;

// A smooth hand-held motion: position and yaw/pitch as sines of time.
SE3 motion(double t) {
  const Eigen::Vector3d c(0.3 * std::sin(1.3 * t), 0.2 * std::sin(0.9 * t + 0.5), 0.1 * t);
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.5 * std::sin(1.1 * t), Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(0.2 * std::sin(0.7 * t), Eigen::Vector3d::UnitX()));
  return SE3(q, c);
}

TEST(TrajectoryRefiner, AccelerationResidualMatchesTheMotion) {
  RefineParams p;
  p.acceleration_sigma = 1.0;
  p.angular_acceleration_sigma_deg = 180.0 / M_PI;  // 1 rad/s²: the residual is α itself
  // Constant velocity on SE(3) (the same step in the camera's frame), however fast: zero.
  const Eigen::Quaterniond step(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()));
  const SE3 D(step, Eigen::Vector3d(0.1, 0.02, -0.05));
  const SE3 T0(Eigen::Quaterniond(Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitX())),
               Eigen::Vector3d(1.0, 2.0, 3.0));
  const SE3 T1 = T0 * D, T2 = T1 * D;
  EXPECT_LT(acceleration_residual(T0, T1, T2, 0.033, 0.033, p).norm(), 1e-9);
  // The same steps at twice the time apart in the second: the velocity halves.
  const Eigen::Matrix<double, 6, 1> slower = acceleration_residual(T0, T1, T2, 0.033, 0.066, p);
  EXPECT_GT(slower.norm(), 1.0);
  // A known translation acceleration: c(t) = ½ a t².
  const Eigen::Vector3d a(0.5, -1.0, 2.0);
  const double dt = 0.03;
  auto at = [&](double t) { return SE3(Eigen::Quaterniond::Identity(), 0.5 * a * t * t); };
  const Eigen::Matrix<double, 6, 1> r = acceleration_residual(at(0), at(dt), at(2 * dt), dt, dt, p);
  EXPECT_LT((r.head<3>() - a).norm(), 1e-9);
  EXPECT_LT(r.tail<3>().norm(), 1e-12);
  // Unequal steps and a rotation that speeds up about one axis: α ≈ the second difference.
  const Eigen::Vector3d axis = Eigen::Vector3d(0.0, 0.0, 1.0);
  const double alpha = 3.0, dt1 = 0.03, dt2 = 0.05;
  auto rot = [&](double t) {
    return SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.5 * alpha * t * t, axis)), Eigen::Vector3d::Zero());
  };
  const Eigen::Matrix<double, 6, 1> ra = acceleration_residual(rot(0), rot(dt1), rot(dt1 + dt2), dt1, dt2, p);
  EXPECT_NEAR(ra[5], alpha, 0.01 * alpha);
  EXPECT_NEAR(ra[3], 0.0, 1e-9);
  // The σ whitens.
  p.acceleration_sigma = 2.0;
  EXPECT_LT((acceleration_residual(at(0), at(dt), at(2 * dt), dt, dt, p).head<3>() - a / 2.0).norm(), 1e-9);
}

double mean_error(const std::vector<SE3>& poses, const std::vector<SE3>& truth, size_t skip = 1000000) {
  double sum = 0.0;
  int n = 0;
  for (size_t i = 0; i < poses.size(); ++i) {
    if (i == skip) continue;
    sum += (poses[i].translation() - truth[i].translation()).norm();
    ++n;
  }
  return sum / n;
}

TEST(TrajectoryRefiner, SmoothsNoiseAndCarriesADegradedFrame) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0.0, 1.0);
  std::vector<RefinerFrame> frames;
  std::vector<SE3> truth, measured;
  const size_t bad = 40;
  for (int i = 0; i < 90; ++i) {
    const double t = i / 30.0;
    truth.push_back(motion(t));
    Vector6d xi;
    xi << 0.004 * n(rng), 0.004 * n(rng), 0.004 * n(rng), 0.004 * n(rng), 0.004 * n(rng),
        0.004 * n(rng);
    RefinerFrame f;
    f.timestamp = t;
    f.T_wc = truth.back() * SE3::exp(xi);
    if (static_cast<size_t>(i) == bad) {  // motion blur: 5 cm off, reported degraded
      f.T_wc = SE3(f.T_wc.quaternion(), f.T_wc.translation() + Eigen::Vector3d(0.05, 0.0, 0.0));
      f.degraded = true;
    }
    frames.push_back(f);
    measured.push_back(f.T_wc);
  }
  const RefineParams p;
  const std::vector<SE3> refined = refine_trajectory(frames, p);
  ASSERT_EQ(refined.size(), frames.size());
  const double before = mean_error(measured, truth, bad), after = mean_error(refined, truth, bad);
  EXPECT_LT(after, 0.8 * before) << before << " -> " << after;
  const double bad_before = (measured[bad].translation() - truth[bad].translation()).norm();
  const double bad_after = (refined[bad].translation() - truth[bad].translation()).norm();
  EXPECT_GT(bad_before, 0.045);
  EXPECT_LT(bad_after, 0.015) << bad_before << " -> " << bad_after;
  // The same frame, not flagged: the smoother moves it less.
  frames[bad].degraded = false;
  const std::vector<SE3> trusted = refine_trajectory(frames, p);
  EXPECT_GT((trusted[bad].translation() - truth[bad].translation()).norm(), 2.0 * bad_after);
}

TEST(TrajectoryRefiner, FramesFarApartAreLeftAlone) {
  std::vector<RefinerFrame> frames;
  for (int i = 0; i < 10; ++i) {
    RefinerFrame f;
    f.timestamp = 0.5 * i;  // 2 Hz: beyond max_gap_s
    f.T_wc = motion(f.timestamp) * SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.01 * (i % 2), 0, 0));
    frames.push_back(f);
  }
  RefineParams p;
  p.max_gap_s = 0.2;
  const std::vector<SE3> refined = refine_trajectory(frames, p);
  for (size_t i = 0; i < frames.size(); ++i)
    EXPECT_LT((refined[i].translation() - frames[i].T_wc.translation()).norm(), 1e-12);
}

}  // namespace
