// Support closure: the plane under an object found in its surroundings, the footprint, the virtual
// view, and the cases where no face is closed. Synthetic: a camera 1 m above the plane z = 0
// looking straight down at a square patch (the object's top) at some height.

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "dqo_map/mesh/support_closure.h"

namespace dqo::mesh {
namespace {

// A view from (0, 0, 1) looking down −z at the square |x|, |y| <= half at height `top`.
FusionView top_view(double half, double top) {
  FusionView v;
  v.camera.width = v.camera.height = 101;
  v.camera.fx = v.camera.fy = 200.0;
  v.camera.cx = v.camera.cy = 50.0;
  // Camera axes: x = world x, y = world −y, z = world −z (looking down), a proper rotation.
  Eigen::Matrix3d R;
  R << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  v.T_wc = SE3::from_rotation_translation(R, Eigen::Vector3d(0, 0, 1));
  v.depth.assign(101 * 101, 0.f);
  v.rgb.assign(3 * 101 * 101, 0.5f);
  const double d = 1.0 - top;
  for (int y = 0; y < 101; ++y) {
    for (int x = 0; x < 101; ++x) {
      const Eigen::Vector3d p = v.T_wc * v.camera.back_project(x, y, d);
      if (std::abs(p.x()) <= half && std::abs(p.y()) <= half) v.depth[y * 101 + x] = static_cast<float>(d);
    }
  }
  return v;
}

// Points of the plane z = height around the square (a ring from half to half + 5 cm).
std::vector<Eigen::Vector3d> ring(double half, double height) {
  std::vector<Eigen::Vector3d> out;
  for (double x = -half - 0.05; x <= half + 0.05; x += 0.005) {
    for (double y = -half - 0.05; y <= half + 0.05; y += 0.005) {
      if (std::abs(x) > half || std::abs(y) > half) out.emplace_back(x, y, height);
    }
  }
  return out;
}

OrientedBox box(double half, double top) {
  OrientedBox b;
  b.centre = Eigen::Vector3d(0, 0, 0.5 * top);
  b.half_extents = Eigen::Vector3d(half, half, 0.5 * top);
  return b;
}

TEST(SupportClosure, ThinObjectOnAPlaneIsClosedOverItsFootprint) {
  const double half = 0.05, top = 0.008, voxel = 0.002;
  SupportClosureInfo info;
  const auto view = support_closure_view({top_view(half, top)}, ring(half, 0.0), box(half, top),
                                         voxel, SupportClosureParams(), &info);
  ASSERT_TRUE(view.has_value()) << info.reason;
  EXPECT_TRUE(info.closed);
  EXPECT_NEAR(info.normal.z(), 1.0, 1e-9);  // towards the object
  EXPECT_NEAR(info.offset, 0.0, 1e-9);
  // The footprint is the 10 cm square: (10 cm / 2 mm)² cells, give or take its border.
  const double cells = std::pow(2 * half / voxel, 2);
  EXPECT_NEAR(info.footprint_cells, cells, 0.1 * cells);
  // Every footprint pixel sees the plane: back-projected, it lies on z = 0 inside the square.
  int surface = 0;
  for (int y = 0; y < view->camera.height; ++y) {
    for (int x = 0; x < view->camera.width; ++x) {
      const float d = view->depth[static_cast<size_t>(y) * view->camera.width + x];
      if (d <= 0.f) continue;
      ++surface;
      const Eigen::Vector3d p = view->T_wc * view->camera.back_project(x, y, d);
      EXPECT_NEAR(p.z(), 0.0, 1e-9);
      EXPECT_LE(std::abs(p.x()), half + 2 * voxel);
      EXPECT_LE(std::abs(p.y()), half + 2 * voxel);
      // Looking up at it: the camera is below the plane.
      EXPECT_LT(view->T_wc.translation().z(), 0.0);
    }
  }
  EXPECT_EQ(surface, info.footprint_cells);
}

TEST(SupportClosure, TiltedPlanesWork) {
  // The same scene rotated by 40° about a skew axis: no gravity direction is assumed.
  const SE3 T(Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 0.5).normalized())),
              Eigen::Vector3d(0.3, -0.2, 1.0));
  FusionView v = top_view(0.05, 0.008);
  v.T_wc = T * v.T_wc;
  std::vector<Eigen::Vector3d> around = ring(0.05, 0.0);
  for (auto& p : around) p = T * p;
  OrientedBox b = box(0.05, 0.008);
  b.centre = T * b.centre;
  b.rotation = T.rotation();
  SupportClosureInfo info;
  ASSERT_TRUE(support_closure_view({v}, around, b, 0.002, SupportClosureParams(), &info)) << info.reason;
  EXPECT_NEAR(info.normal.dot(T.rotation().col(2)), 1.0, 1e-6);
}

TEST(SupportClosure, LegsOnTheFloorAreNotClosed) {
  // A table's view from above: its top at 0.7 m and, seen past it, four leg ends on the floor at
  // the corners (small squares 5 mm up). The hull of the contacts would be the table's whole
  // footprint; the contacts touch its boundary at the corners only.
  FusionView v = top_view(0.3, 0.7);
  const double d_leg = 1.0 - 0.005;
  for (int y = 0; y < v.camera.height; ++y) {
    for (int x = 0; x < v.camera.width; ++x) {
      const Eigen::Vector3d p = v.T_wc * v.camera.back_project(x, y, d_leg);
      const bool leg = std::abs(std::abs(p.x()) - 0.2) < 0.02 && std::abs(std::abs(p.y()) - 0.2) < 0.02;
      if (leg) v.depth[y * v.camera.width + x] = static_cast<float>(d_leg);
    }
  }
  SupportClosureInfo info;
  EXPECT_FALSE(support_closure_view({v}, ring(0.22, 0.0), box(0.22, 0.7), 0.005,
                                    SupportClosureParams(), &info));
  EXPECT_STREQ(info.reason, "the contacts do not outline a footprint (legs?)");
  EXPECT_LT(info.rim_coverage, 0.5);
}

TEST(SupportClosure, NoFaceIsClosedWithoutASupport) {
  SupportClosureInfo info;
  // The object floats 10 cm above the plane.
  EXPECT_FALSE(support_closure_view({top_view(0.05, 0.10)}, ring(0.05, 0.0), box(0.05, 0.10), 0.002,
                                    SupportClosureParams(), &info));
  EXPECT_STREQ(info.reason, "the object does not reach the plane");
  // Background without a plane: scattered points.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  std::vector<Eigen::Vector3d> scattered;
  for (int i = 0; i < 400; ++i) scattered.emplace_back(u(rng), u(rng), u(rng));
  EXPECT_FALSE(support_closure_view({top_view(0.05, 0.008)}, scattered, box(0.05, 0.008), 0.002,
                                    SupportClosureParams(), &info));
  EXPECT_STREQ(info.reason, "no plane in the background around it");
  // A plane through the object: a top at 5 cm and a lower step at 1 cm, the plane at 3 cm.
  FusionView two = top_view(0.05, 0.05);
  FusionView low = top_view(0.03, 0.01);  // a lower step of the same object
  EXPECT_FALSE(support_closure_view({two, low, low, low}, ring(0.05, 0.03), box(0.05, 0.05), 0.002,
                                    SupportClosureParams(), &info));
  EXPECT_STREQ(info.reason, "the plane cuts through the object");
  SupportClosureParams off;
  off.enabled = false;
  EXPECT_FALSE(support_closure_view({top_view(0.05, 0.008)}, ring(0.05, 0.0), box(0.05, 0.008),
                                    0.002, off, &info));
}

}  // namespace
}  // namespace dqo::mesh
