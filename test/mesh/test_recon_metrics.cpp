#include "dqo_map/mesh/recon_metrics.h"

#include <gtest/gtest.h>

#include <cmath>

#include "mesh_test_util.h"

namespace dqo::mesh {
namespace {

using test_util::icosphere;
using test_util::merged;
using test_util::plane_patch;

ReconMetrics evaluate_ok(const TriangleMesh& rec, const TriangleMesh& gt,
                         const ReconParams& params = {}) {
  std::string error;
  const auto m = evaluate_reconstruction(rec, gt, params, &error);
  EXPECT_TRUE(m.has_value()) << error;
  return m.value_or(ReconMetrics{});
}

OrientedBox cube_box(const Eigen::Vector3d& centre, double half) {
  OrientedBox box;
  box.centre = centre;
  box.half_extents = Eigen::Vector3d::Constant(half);
  return box;
}

TEST(ReconMetrics, MeshAgainstItselfScoresNearZero) {
  const TriangleMesh sphere = icosphere(Eigen::Vector3d(0.3, -0.2, 1.0), 0.1, 3);
  const ReconMetrics m = evaluate_ok(sphere, sphere);
  // Independent samples of the same surface: distances are about half the sample spacing
  // (sqrt(0.126 m^2 / 10k) ~ 3.5 mm), far below 1 cm.
  EXPECT_LT(m.accuracy_cm, 0.2);
  EXPECT_LT(m.completion_cm, 0.2);
  EXPECT_DOUBLE_EQ(m.comp_ratio_1cm, 100.0);
  EXPECT_DOUBLE_EQ(m.comp_ratio_5cm, 100.0);
  EXPECT_EQ(m.rec_points, 10000);
  EXPECT_EQ(m.gt_points, 10000);
}

// A 20 cm square shifted along its normal by d: every point's nearest surface point is straight
// across, at exactly d; the sampled nearest point is at sqrt(d^2 + l^2) with l the lateral gap to
// the nearest sample (~1 mm at 25 samples per cm^2).
TEST(ReconMetrics, PlaneShiftedAlongNormalByHalfACentimetre) {
  const TriangleMesh gt = plane_patch(0.2, 8, 0.0);
  const TriangleMesh rec = plane_patch(0.2, 8, 0.005);
  const ReconMetrics m = evaluate_ok(rec, gt);
  EXPECT_GE(m.accuracy_cm, 0.5 - 1e-9);
  EXPECT_GE(m.completion_cm, 0.5 - 1e-9);
  EXPECT_NEAR(m.accuracy_cm, 0.5, 0.05);
  EXPECT_NEAR(m.completion_cm, 0.5, 0.05);
  EXPECT_DOUBLE_EQ(m.comp_ratio_1cm, 100.0);
  EXPECT_DOUBLE_EQ(m.comp_ratio_5cm, 100.0);
}

TEST(ReconMetrics, PlaneShiftedAlongNormalByTwoCentimetres) {
  const TriangleMesh gt = plane_patch(0.2, 8, 0.0);
  const TriangleMesh rec = plane_patch(0.2, 8, -0.02);
  const ReconMetrics m = evaluate_ok(rec, gt);
  EXPECT_NEAR(m.accuracy_cm, 2.0, 0.05);
  EXPECT_NEAR(m.completion_cm, 2.0, 0.05);
  EXPECT_DOUBLE_EQ(m.comp_ratio_1cm, 0.0);
  EXPECT_DOUBLE_EQ(m.comp_ratio_5cm, 100.0);
}

// Concentric spheres of radii r and r + d: the surfaces are exactly d apart everywhere, so no
// sampled distance can be below d (up to the facets' chordal error, ~1e-3 mm here).
TEST(ReconMetrics, ConcentricSpheresAreTheirRadialGapApart) {
  const Eigen::Vector3d c(-1.0, 2.0, 0.5);
  const double d = 0.03;
  const TriangleMesh gt = icosphere(c, 0.1, 4);
  const TriangleMesh rec = icosphere(c, 0.1 + d, 4);
  const ReconMetrics m = evaluate_ok(rec, gt);
  EXPECT_GE(m.accuracy_cm, 100.0 * d - 0.01);
  EXPECT_GE(m.completion_cm, 100.0 * d - 0.01);
  EXPECT_NEAR(m.accuracy_cm, 100.0 * d, 0.05);
  EXPECT_NEAR(m.completion_cm, 100.0 * d, 0.05);
  EXPECT_DOUBLE_EQ(m.comp_ratio_1cm, 0.0);
  EXPECT_DOUBLE_EQ(m.comp_ratio_5cm, 100.0);
}

TEST(ReconMetrics, CropToTheGroundTruthBoxIgnoresSurfaceOutsideIt) {
  const Eigen::Vector3d c(0.0, 0.0, 1.0);
  const TriangleMesh gt = icosphere(c, 0.1, 3);
  const TriangleMesh rec_alone = icosphere(c, 0.105, 3);
  // A far-away blob holding about 1/5 of the reconstruction's area.
  const TriangleMesh rec = merged(rec_alone, icosphere(c + Eigen::Vector3d(1.0, 0, 0), 0.05, 3));

  ReconParams cropped;
  cropped.crop_box = cube_box(c, 0.1);
  const ReconMetrics alone = evaluate_ok(rec_alone, gt);
  const ReconMetrics with_blob_cropped = evaluate_ok(rec, gt, cropped);
  const ReconMetrics with_blob = evaluate_ok(rec, gt);

  EXPECT_NEAR(with_blob_cropped.accuracy_cm, alone.accuracy_cm, 0.03);
  EXPECT_NEAR(with_blob_cropped.completion_cm, alone.completion_cm, 0.03);
  EXPECT_EQ(with_blob_cropped.rec_points, 10000);  // sampled inside the box, not thinned
  // Uncropped, ~20 % of the points lie ~1 m from the ground truth: accuracy grows by ~18 cm.
  EXPECT_GT(with_blob.accuracy_cm, alone.accuracy_cm + 10.0);
}

TEST(ReconMetrics, CropIsEnlargedByOneOverPointNine) {
  const Eigen::Vector3d c = Eigen::Vector3d::Zero();
  const TriangleMesh gt = icosphere(c, 0.1, 3);
  // A sphere of radius 0.105 pokes out of a box of half extent 0.1 but not of 0.1 / 0.9.
  const TriangleMesh rec = icosphere(c, 0.105, 3);
  ReconParams params;
  params.crop_box = cube_box(c, 0.1);
  const ReconMetrics enlarged = evaluate_ok(rec, gt, params);
  params.crop_scale = 1.0;
  const ReconMetrics tight = evaluate_ok(rec, gt, params);
  // Tight, the caps beyond the box are cut off: the ground truth's poles lose their partner.
  EXPECT_LT(tight.comp_ratio_1cm, 99.0);
  EXPECT_DOUBLE_EQ(enlarged.comp_ratio_1cm, 100.0);
}

TEST(ReconMetrics, DeterministicForASeed) {
  const TriangleMesh gt = icosphere(Eigen::Vector3d::Zero(), 0.1, 2);
  const TriangleMesh rec = icosphere(Eigen::Vector3d(0.003, 0, 0), 0.1, 2);
  ReconParams params;
  params.seed = 42;
  const ReconMetrics a = evaluate_ok(rec, gt, params);
  const ReconMetrics b = evaluate_ok(rec, gt, params);
  EXPECT_EQ(a.accuracy_cm, b.accuracy_cm);
  EXPECT_EQ(a.completion_cm, b.completion_cm);
  EXPECT_EQ(a.comp_ratio_1cm, b.comp_ratio_1cm);
  params.seed = 43;
  const ReconMetrics c = evaluate_ok(rec, gt, params);
  EXPECT_NE(a.accuracy_cm, c.accuracy_cm);
  EXPECT_NEAR(a.accuracy_cm, c.accuracy_cm, 0.05);
}

// Uniform by area: two triangles of areas 1 and 3 (in units of 0.5 m^2) get points in that
// ratio, and every point lies on its triangle.
TEST(SampleSurface, UniformByArea) {
  TriangleMesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {5, 0, 1}, {8, 0, 1}, {5, 1, 1}};
  m.triangles = {{0, 1, 2}, {3, 4, 5}};
  const int n = 40000;
  const auto points = sample_surface(m, n, 7);
  ASSERT_EQ(static_cast<int>(points.size()), n);
  int in_small = 0;
  Eigen::Vector2d centroid_small = Eigen::Vector2d::Zero();
  for (const Eigen::Vector3d& p : points) {
    if (p.z() == 0.0) {
      ++in_small;
      EXPECT_GE(p.x(), -1e-12);
      EXPECT_GE(p.y(), -1e-12);
      EXPECT_LE(p.x() + p.y(), 1.0 + 1e-12);
      centroid_small += p.head<2>();
    } else {
      EXPECT_DOUBLE_EQ(p.z(), 1.0);
      EXPECT_GE(p.x(), 5.0 - 1e-12);
      EXPECT_LE((p.x() - 5.0) / 3.0 + p.y(), 1.0 + 1e-12);
    }
  }
  // Binomial(n, 1/4): standard deviation ~87 points.
  EXPECT_NEAR(in_small, n / 4, 450);
  // Uniform within the triangle: the mean is the centroid (1/3, 1/3), sd ~0.0025 per coordinate.
  centroid_small /= in_small;
  EXPECT_NEAR(centroid_small.x(), 1.0 / 3.0, 0.01);
  EXPECT_NEAR(centroid_small.y(), 1.0 / 3.0, 0.01);
}

TEST(SampleSurface, CropKeepsOnlyPointsInsideTheBox) {
  const TriangleMesh plane = plane_patch(1.0, 4, 0.0);
  OrientedBox box;
  box.centre = Eigen::Vector3d(0.1, 0.0, 0.0);
  box.rotation = Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  box.half_extents = Eigen::Vector3d(0.1, 0.05, 0.01);
  const auto points = sample_surface(plane, 2000, 3, &box);
  ASSERT_EQ(points.size(), 2000u);
  for (const Eigen::Vector3d& p : points) EXPECT_TRUE(contains(box, p)) << p.transpose();
}

TEST(ReconMetrics, Errors) {
  const TriangleMesh sphere = icosphere(Eigen::Vector3d::Zero(), 0.1, 1);
  std::string error;
  EXPECT_FALSE(evaluate_reconstruction(TriangleMesh{}, sphere, {}, &error));
  EXPECT_NE(error.find("reconstructed mesh is empty"), std::string::npos) << error;
  EXPECT_FALSE(evaluate_reconstruction(sphere, TriangleMesh{}, {}, &error));
  EXPECT_NE(error.find("ground-truth mesh is empty"), std::string::npos) << error;

  ReconParams far;
  far.crop_box = cube_box(Eigen::Vector3d(5, 5, 5), 0.1);
  EXPECT_FALSE(evaluate_reconstruction(sphere, sphere, far, &error));
  EXPECT_NE(error.find("cropped away"), std::string::npos) << error;

  ReconParams none;
  none.samples = 0;
  EXPECT_FALSE(evaluate_reconstruction(sphere, sphere, none, &error));

  TriangleMesh bad = sphere;
  bad.triangles.push_back({0, 1, 999});
  EXPECT_FALSE(evaluate_reconstruction(bad, sphere, {}, &error));
  EXPECT_NE(error.find("index"), std::string::npos) << error;

  TriangleMesh flat;  // a triangle with no area
  flat.vertices = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}};
  flat.triangles = {{0, 1, 2}};
  EXPECT_FALSE(evaluate_reconstruction(flat, sphere, {}, &error));
  EXPECT_NE(error.find("no area"), std::string::npos) << error;
}

}  // namespace
}  // namespace dqo::mesh
