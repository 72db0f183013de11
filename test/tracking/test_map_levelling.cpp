// tracking_node's z-up map: the levelling rotation, the accelerometer's mean, and the floor found
// in a depth image of a floor and a wall seen by a tilted, rolled camera.
#include <cmath>
#include <random>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "dqo_map/tracking/map_levelling.h"

namespace dqo::tracking {
namespace {

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
}

TEST(MapLevelling, LevelRotationTakesUpToZAndKeepsTheHeading) {
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int i = 0; i < 100; ++i) {
    const Eigen::Vector3d up(n(rng), n(rng), n(rng));
    const Eigen::Matrix3d R = level_rotation(up);
    EXPECT_LT((R * R.transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
    EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
    EXPECT_LT(((R * up.normalized()) - Eigen::Vector3d::UnitZ()).norm(), 1e-12);
    const Eigen::Vector3d x = R * Eigen::Vector3d::UnitX();
    if (std::abs(up.normalized().x()) < 0.99) {
      EXPECT_NEAR(x.y(), 0.0, 1e-12) << "the body's x keeps its heading";
      EXPECT_GT(x.x(), 0.0);
    }
  }
  // A level body is left as it is.
  EXPECT_LT((level_rotation(Eigen::Vector3d(0, 0, 2)) - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_EQ(map_level_from_string("floor"), MapLevel::kFloor);
  EXPECT_FALSE(map_level_from_string("Floor"));
}

TEST(MapLevelling, GravityIsTheMeanOfTheFirstSamples) {
  GravityEstimator g(50);
  EXPECT_FALSE(g.up());
  const Eigen::Vector3d up = Eigen::Vector3d(0.1, -0.9, 0.3).normalized();
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 0.3);
  for (int i = 0; i < 50; ++i) g.add(9.81 * up + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  g.add(Eigen::Vector3d(std::nan(""), 0, 0));
  EXPECT_TRUE(g.ready());
  for (int i = 0; i < 100; ++i) g.add(Eigen::Vector3d(0, 0, 50));  // after the first moments: ignored
  double magnitude = 0.0;
  const auto found = g.up(&magnitude);
  ASSERT_TRUE(found);
  EXPECT_LT(angle_deg(*found, up), 1.0);
  EXPECT_NEAR(magnitude, 9.81, 0.2);
}

// Depth of the floor z = 0 and a wall x = 2 of a world, seen from 1.4 m up, pitched 35 degrees down
// and rolled 10 degrees: the floor's normal comes back as the world's up in the camera frame.
TEST(MapLevelling, FloorOfATiltedView) {
  const PinholeCamera camera{300.0, 300.0, 159.5, 119.5, 320, 240};
  // Optical frame looking along world +x, then pitched down and rolled.
  Eigen::Matrix3d R_w_level;
  R_w_level << 0, 0, 1, -1, 0, 0, 0, -1, 0;  // optical x right = -y world, y down = -z, z = +x
  const Eigen::Matrix3d R_wc = R_w_level * Eigen::AngleAxisd(-35.0 * M_PI / 180.0, Eigen::Vector3d::UnitX()).toRotationMatrix() *
                               Eigen::AngleAxisd(10.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Vector3d t_wc(0.0, 0.0, 1.4);
  DepthImage depth(camera.width, camera.height, 1, 0.0f);
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const Eigen::Vector3d ray_c = camera.back_project(u, v, 1.0);
      const Eigen::Vector3d ray_w = R_wc * ray_c;
      double s = 1e9;
      if (ray_w.z() < -1e-9) s = std::min(s, -t_wc.z() / ray_w.z());           // floor
      if (ray_w.x() > 1e-9) s = std::min(s, (2.0 - t_wc.x()) / ray_w.x());     // wall
      if (s < 20.0) depth.at(u, v) = static_cast<float>(s);  // depth = z_c = s for a ray of z_c 1
    }
  }
  const Eigen::Vector3d up_c = R_wc.transpose() * Eigen::Vector3d::UnitZ();
  std::string error;
  const auto floor = find_floor(camera, depth, Eigen::Vector3d(0, -1, 0), FloorParams(), &error);
  ASSERT_TRUE(floor) << error;
  EXPECT_LT(angle_deg(floor->up_c, up_c), 0.1);
  EXPECT_NEAR(floor->height, 1.4, 5e-3);  // inliers near the corner lean it a little
  // Looking for a plane near the wall's normal finds the wall, which is not below the camera ...
  // and with a tilt limit that excludes both, nothing.
  FloorParams strict;
  strict.max_tilt_deg = 5.0;
  EXPECT_FALSE(find_floor(camera, depth, Eigen::Vector3d(1, 0, 0), strict, &error));
  EXPECT_FALSE(error.empty());
  EXPECT_FALSE(find_floor(camera, DepthImage(10, 10, 1, 1.0f), Eigen::Vector3d(0, -1, 0), FloorParams(), &error));
}

}  // namespace
}  // namespace dqo::tracking
