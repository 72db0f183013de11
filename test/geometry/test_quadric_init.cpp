#include "dqo_map/geometry/quadric_init.h"

#include <gtest/gtest.h>

#include "geometry_checks.h"

namespace dqo {
namespace {

TEST(QuadricInit, NoiseFreeViewsRecoverTheEllipsoid) {
  // Seeds 1..12 cover 3 to 8 views twice.
  for (uint64_t seed = 1; seed <= 12; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    EXPECT_LE(checks::init_noise_free_error(seed), checks::kNoiseFreeInitTolerance);
  }
}

TEST(QuadricInit, TwoPixelNoiseTenViewsCentreWithinTwoPercent) {
  for (uint64_t seed = 1; seed <= 20; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    EXPECT_LE(checks::init_noisy_centre_error(seed), checks::kNoisyCentreTolerance);
  }
}

TEST(QuadricInit, DegenerateInputsFailWithTheirOwnStatus) {
  // Seed 733: cameras at one place whose rays meet (to round-off) at the cameras, which once made
  // the baseline / distance ratio 0/0 and let the case through.
  for (uint64_t seed : {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 733}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    EXPECT_EQ(checks::init_degenerate_failures(seed), 0.0);
  }
}

// The same three failures spelled out, with their messages.
TEST(QuadricInit, FailureMessages) {
  std::mt19937_64 rng(7);
  const PinholeCamera cam = checks::test_camera();
  const DualQuadric q = checks::random_quadric(rng);
  std::vector<BoxObservation> obs = checks::to_observations(checks::random_views(rng, q, cam, 5), cam);
  ASSERT_EQ(obs.size(), 5u);

  QuadricInitResult r = initialise_from_boxes({obs[0], obs[1]});
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.status, InitStatus::kTooFewViews);
  EXPECT_NE(r.error.find("at least 3 views"), std::string::npos) << r.error;

  // Two edges of every box at the border leave 2 x 5 = 10 planes: still enough.
  std::vector<BoxObservation> half = obs;
  for (BoxObservation& o : half) {
    o.box.x_min = 2.0;
    o.box.y_min = 1.0;
  }
  r = initialise_from_boxes(half);
  EXPECT_NE(r.status, InitStatus::kBoxesTouchBorder) << r.error;
  EXPECT_EQ(r.num_planes, 10);
  // Three edges at the border leave 5 planes: too few, and the message says why.
  for (BoxObservation& o : half) o.box.x_max = 639.0;
  r = initialise_from_boxes(half);
  EXPECT_EQ(r.status, InitStatus::kBoxesTouchBorder);
  EXPECT_NE(r.error.find("boxes touch the image border"), std::string::npos) << r.error;

  // Five copies of one view: one place.
  r = initialise_from_boxes({obs[0], obs[0], obs[0], obs[0], obs[0]});
  EXPECT_EQ(r.status, InitStatus::kDegenerateGeometry);
  EXPECT_NE(r.error.find("degenerate geometry"), std::string::npos) << r.error;

  std::vector<BoxObservation> broken = obs;
  broken[1].box = Box2d{10, 10, 5, 20};
  EXPECT_EQ(initialise_from_boxes(broken).status, InitStatus::kInvalidInput);

