#include "dqo_map/io/trajectory_io.h"

#include <gtest/gtest.h>

namespace dqo {
namespace {

TEST(AssociateTimestamps, PairsNearestOneToOneWithinTheWindow) {
  const std::vector<double> a = {1.000, 1.033, 1.066, 1.100, 1.500};
  const std::vector<double> b = {0.995, 1.040, 1.045, 1.090, 1.600};
  const auto m = associate_timestamps(a, b, 0.02);
  // 1.066 is 0.021 from 1.045 and 0.024 from 1.090: no partner. 1.5 has none either.
  const std::vector<std::pair<int, int>> expected = {{0, 0}, {1, 1}, {3, 3}};
  EXPECT_EQ(m, expected);
}

TEST(AssociateTimestamps, GreedyByDifferenceUsesEachIndexOnce) {
  // Both a's are nearest to b[0]; the closer one wins it, the other takes b[1].
  const std::vector<double> a = {10.000, 10.008};
  const std::vector<double> b = {10.010, 10.019};
  const auto m = associate_timestamps(a, b, 0.02);
  const std::vector<std::pair<int, int>> expected = {{0, 1}, {1, 0}};
  EXPECT_EQ(m, expected);
  EXPECT_TRUE(associate_timestamps({}, b, 0.02).empty());
}

TEST(PoseAt, InterpolatesBetweenNeighboursAndFallsBackToNearest) {
  Trajectory traj;
  traj.emplace_back(1.0, SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 0)));
  traj.emplace_back(1.08, SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitZ())),
                              Eigen::Vector3d(1, 0, 0)));
  traj.emplace_back(2.0, SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(5, 0, 0)));

  const auto mid = pose_at(traj, 1.02);
  ASSERT_TRUE(mid);
  EXPECT_NEAR(mid->translation().x(), 0.25, 1e-12);
  EXPECT_NEAR(Eigen::AngleAxisd(mid->quaternion()).angle(), 0.05, 1e-12);

  EXPECT_EQ(pose_at(traj, 1.08)->translation().x(), 1.0);  // exact sample
  // 1.08 .. 2.0 is a gap of 0.92 s: no interpolation; 1.09 is within 0.02 of 1.08.
  EXPECT_EQ(pose_at(traj, 1.09)->translation().x(), 1.0);
  EXPECT_FALSE(pose_at(traj, 1.5));
  EXPECT_EQ(pose_at(traj, 0.99)->translation().x(), 0.0);  // before the start, within 0.02
  EXPECT_FALSE(pose_at(traj, 0.9));
  EXPECT_FALSE(pose_at(traj, 2.05));

  PoseLookupParams nearest;
  nearest.interpolate = false;
  nearest.max_difference = 0.1;
  EXPECT_EQ(pose_at(traj, 1.03, nearest)->translation().x(), 0.0);
  EXPECT_EQ(pose_at(traj, 1.06, nearest)->translation().x(), 1.0);
  EXPECT_FALSE(pose_at(traj, 1.5, nearest));
  EXPECT_FALSE(pose_at({}, 1.0));
}

}  // namespace
}  // namespace dqo
