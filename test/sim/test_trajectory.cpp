// Camera paths: look-at convention, orbits, hand-held walks (TUM files: test/common).

#include <gtest/gtest.h>

#include <cmath>
#include <numeric>

#include "dqo_map/sim/trajectory.h"

namespace dqo::sim {
namespace {

TEST(Trajectory, LookAtUsesTheOpticalFrame) {
  const SE3 T = look_at(Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(2, 0, 1));
  const Eigen::Matrix3d R = T.rotation();
  EXPECT_NEAR((R.col(2) - Eigen::Vector3d(1, 0, 0)).norm(), 0.0, 1e-12);   // z forward
  EXPECT_NEAR((R.col(0) - Eigen::Vector3d(0, -1, 0)).norm(), 0.0, 1e-12);  // x right
  EXPECT_NEAR((R.col(1) - Eigen::Vector3d(0, 0, -1)).norm(), 0.0, 1e-12);  // y down
  EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
  // Straight down is legal.
  const SE3 D = look_at(Eigen::Vector3d(0, 0, 2), Eigen::Vector3d(0, 0, 0));
  EXPECT_NEAR((D.rotation().col(2) - Eigen::Vector3d(0, 0, -1)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(D.rotation().determinant(), 1.0, 1e-12);
}

TEST(Trajectory, OrbitCirclesTheTargetLookingAtIt) {
  OrbitParams p;
  p.target = Eigen::Vector3d(0.5, -0.2, 0.8);
  p.radius = 1.2;
  p.height = 1.4;
  const auto poses = make_orbit(p, 100, 30.0);
  ASSERT_EQ(poses.size(), 100u);
  for (size_t i = 0; i < poses.size(); ++i) {
    const Eigen::Vector3d c = poses[i].T_wc.translation();
    EXPECT_NEAR(std::hypot(c.x() - 0.5, c.y() + 0.2), 1.2, 1e-12);
    EXPECT_NEAR(c.z(), 1.4, 1e-12);
    const Eigen::Vector3d to_target = (p.target - c).normalized();
    EXPECT_NEAR(poses[i].T_wc.rotation().col(2).dot(to_target), 1.0, 1e-12);
    EXPECT_NEAR(poses[i].timestamp, i / 30.0, 1e-12);
  }
  // A full orbit does not repeat its first pose.
  EXPECT_GT((poses.front().T_wc.translation() - poses.back().T_wc.translation()).norm(), 0.05);
}

TEST(Trajectory, WalkIsSmoothAtConstantSpeedThroughItsEnds) {
  WalkParams p;
  p.waypoints = {{0, 0, 1.5}, {1, 0, 1.5}, {2, 1, 1.4}, {2, 3, 1.6}};
  p.look_at = {{1, 1, 1}, {2, 2, 1}, {3, 3, 1}, {3, 4, 1}};
  const auto poses = make_walk(p, 200, 30.0);
  ASSERT_EQ(poses.size(), 200u);
  EXPECT_NEAR((poses.front().T_wc.translation() - p.waypoints.front()).norm(), 0.0, 1e-9);
  EXPECT_NEAR((poses.back().T_wc.translation() - p.waypoints.back()).norm(), 0.0, 1e-9);
  std::vector<double> steps;
  double max_turn = 0.0;
  for (size_t i = 1; i < poses.size(); ++i) {
    steps.push_back((poses[i].T_wc.translation() - poses[i - 1].T_wc.translation()).norm());
    const Eigen::Quaterniond dq =
        poses[i - 1].T_wc.quaternion().conjugate() * poses[i].T_wc.quaternion();
    max_turn = std::max(max_turn, 2.0 * std::acos(std::min(1.0, std::abs(dq.w()))));
  }
  const double mean = std::accumulate(steps.begin(), steps.end(), 0.0) / steps.size();
  for (const double s : steps) EXPECT_NEAR(s, mean, 0.03 * mean);
  EXPECT_LT(max_turn, 0.1);  // radians per frame: no jumps
  // The shake moves the camera a little and smoothly, deterministically.
  p.jitter_position = 0.01;
  p.jitter_rotation_deg = 1.0;
  p.seed = 5;
  const auto shaken = make_walk(p, 200, 30.0);
  const auto again = make_walk(p, 200, 30.0);
  double max_offset = 0.0;
  for (size_t i = 0; i < poses.size(); ++i) {
    const double d = (shaken[i].T_wc.translation() - poses[i].T_wc.translation()).norm();
    max_offset = std::max(max_offset, d);
    EXPECT_EQ(shaken[i].T_wc.translation(), again[i].T_wc.translation());
  }
  EXPECT_GT(max_offset, 0.002);
  EXPECT_LT(max_offset, 0.02);
}

}  // namespace
}  // namespace dqo::sim
