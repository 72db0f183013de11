// Pixel labels: instance images through a table; objects through ellipsoid and box, on a
// synthetic depth image of a sphere in front of a wall; overlapping claims go to the higher score.

#include <gtest/gtest.h>

#include <cmath>

#include "dqo_map/gaussians/pixel_labels.h"

namespace dqo::gs {
namespace {

TEST(PixelLabels, InstanceThroughTable) {
  InstanceImage inst(4, 2, 1);
  inst.data = {0, 1, 2, 3, 4, 1, 0, 9};
  // Detection index + 1 -> map object ID; detection 3 (value 4) was rejected (0).
  const std::vector<uint32_t> table = {0, 17, 5, 40, 0};
  const LabelImage labels = labels_from_instance(inst, table);
  const std::vector<uint32_t> expected = {0, 17, 5, 40, 0, 17, 0, 0};  // 9 is outside the table
  EXPECT_EQ(labels.data, expected);
  EXPECT_EQ(labels.width, 4);
  EXPECT_EQ(labels.height, 2);

  const LabelImage ids = labels_from_instance(inst);
  EXPECT_EQ(ids.data, std::vector<uint32_t>({0, 1, 2, 3, 4, 1, 0, 9}));
}

struct SphereScene {
  PinholeCamera camera;
  SE3 T_wc;
  Eigen::Vector3d centre_w;
  double radius = 0.3;
  DepthImage depth;
  std::vector<uint8_t> on_sphere;
};

// A camera somewhere in the world looking at a sphere 2 m ahead, a wall 4 m ahead (depth exact,
// computed per pixel from the ray), one pixel in 13 without a measurement.
SphereScene make_sphere_scene() {
  SphereScene s;
  s.camera.width = 80;
  s.camera.height = 60;
  s.camera.fx = s.camera.fy = 70.0;
  s.camera.cx = 39.5;
  s.camera.cy = 29.5;
  s.T_wc =
      SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.2, 1.0, -0.3).normalized())),
          Eigen::Vector3d(1.0, -0.5, 0.8));
  const Eigen::Vector3d c_c(0.1, -0.05, 2.0);
  s.centre_w = s.T_wc * c_c;
  s.depth = DepthImage(s.camera.width, s.camera.height, 1, 0.f);
  s.on_sphere.assign(s.depth.data.size(), 0);
  for (int v = 0; v < s.camera.height; ++v) {
    for (int u = 0; u < s.camera.width; ++u) {
      const size_t p = static_cast<size_t>(v) * s.camera.width + u;
      if (p % 13 == 0) continue;
      const Eigen::Vector3d d = s.camera.back_project(u, v, 1.0);  // z = 1 along the ray
      // |t d − c|² = r²: a t² − 2 b t + (|c|² − r²) = 0.
      const double a = d.squaredNorm(), b = d.dot(c_c),
                   cc = c_c.squaredNorm() - s.radius * s.radius;
      const double disc = b * b - a * cc;
      if (disc > 0.0) {
        s.depth.data[p] = static_cast<float>((b - std::sqrt(disc)) / a);
        s.on_sphere[p] = 1;
      } else {
        s.depth.data[p] = 4.f;
      }
    }
  }
  return s;
}

TEST(PixelLabels, EllipsoidAndBox) {
  const SphereScene s = make_sphere_scene();
  LabelledObject obj;
  obj.object_id = 7;
  obj.quadric = DualQuadric::from_params(s.centre_w, Eigen::Matrix3d::Identity(),
                                         Eigen::Vector3d::Constant(s.radius));
  obj.box = Box2d{0.0, 0.0, 80.0, 60.0};
  const LabelImage labels = labels_from_objects(s.depth, s.camera, s.T_wc, {obj});
  int on = 0;
  for (size_t p = 0; p < labels.data.size(); ++p) {
    if (s.on_sphere[p]) {
      ++on;
      EXPECT_EQ(labels.data[p], 7u) << p;
    } else {
      EXPECT_EQ(labels.data[p], 0u) << p;  // the wall, and pixels without depth
    }
  }
  EXPECT_GT(on, 100);

  // A box over the left half only: sphere pixels right of it stay unlabelled.
  obj.box = Box2d{0.0, 0.0, 40.0, 60.0};
  const LabelImage half = labels_from_objects(s.depth, s.camera, s.T_wc, {obj});
  for (int v = 0; v < 60; ++v) {
    for (int u = 0; u < 80; ++u) {
      const size_t p = static_cast<size_t>(v) * 80 + u;
      EXPECT_EQ(half.data[p], (s.on_sphere[p] && u <= 40) ? 7u : 0u) << u << "," << v;
    }
  }

  // An ellipsoid too small to hold the surface even scaled by 1.2 labels nothing ...
  obj.box = Box2d{0.0, 0.0, 80.0, 60.0};
  obj.quadric = DualQuadric::from_params(s.centre_w, Eigen::Matrix3d::Identity(),
                                         Eigen::Vector3d::Constant(0.2));
  const LabelImage small = labels_from_objects(s.depth, s.camera, s.T_wc, {obj});
  for (const uint32_t l : small.data) EXPECT_EQ(l, 0u);
  // ... and holds it once scaled by 1.6.
  ObjectLabelParams params;
  params.ellipsoid_scale = 1.6;
  const LabelImage scaled = labels_from_objects(s.depth, s.camera, s.T_wc, {obj}, params);
  for (size_t p = 0; p < scaled.data.size(); ++p) {
    if (s.on_sphere[p]) {
      EXPECT_EQ(scaled.data[p], 7u);
    }
  }
}

TEST(PixelLabels, OverlappingClaimsGoToTheHigherScore) {
  const SphereScene s = make_sphere_scene();
  LabelledObject a, b;
  a.object_id = 3;
  b.object_id = 4;
  a.quadric = b.quadric = DualQuadric::from_params(s.centre_w, Eigen::Matrix3d::Identity(),
                                                   Eigen::Vector3d::Constant(s.radius));
  a.box = Box2d{0.0, 0.0, 50.0, 60.0};
  b.box = Box2d{30.0, 0.0, 80.0, 60.0};
  a.score = 0.6f;
  b.score = 0.9f;
  for (const bool swap : {false, true}) {
    const std::vector<LabelledObject> objects =
        swap ? std::vector<LabelledObject>{b, a} : std::vector<LabelledObject>{a, b};
    const LabelImage labels = labels_from_objects(s.depth, s.camera, s.T_wc, objects);
    for (int v = 0; v < 60; ++v) {
      for (int u = 0; u < 80; ++u) {
        const size_t p = static_cast<size_t>(v) * 80 + u;
        uint32_t expected = 0;
        if (s.on_sphere[p]) expected = u >= 30 ? 4u : 3u;  // b (0.9) wins where both claim
        EXPECT_EQ(labels.data[p], expected) << u << "," << v << " swap " << swap;
      }
    }
  }
}

}  // namespace
}  // namespace dqo::gs
