// Sensor noise and simulated detections: statistics close to their parameters, determinism.

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <memory>

#include "dqo_map/sim/detections.h"
#include "dqo_map/sim/noise.h"
#include "dqo_map/sim/renderer.h"
#include "sim_test_utils.h"

namespace dqo::sim {
namespace {

using testing::empty_scene;
using testing::make_object;

// A camera looking along +z at a wall facing it at distance z.
Scene wall_scene(double z) {
  Scene scene = empty_scene(200, 150, 150.0, SE3());
  scene.background.push_back(make_object(0, std::make_shared<Quad>(Eigen::Vector2d(100, 100)),
                                         SE3(Eigen::Quaterniond::Identity(), {0, 0, z})));
  scene.noise.enabled = true;
  return scene;
}

TEST(SensorNoise, DepthSigmaGrowsWithTheSquareOfDepth) {
  const Scene scene = wall_scene(2.0);
  const Frame f = Renderer(scene, 2).render(0, true);
  double sum = 0.0, sum2 = 0.0;
  int n = 0;
  for (const float d : f.depth.data) {
    ASSERT_GT(d, 0.0f);  // a flat wall has no edges: no holes
    sum += d - 2.0;
    sum2 += (d - 2.0) * (d - 2.0);
    ++n;
  }
  const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
  // 1.5 mm * 2^2 = 6 mm; 30000 samples: the standard error of sd is ~0.4 %.
  EXPECT_NEAR(sd, 0.006, 0.0003);
  EXPECT_NEAR(mean, 0.0, 0.0002);
}

TEST(SensorNoise, NoReturnBeyondMaxDepth) {
  const Frame f = Renderer(wall_scene(5.5), 2).render(0, true);
  for (const float d : f.depth.data) ASSERT_EQ(d, 0.0f);
  const Frame g = Renderer(wall_scene(5.5), 2).render(0, false);  // --no-noise: full range
  for (const float d : g.depth.data) ASSERT_GT(d, 5.0f);
}

TEST(SensorNoise, HolesOnTheFarSideOfDepthEdges) {
  Scene scene = wall_scene(3.0);
  scene.objects.push_back(make_object(1, std::make_shared<Box>(Eigen::Vector3d(0.6, 0.6, 0.2)),
                                      SE3(Eigen::Quaterniond::Identity(), {0, 0, 1.5})));
  const Frame clean = Renderer(scene, 2).render(0, false);
  const Frame noisy = Renderer(scene, 2).render(0, true);
  int edge = 0, edge_holes = 0, interior_holes = 0;
  for (int v = 1; v + 1 < 150; ++v) {
    for (int u = 1; u + 1 < 200; ++u) {
      const float z = clean.depth.at(u, v);
      bool near_edge = false;
      for (int dv = -1; dv <= 1; ++dv) {
        for (int du = -1; du <= 1; ++du) near_edge |= z - clean.depth.at(u + du, v + dv) > 0.1f;
      }
      const bool hole = noisy.depth.at(u, v) == 0.0f;
      if (near_edge) {
        ++edge;
        edge_holes += hole;
      } else {
        interior_holes += hole;
      }
    }
  }
  EXPECT_GT(edge, 100);
  EXPECT_NEAR(static_cast<double>(edge_holes) / edge, 0.8, 0.08);
  EXPECT_EQ(interior_holes, 0);
}

TEST(SensorNoise, RgbNoiseHasTheGivenSigma) {
  Scene scene = wall_scene(2.0);
  scene.lighting.ambient = Eigen::Vector3f::Constant(1.0f);
  scene.background[0].material.colour_a = Eigen::Vector3f::Constant(0.5f);  // 127.5 -> 128
  scene.noise.sensor.rgb_sigma = 4.0;
  const Frame f = Renderer(scene, 2).render(0, true);
  double sum = 0.0, sum2 = 0.0;
  for (const uint8_t c : f.rgb.data) {
    sum += c - 128.0;
    sum2 += (c - 128.0) * (c - 128.0);
  }
  const double n = static_cast<double>(f.rgb.data.size());
  const double sd = std::sqrt(sum2 / n - (sum / n) * (sum / n));
  // Rounding to integers adds 1/12 to the variance.
  EXPECT_NEAR(sd, std::sqrt(16.0 + 1.0 / 12.0), 0.1);
}

// A frame with four large, fully visible objects.
Frame four_objects(int index) {
  Frame f;
  f.index = index;
  for (uint32_t id = 1; id <= 4; ++id) {
    FrameObject o;
    o.id = id;
    o.box = Box2d{100.0 * id, 100.0, 100.0 * id + 60.0, 180.0};
    o.visible_fraction = 1.0;
    f.objects.push_back(o);
  }
  return f;
}

DetectionContext context() {
  DetectionContext ctx;
  ctx.width = 640;
  ctx.height = 480;
  ctx.class_names = {{1, "a"}, {2, "b"}, {3, "c"}, {4, "d"}, {5, "e"}};
  for (uint32_t id = 1; id <= 4; ++id) ctx.class_of_object[id] = static_cast<int>(id);
  return ctx;
}

TEST(Detections, RatesMatchTheirParameters) {
  const DetectionNoiseParams params;  // 10 % misses, 5 % false positives, 2 % confusions, 3 px
  const DetectionContext ctx = context();
  const int frames = 5000;
  int objects = 0, found = 0, false_pos = 0, confused = 0;
  double jitter2 = 0.0;
  int jitter_n = 0;
  for (int i = 0; i < frames; ++i) {
    const Frame f = four_objects(i);
    for (const Detection2d& d : simulate_detections(f, ctx, params, true, 42)) {
      if (d.gt_id == 0) {
        ++false_pos;
        EXPECT_TRUE(ctx.class_names.count(d.class_id));
        continue;
      }
      ++found;
      confused += d.class_id != static_cast<int>(d.gt_id);
      EXPECT_EQ(d.class_name, ctx.class_names.at(d.class_id));
      EXPECT_GE(d.score, 0.5f);
      EXPECT_LE(d.score, 1.0f);
      const Box2d& truth = f.objects[d.gt_id - 1].box;
      jitter2 += std::pow(d.box.x_min - truth.x_min, 2) + std::pow(d.box.y_max - truth.y_max, 2);
      jitter_n += 2;
    }
    objects += 4;
  }
  // 20000 objects: binomial standard errors 0.2 %, 0.15 %, 0.1 %.
  EXPECT_NEAR(1.0 - static_cast<double>(found) / objects, 0.10, 0.01);
  EXPECT_NEAR(static_cast<double>(false_pos) / objects, 0.05, 0.007);
  EXPECT_NEAR(static_cast<double>(confused) / found, 0.02, 0.004);
  EXPECT_NEAR(std::sqrt(jitter2 / jitter_n), 3.0, 0.1);
}

TEST(Detections, ExactWithoutNoiseAndOnlyForWellSeenObjects) {
  DetectionNoiseParams params;
  params.min_visible_fraction = 0.3;
  params.min_box_px = 20.0;
  Frame f = four_objects(0);
  f.objects[1].visible_fraction = 0.2;                // too hidden
  f.objects[2].box = Box2d{10.0, 10.0, 25.0, 200.0};  // too thin
  const auto dets = simulate_detections(f, context(), params, false, 1);
  ASSERT_EQ(dets.size(), 2u);
  EXPECT_EQ(dets[0].gt_id, 1u);
  EXPECT_EQ(dets[1].gt_id, 4u);
  EXPECT_EQ(dets[0].box.x_min, f.objects[0].box.x_min);
  EXPECT_EQ(dets[1].box.y_max, f.objects[3].box.y_max);
  EXPECT_EQ(dets[0].score, 1.0f);
  EXPECT_EQ(dets[0].class_name, "a");
}

TEST(Detections, DeterministicPerSeedAndFrame) {
  const DetectionNoiseParams params;
  const auto a = simulate_detections(four_objects(3), context(), params, true, 9);
  const auto b = simulate_detections(four_objects(3), context(), params, true, 9);
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].box.x_min, b[i].box.x_min);
    EXPECT_EQ(a[i].gt_id, b[i].gt_id);
  }
  // Another seed gives other boxes.
  const auto c = simulate_detections(four_objects(3), context(), params, true, 10);
  bool differs = a.size() != c.size();
  for (size_t i = 0; !differs && i < a.size(); ++i) differs = a[i].box.x_min != c[i].box.x_min;
  EXPECT_TRUE(differs);
}

}  // namespace
}  // namespace dqo::sim
