#include "dqo_map/mesh/tsdf_fusion.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "dqo_map/mesh/recon_metrics.h"
#include "mesh_test_util.h"

namespace dqo::mesh {
namespace {

using test_util::Sphere;

const Eigen::Vector3d kCentre(0.5, -0.3, 1.2);
constexpr double kRadius = 0.1;
const Eigen::Vector3d kColour(0.8, 0.3, 0.2);

PinholeCamera small_camera() {
  PinholeCamera cam;
  cam.width = 120;
  cam.height = 90;
  cam.fx = cam.fy = 110.0;
  cam.cx = 59.5;
  cam.cy = 44.5;
  return cam;
}

// 14 views from all around, 0.4 m from the centre (the sphere fills about half the image).
std::vector<FusionView> render(const std::vector<Sphere>& spheres) {
  std::vector<FusionView> views;
  for (const SE3& T_wc : test_util::views_around(kCentre, 0.4, 14)) {
    views.push_back(test_util::render_spheres(small_camera(), T_wc, spheres, kColour));
  }
  return views;
}

OrientedBox box_around(const Eigen::Vector3d& centre, double half) {
  OrientedBox box;
  box.centre = centre;
  box.half_extents = Eigen::Vector3d::Constant(half);
  return box;
}

double distance_to_sphere(const Eigen::Vector3d& p, const Sphere& s) {
  return std::abs((p - s.centre).norm() - s.radius);
}

// Vertices within `radius` of `centre`.
int vertices_near(const TriangleMesh& m, const Eigen::Vector3d& centre, double radius) {
  int n = 0;
  for (const auto& v : m.vertices) n += (v - centre).norm() < radius;
  return n;
}

class TsdfSphere : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    views_ = new std::vector<FusionView>(render({{kCentre, kRadius}}));
    std::string error;
    auto fused = fuse_object(*views_, box_around(kCentre, kRadius), TsdfParams{}, &error);
    ASSERT_TRUE(fused) << error;
    mesh_ = new TriangleMesh(std::move(*fused));
  }
  static void TearDownTestSuite() {
    delete views_;
    delete mesh_;
  }
  static std::vector<FusionView>* views_;
  static TriangleMesh* mesh_;
};
std::vector<FusionView>* TsdfSphere::views_ = nullptr;
TriangleMesh* TsdfSphere::mesh_ = nullptr;

TEST_F(TsdfSphere, VerticesLieOnTheSphere) {
  ASSERT_NE(mesh_, nullptr);
  const double voxel = object_voxel_size(box_around(kCentre, kRadius), TsdfParams{});
  EXPECT_DOUBLE_EQ(voxel, 0.002);  // 20 cm across / 100 voxels
  ASSERT_GT(mesh_->vertices.size(), 1000u);
  std::vector<double> off;
  double signed_sum = 0.0;
  for (const auto& v : mesh_->vertices) {
    off.push_back(distance_to_sphere(v, {kCentre, kRadius}));
    signed_sum += (v - kCentre).norm() - kRadius;
  }
  std::sort(off.begin(), off.end());
  const double n = static_cast<double>(off.size());
  // Depth is sampled per pixel (~2.7 mm here, coarser than the voxel), so where a view grazes
  // the sphere a voxel reads the depth of a neighbouring ray: the worst vertex is about a voxel
  // off (1.02 measured), the bulk far closer (mean 0.16, 99th percentile 0.55 voxels).
  EXPECT_LT(off.back(), 1.25 * voxel) << "worst vertex " << off.back() / voxel << " voxels off";
  EXPECT_LT(off[off.size() * 99 / 100], 0.75 * voxel);
  EXPECT_LT(std::accumulate(off.begin(), off.end(), 0.0) / n, 0.25 * voxel);
  // No systematic offset (half a voxel would be a misplaced voxel centre): 0.012 measured.
  EXPECT_LT(std::abs(signed_sum / n), 0.05 * voxel);
}

TEST_F(TsdfSphere, MeshCoversTheSphere) {
  ASSERT_NE(mesh_, nullptr);
  ReconParams params;
  params.samples = 5000;
  std::string error;
  const auto m = evaluate_reconstruction(
      *mesh_, test_util::icosphere(kCentre, kRadius, 4), params, &error);
  ASSERT_TRUE(m) << error;
  // Sample spacing on the 0.126 m^2 sphere is ~5 mm: ~0.25 cm point-to-point for a perfect mesh.
  EXPECT_LT(m->completion_cm, 0.35);
  EXPECT_LT(m->accuracy_cm, 0.35);
  EXPECT_DOUBLE_EQ(m->comp_ratio_1cm, 100.0);
}

TEST_F(TsdfSphere, VertexColoursAreTheInputColour) {
  ASSERT_NE(mesh_, nullptr);
  ASSERT_EQ(mesh_->colours.size(), mesh_->vertices.size());
  for (const auto& c : mesh_->colours) {
    // 8-bit quantisation in the volume: within half a level plus rounding.
    EXPECT_LT((c - kColour).cwiseAbs().maxCoeff(), 0.6 / 255.0) << c.transpose();
  }
}

TEST_F(TsdfSphere, FuseViewsAtAGivenVoxelSize) {
  ASSERT_NE(views_, nullptr);
  std::string error;
  const double voxel = 0.005;
  const auto mesh = fuse_views(*views_, voxel, TsdfParams{}, &error);
  ASSERT_TRUE(mesh) << error;
  ASSERT_GT(mesh->vertices.size(), 100u);
  for (const auto& v : mesh->vertices) {
    EXPECT_LT(distance_to_sphere(v, {kCentre, kRadius}), voxel);
  }
}

