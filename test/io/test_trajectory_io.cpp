#include "dqo_map/io/trajectory_io.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "io_test_util.h"

namespace dqo {
namespace {

SE3 random_pose(std::mt19937_64& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
  return SE3(q, Eigen::Vector3d(normal(rng), normal(rng), normal(rng)) * 3.0);
}

TEST(TumTrajectory, RoundTripIsExact) {
  test::TempDir tmp;
  std::mt19937_64 rng(5);
  Trajectory poses;
  for (int i = 0; i < 20; ++i) poses.emplace_back(1305031102.175304 + i / 30.0, random_pose(rng));
  std::string error;
  ASSERT_TRUE(write_tum_trajectory(tmp / "traj.txt", poses, &error)) << error;
  const auto back = read_tum_trajectory(tmp / "traj.txt", &error);
  ASSERT_TRUE(back) << error;
  ASSERT_EQ(back->size(), poses.size());
  for (size_t i = 0; i < poses.size(); ++i) {
    EXPECT_EQ((*back)[i].first, poses[i].first);  // timestamps bit for bit
    EXPECT_EQ((*back)[i].second.translation(), poses[i].second.translation());
    // Only renormalising a unit quaternion may move its last bit.
    EXPECT_LT(((*back)[i].second.quaternion().coeffs() - poses[i].second.quaternion().coeffs())
                  .cwiseAbs()
                  .maxCoeff(),
              1e-15);
  }
  const std::string text = test::read_text(tmp / "traj.txt");
  EXPECT_EQ(text.rfind("# timestamp tx ty tz qx qy qz qw\n", 0), 0u) << text;
}

TEST(TumTrajectory, ReadsCommentsBlankLinesAndScalarLastQuaternions) {
  test::TempDir tmp;
  test::write_text(tmp / "gt.txt",
                   "# ground truth trajectory\n"
                   "# timestamp tx ty tz qx qy qz qw\n"
                   "\n"
                   "1.5 1 2 3 0 0 0.70710678118654757 0.70710678118654757\r\n"
                   "2.5 -1 0 0 0 0 0 2\n");
  std::string error;
  const auto poses = read_tum_trajectory(tmp / "gt.txt", &error);
  ASSERT_TRUE(poses) << error;
  ASSERT_EQ(poses->size(), 2u);
  EXPECT_EQ((*poses)[0].first, 1.5);
  EXPECT_EQ((*poses)[0].second.translation(), Eigen::Vector3d(1, 2, 3));
  // 90 degrees about z: x goes to y.
  EXPECT_LT(((*poses)[0].second.rotation() * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY())
                .norm(),
            1e-12);
  EXPECT_DOUBLE_EQ((*poses)[1].second.quaternion().w(), 1.0);  // normalised
}

TEST(TumTrajectory, MalformedLinesNameFileAndLine) {
  test::TempDir tmp;
  std::string error;
  test::write_text(tmp / "a.txt", "# header\n1 0 0 0 0 0 0 1\n2 0 0 0 0 0 1\n");
  EXPECT_FALSE(read_tum_trajectory(tmp / "a.txt", &error));
  EXPECT_NE(error.find(tmp / "a.txt:3:"), std::string::npos) << error;
  test::write_text(tmp / "b.txt", "1 0 0 0 0 0 0 1\n2 0 0 x 0 0 0 1\n");
  EXPECT_FALSE(read_tum_trajectory(tmp / "b.txt", &error));
  EXPECT_NE(error.find(tmp / "b.txt:2:"), std::string::npos) << error;
  EXPECT_NE(error.find("'x'"), std::string::npos) << error;
  test::write_text(tmp / "c.txt", "1 0 0 0 0 0 0 0\n");
  EXPECT_FALSE(read_tum_trajectory(tmp / "c.txt", &error));
  EXPECT_NE(error.find(tmp / "c.txt:1:"), std::string::npos) << error;
  test::write_text(tmp / "d.txt", "1 0 0 nan 0 0 0 1\n");
  EXPECT_FALSE(read_tum_trajectory(tmp / "d.txt", &error));
  EXPECT_FALSE(read_tum_trajectory(tmp / "missing.txt", &error));
  EXPECT_NE(error.find("missing.txt"), std::string::npos) << error;
}

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
