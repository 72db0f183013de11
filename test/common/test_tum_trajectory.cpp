// The TUM trajectory text format: exact round trip, comments, errors that name file and line.
#include "dqo_map/common/tum_trajectory.h"

#include <filesystem>
#include <fstream>
#include <random>

#include <gtest/gtest.h>

#include "../io/io_test_util.h"  // TempDir, write_text, read_text: plain C++, no io/ library

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

TEST(TumTrajectory, ErrorsNameTheLine) {
  const auto path = (std::filesystem::temp_directory_path() / "dqo_common_bad_traj.txt").string();
  {
    std::ofstream f(path);
    f << "# comment\n1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 1\n";
  }
  std::string error;
  EXPECT_FALSE(read_tum_trajectory(path, &error));
  EXPECT_NE(error.find(path + ":3:"), std::string::npos) << error;
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace dqo