TEST(TsdfFusion, LargestComponentDropsASeparateBlob) {
  // A 2 cm blob 5 cm clear of the sphere, inside the object's (generous) box.
  const Sphere blob{kCentre + Eigen::Vector3d(0.12, 0.12, 0.0), 0.02};
  const auto views = render({{kCentre, kRadius}, blob});
  const OrientedBox box = box_around(kCentre, 0.15);
  std::string error;

  TsdfParams keep_all;
  keep_all.largest_component = false;
  const auto both = fuse_object(views, box, keep_all, &error);
  ASSERT_TRUE(both) << error;
  EXPECT_GT(vertices_near(*both, blob.centre, blob.radius + 0.01), 50);

  const auto largest = fuse_object(views, box, TsdfParams{}, &error);
  ASSERT_TRUE(largest) << error;
  EXPECT_EQ(vertices_near(*largest, blob.centre, blob.radius + 0.01), 0);
  // The sphere itself is untouched: the same vertices near it in both meshes.
  const int sphere_both = vertices_near(*both, kCentre, kRadius + 0.01);
  EXPECT_GT(sphere_both, 1000);
  EXPECT_EQ(vertices_near(*largest, kCentre, kRadius + 0.01), sphere_both);
  ASSERT_EQ(largest->colours.size(), largest->vertices.size());
}

TEST(TsdfFusion, CropRemovesSurfaceOutsideTheObjectBox) {
  const Sphere outside{kCentre + Eigen::Vector3d(0.0, 0.0, 0.2), 0.03};
  const auto views = render({{kCentre, kRadius}, outside});
  const OrientedBox box = box_around(kCentre, kRadius);
  std::string error;

  TsdfParams no_crop;
  no_crop.largest_component = false;
  no_crop.crop_margin = -1.0;
  const auto uncropped = fuse_object(views, box, no_crop, &error);
  ASSERT_TRUE(uncropped) << error;
  EXPECT_GT(vertices_near(*uncropped, outside.centre, outside.radius + 0.01), 50);

  TsdfParams crop = no_crop;
  crop.crop_margin = 0.1;
  const auto cropped = fuse_object(views, box, crop, &error);
  ASSERT_TRUE(cropped) << error;
  const OrientedBox crop_box = object_crop_box(box, crop);
  EXPECT_NEAR(crop_box.half_extents.x(), kRadius + 0.02, 1e-12);  // 10 % of the 20 cm extent
  for (const auto& v : cropped->vertices) EXPECT_TRUE(contains(crop_box, v));
  EXPECT_EQ(vertices_near(*cropped, outside.centre, outside.radius + 0.01), 0);
}

TEST(TsdfFusion, VoxelSizeIsScaledToTheBoxAndClamped) {
  const TsdfParams params;
  EXPECT_DOUBLE_EQ(object_voxel_size(box_around(kCentre, 0.5), params), 0.01);
  EXPECT_DOUBLE_EQ(object_voxel_size(box_around(kCentre, 0.01), params), params.min_voxel);
  EXPECT_DOUBLE_EQ(object_voxel_size(box_around(kCentre, 10.0), params), params.max_voxel);
  // Thin boxes grow by at least two voxels, so a flat object keeps its surface.
  OrientedBox thin = box_around(kCentre, 0.001);
  EXPECT_NEAR(object_crop_box(thin, params).half_extents.x(), 0.001 + 2 * params.min_voxel,
              1e-12);
}

TEST(TsdfFusion, RejectsBadInput) {
  const OrientedBox box = box_around(kCentre, kRadius);
  std::string error;
  EXPECT_FALSE(fuse_object({}, box, TsdfParams{}, &error));
  EXPECT_NE(error.find("no views"), std::string::npos) << error;

  const FusionView good = test_util::render_spheres(
      small_camera(), test_util::look_at(kCentre + Eigen::Vector3d(0, 0, 0.4), kCentre),
      {{kCentre, kRadius}}, kColour);

  FusionView short_depth = good;
  short_depth.depth.pop_back();
  EXPECT_FALSE(fuse_object({good, short_depth}, box, TsdfParams{}, &error));
  EXPECT_NE(error.find("fusion view 1: depth has"), std::string::npos) << error;

  FusionView short_rgb = good;
  short_rgb.rgb.resize(good.depth.size());
  EXPECT_FALSE(fuse_object({short_rgb}, box, TsdfParams{}, &error));
  EXPECT_NE(error.find("rgb has"), std::string::npos) << error;

  FusionView no_pixels = good;
  no_pixels.camera.width = 0;
  EXPECT_FALSE(fuse_object({no_pixels}, box, TsdfParams{}, &error));
  EXPECT_NE(error.find("no pixels"), std::string::npos) << error;

  FusionView empty = good;
  std::fill(empty.depth.begin(), empty.depth.end(), 0.0f);
  empty.depth[0] = std::nanf("");
  EXPECT_FALSE(fuse_object({empty}, box, TsdfParams{}, &error));
  EXPECT_NE(error.find("no surface fused"), std::string::npos) << error;

  // Surface that lies wholly outside the object's box is "no surface fused" after the crop.
  EXPECT_FALSE(fuse_object({good}, box_around(kCentre + Eigen::Vector3d(1, 0, 0), 0.05),
                           TsdfParams{}, &error));
  EXPECT_NE(error.find("no surface fused"), std::string::npos) << error;

  EXPECT_FALSE(fuse_views({good}, 0.0, TsdfParams{}, &error));
  EXPECT_NE(error.find("voxel size"), std::string::npos) << error;

  OrientedBox nan_box = box;
  nan_box.centre.x() = std::nan("");
  EXPECT_FALSE(fuse_object({good}, nan_box, TsdfParams{}, &error));
  EXPECT_NE(error.find("object box"), std::string::npos) << error;
}

}  // namespace
}  // namespace dqo::mesh