  r = initialise_from_boxes(obs);
  EXPECT_TRUE(r.ok) << r.error;
  EXPECT_TRUE(r.error.empty());
  EXPECT_LT(r.mean_edge_error_px, 1e-6);
  EXPECT_GT(r.baseline_ratio, 0.05);
}

TEST(QuadricInit, SingleViewFromDepth) {
  for (uint64_t seed = 1; seed <= 12; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    EXPECT_LE(checks::depth_init_error(seed), checks::kDepthInitToleranceM);
  }
}

TEST(QuadricInit, SingleViewFrontoParallelByHand) {
  // A plane at 2 m filling the box [200, 300) x [100, 180): 100 x 80 px, lateral semi-axes at the
  // front 0.190 and 0.152 m. No spread, so the depth semi-axis is its floor, half the smaller
  // lateral one (0.0762 m), and the centre lies that far behind the plane.
  const PinholeCamera cam = checks::test_camera();
  std::vector<float> depth(640 * 480, std::nanf(""));
  for (int v = 100; v < 180; ++v) {
    for (int u = 200; u < 300; ++u) depth[v * 640 + u] = 2.0f;
  }
  const Box2d box{200, 100, 300, 180};
  const QuadricInitResult r = initialise_from_depth(box, cam, SE3::identity(), DepthView{depth.data(), 640, 480});
  ASSERT_TRUE(r.ok) << r.error;
  // 8000 pixels over a budget of 1500: every second column of every second row.
  EXPECT_EQ(r.num_depth_samples, 50 * 40);
  const double c = 0.5 * (0.5 * 80.0 / 525.0 * 2.0);
  const double z = 2.0 + c;
  EXPECT_NEAR(r.quadric.centre().x(), (250.0 - 319.5) / 525.0 * z, 1e-9);
  EXPECT_NEAR(r.quadric.centre().y(), (140.0 - 239.5) / 525.0 * z, 1e-9);
  EXPECT_NEAR(r.quadric.centre().z(), z, 1e-9);
  EXPECT_NEAR(r.quadric.semi_axes().x(), 50.0 * z / 525.0, 1e-9);
  EXPECT_NEAR(r.quadric.semi_axes().y(), 40.0 * z / 525.0, 1e-9);
  EXPECT_NEAR(r.quadric.semi_axes().z(), c, 1e-9);
  EXPECT_TRUE(r.quadric.is_valid());

  // A box over invalid depth only.
  const QuadricInitResult none =
      initialise_from_depth(Box2d{400, 300, 500, 400}, cam, SE3::identity(), DepthView{depth.data(), 640, 480});
  EXPECT_FALSE(none.ok);
  EXPECT_EQ(none.status, InitStatus::kNoValidDepth);
}

TEST(QuadricInit, SingleViewThinObjectInFrontOfWallByHand) {
  // A bottle at 1.5 m, columns [234, 267) of the box [200, 300) x [100, 260), a wall at 3 m behind
  // the rest: two thirds of the box are wall, so the median depth in the box (the released code's
  // rule) is the wall's. The front is the bottle (it covers most of the box's centre); the wall is
  // beyond its reach (1.5 m + 2 × 0.229 m); the bottle's front is flat, so the depth semi-axis is
  // half the smaller lateral one: 0.5 × 0.5 × 100 / 525 × 1.5 m.
  const PinholeCamera cam = checks::test_camera();
  std::vector<float> depth(640 * 480, 3.0f);
  for (int v = 100; v < 260; ++v) {
    for (int u = 234; u < 267; ++u) depth[v * 640 + u] = 1.5f;
  }
  const Box2d box{200, 100, 300, 260};
  const QuadricInitResult r = initialise_from_depth(box, cam, SE3::identity(), DepthView{depth.data(), 640, 480});
  ASSERT_TRUE(r.ok) << r.error;
  const double c = 0.5 * (0.5 * 100.0 / 525.0 * 1.5);
  const double z = 1.5 + c;
  EXPECT_NEAR(r.quadric.centre().x(), (250.0 - 319.5) / 525.0 * z, 1e-9);
  EXPECT_NEAR(r.quadric.centre().y(), (180.0 - 239.5) / 525.0 * z, 1e-9);
  EXPECT_NEAR(r.quadric.centre().z(), z, 1e-9);
  EXPECT_NEAR(r.quadric.semi_axes().x(), 50.0 * z / 525.0, 1e-9);
  EXPECT_NEAR(r.quadric.semi_axes().y(), 80.0 * z / 525.0, 1e-9);
  EXPECT_NEAR(r.quadric.semi_axes().z(), c, 1e-9);
  // The ellipsoid ends in front of the wall, not on it.
  EXPECT_LT(r.quadric.centre().z() + r.quadric.semi_axes().z(), 2.0);

  // A bottle with depth (a step 10 cm deeper over its right half): the depth semi-axis is the step.
  for (int v = 100; v < 260; ++v) {
    for (int u = 250; u < 267; ++u) depth[v * 640 + u] = 1.6f;
  }
  const QuadricInitResult deep = initialise_from_depth(box, cam, SE3::identity(), DepthView{depth.data(), 640, 480});
  ASSERT_TRUE(deep.ok) << deep.error;
  const double step = static_cast<double>(1.6f) - static_cast<double>(1.5f);
  EXPECT_NEAR(deep.quadric.semi_axes().z(), step, 1e-9);
  EXPECT_NEAR(deep.quadric.centre().z(), 1.5 + step, 1e-9);
}

}  // namespace
}  // namespace dqo
