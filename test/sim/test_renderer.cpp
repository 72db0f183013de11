// Renderer: exact depth, instance pixels inside their boxes, depth back-projected onto the
// ground-truth meshes, visible fractions, determinism across thread counts.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>
#include <memory>

#include "dqo_map/sim/renderer.h"
#include "dqo_map/sim/scene_loader.h"
#include "sim_test_utils.h"

namespace dqo::sim {
namespace {

using testing::empty_scene;
using testing::make_object;

constexpr double kPi = 3.14159265358979323846;

SE3 pose_rpy(double r, double p, double y, const Eigen::Vector3d& t) {
  const Eigen::Quaterniond q = Eigen::AngleAxisd(y, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(p, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(r, Eigen::Vector3d::UnitX());
  return SE3(q, t);
}

// Within one unit in the last place of the float nearest to the exact value.
bool float_exact(float depth, long double exact) {
  const float f = static_cast<float>(exact);
  const float ulp = std::nextafter(f, std::numeric_limits<float>::infinity()) - f;
  return std::abs(static_cast<long double>(depth) - exact) <= static_cast<long double>(ulp);
}

Eigen::Matrix<long double, 3, 1> ld(const Eigen::Vector3d& v) { return v.cast<long double>(); }

const Scene& tiny() {
  static const Scene scene = [] {
    std::string error;
    auto s = load_scene(testing::scene_path("tiny"), {}, &error);
    EXPECT_TRUE(s.has_value()) << error;
    return s ? *s : Scene();
  }();
  return scene;
}

TEST(Renderer, PlaneDepthIsExactToFloatPrecision) {
  const SE3 T_wc = pose_rpy(-1.9, 0.2, 0.7, Eigen::Vector3d(0.3, -0.4, 1.6));
  Scene scene = empty_scene(96, 72, 80.0, T_wc);
  const SE3 T_wq = pose_rpy(0.3, -0.2, 0.4, Eigen::Vector3d(0.1, 0.2, -0.05));
  scene.background.push_back(
      make_object(0, std::make_shared<Quad>(Eigen::Vector2d(100, 100)), T_wq));
  const Renderer renderer(scene, 2);
  const Frame f = renderer.render(0, false);
  // Closed form in the camera frame: the plane n·p = n·q0, the ray p = t d_c with d_c.z = 1.
  const SE3 T_cq = T_wc.inverse() * T_wq;
  const auto n = ld(T_cq.rotation().col(2));
  const auto q0 = ld(T_cq.translation());
  int checked = 0;
  for (int v = 0; v < 72; ++v) {
    for (int u = 0; u < 96; ++u) {
      const Eigen::Matrix<long double, 3, 1> d((u - scene.camera.cx) / scene.camera.fx,
                                               (v - scene.camera.cy) / scene.camera.fy, 1.0L);
      const long double t = n.dot(q0) / n.dot(d);
      // Where the ray meets the plane, in the quad's frame: a far grazing hit can leave the quad.
      const Eigen::Matrix<long double, 3, 1> q =
          T_cq.rotation().transpose().cast<long double>() * (t * d - q0);
      if (!(t > scene.near) || std::abs(q.x()) > 49.9L || std::abs(q.y()) > 49.9L) {
        if (!(t > scene.near) || std::abs(q.x()) > 50.1L || std::abs(q.y()) > 50.1L) {
          EXPECT_EQ(f.depth.at(u, v), 0.0f);
        }
        continue;
      }
      ASSERT_TRUE(float_exact(f.depth.at(u, v), t))
          << "pixel " << u << "," << v << ": " << f.depth.at(u, v) << " vs "
          << static_cast<double>(t);
      ++checked;
    }
  }
  EXPECT_GT(checked, 96 * 72 / 2);
}

TEST(Renderer, SphereDepthIsExactToFloatPrecision) {
  const SE3 T_wc = pose_rpy(-1.6, 0.1, -0.3, Eigen::Vector3d(-0.2, 0.1, 0.9));
  Scene scene = empty_scene(120, 90, 100.0, T_wc);
  // Radius 0.2 scaled by 1.5: the scale path of the renderer is part of the test.
  const SE3 T_wo = pose_rpy(0.5, 0.9, -1.2, Eigen::Vector3d(-0.05, 1.9, 1.0));
  scene.objects.push_back(
      make_object(7, std::make_shared<Ellipsoid>(Eigen::Vector3d::Constant(0.2)), T_wo, 1.5));
  const Renderer renderer(scene, 3);
  const Frame f = renderer.render(0, false);
  const auto c = ld(T_wc.inverse() * T_wo.translation());
  const long double r = 0.3L;
  int inside = 0;
  for (int v = 0; v < 90; ++v) {
    for (int u = 0; u < 120; ++u) {
      const Eigen::Matrix<long double, 3, 1> d((u - scene.camera.cx) / scene.camera.fx,
                                               (v - scene.camera.cy) / scene.camera.fy, 1.0L);
      const long double a = d.squaredNorm(), b = d.dot(c);
      const long double disc = b * b - a * (c.squaredNorm() - r * r);
      if (std::abs(disc) < 1e-6L * b * b) continue;  // grazing the silhouette: either is right
      if (disc < 0) {
        EXPECT_EQ(f.instance.at(u, v), 0) << u << "," << v;
        continue;
      }
      ASSERT_EQ(f.instance.at(u, v), 7) << u << "," << v;
      const long double t = (b - std::sqrt(disc)) / a;
      ASSERT_TRUE(float_exact(f.depth.at(u, v), t))
          << "pixel " << u << "," << v << ": " << f.depth.at(u, v) << " vs "
          << static_cast<double>(t);
      ++inside;
    }
  }
  EXPECT_GT(inside, 500);
  ASSERT_EQ(f.objects.size(), 1u);
  EXPECT_DOUBLE_EQ(f.objects[0].visible_fraction, 1.0);
}

TEST(Renderer, EveryInstancePixelLiesInsideItsObjectsBox) {
  const Scene& scene = tiny();
  ASSERT_EQ(scene.num_frames(), 20);
  const Renderer renderer(scene, 2);
  for (int i = 0; i < scene.num_frames(); ++i) {
    const Frame f = renderer.render(i, true);
    std::map<uint32_t, Box2d> boxes;
    for (const auto& o : f.objects) boxes[o.id] = o.box;
    std::map<uint32_t, Box2d> tight;  // independent: from the instance image itself
    for (int v = 0; v < f.instance.height; ++v) {
      for (int u = 0; u < f.instance.width; ++u) {
        const uint16_t id = f.instance.at(u, v);
        if (id == 0) continue;
        ASSERT_TRUE(boxes.count(id)) << "frame " << i << ": id " << id << " has no FrameObject";
        const Box2d& b = boxes[id];
        EXPECT_TRUE(u >= b.x_min && u <= b.x_max && v >= b.y_min && v <= b.y_max)
            << "frame " << i << " pixel " << u << "," << v << " id " << id;
        auto [it, fresh] = tight.try_emplace(id, Box2d{1e9, 1e9, -1e9, -1e9});
        it->second.x_min = std::min(it->second.x_min, u - 0.5);
        it->second.y_min = std::min(it->second.y_min, v - 0.5);
        it->second.x_max = std::max(it->second.x_max, u + 0.5);
        it->second.y_max = std::max(it->second.y_max, v + 0.5);
      }
    }
    ASSERT_EQ(tight.size(), boxes.size()) << "frame " << i;
    for (const auto& [id, b] : tight) {
      const Box2d c = b.clip(f.instance.width, f.instance.height);
      EXPECT_DOUBLE_EQ(boxes[id].x_min, c.x_min);
      EXPECT_DOUBLE_EQ(boxes[id].y_min, c.y_min);
      EXPECT_DOUBLE_EQ(boxes[id].x_max, c.x_max);
      EXPECT_DOUBLE_EQ(boxes[id].y_max, c.y_max);
    }
  }
}

TEST(Renderer, BackProjectedDepthLandsOnTheGroundTruthMesh) {
  const Scene& scene = tiny();
  const Renderer renderer(scene, 2);
  const DatasetInfo info = renderer.info();
  std::map<uint32_t, const GtObject*> gt;
  for (const auto& o : info.objects) gt[o.id] = &o;
  ASSERT_EQ(gt.size(), 5u);
  double worst = 0.0;
  int checked = 0;
  for (const int i : {0, 7, 13}) {
    const Frame f = renderer.render(i, false);
    for (int v = 0; v < f.depth.height; v += 2) {
      for (int u = (v / 2) % 2; u < f.depth.width; u += 2) {
        const uint16_t id = f.instance.at(u, v);
        if (id == 0) continue;
        const Eigen::Vector3d p_w = f.T_wc * scene.camera.back_project(u, v, f.depth.at(u, v));
        const double d = testing::point_mesh_distance(p_w, gt.at(id)->mesh);
        worst = std::max(worst, d);
        ++checked;
        ASSERT_LT(d, 1e-3) << "frame " << i << " pixel " << u << "," << v << " object " << id;
      }
    }
  }
  EXPECT_GT(checked, 300);
  RecordProperty("worst_distance_um", static_cast<int>(worst * 1e6));
}

TEST(Renderer, GroundTruthBoxesAreTheObjectsTightBoxes) {
  const DatasetInfo info = dataset_info(tiny());
  ASSERT_EQ(info.objects.size(), 5u);
  const GtObject& book = info.objects[0];
  EXPECT_EQ(book.id, 1u);
  EXPECT_EQ(book.class_name, "book");
  EXPECT_NEAR((book.box.half_extents - Eigen::Vector3d(0.11, 0.08, 0.02)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((book.box.centre - Eigen::Vector3d(-0.2, 0.12, 0.77)).norm(), 0.0, 1e-12);
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(20.0 * kPi / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  EXPECT_NEAR((book.box.rotation - R).norm(), 0.0, 1e-12);
  // The cup's lathe body is 0.08 wide and 0.10 tall; its handle makes it wider along x.
  const GtObject& cup = info.objects[1];
  EXPECT_NEAR(2.0 * cup.box.half_extents.z(), 0.10, 1e-12);
  EXPECT_NEAR(2.0 * cup.box.half_extents.y(), 0.08, 1e-4);
  EXPECT_NEAR(cup.box.centre.z(), 0.80, 1e-12);
  for (const auto& o : info.objects) {
    EXPECT_FALSE(o.mesh.empty());
    for (const auto& v : o.mesh.vertices) {
      const Eigen::Vector3d l = o.box.rotation.transpose() * (v - o.box.centre);
      EXPECT_TRUE((l.cwiseAbs().array() <= o.box.half_extents.array() + 1e-9).all()) << o.id;
    }
  }
  EXPECT_EQ(info.class_names.size(), 5u);
  EXPECT_DOUBLE_EQ(info.camera.fx, 140.0);
}

TEST(Renderer, VisibleFractionIsOneUnoccludedAndLessBehindAnOccluder) {
  Scene scene = empty_scene(400, 300, 400.0, SE3());  // optical frame = world: looking along +z
  auto box = [](double s) { return std::make_shared<Box>(Eigen::Vector3d::Constant(s)); };
  // Squares facing the camera: their projections are exact squares, so the hidden part is known.
  auto square = [](double s) { return std::make_shared<Quad>(Eigen::Vector2d(s, s)); };
  auto at = [](double x, double y, double z) {
    return SE3(Eigen::Quaterniond::Identity(), {x, y, z});
  };
  scene.objects.push_back(make_object(1, box(0.2), at(-0.6, 0.0, 3.0)));    // alone
  scene.objects.push_back(make_object(2, square(0.4), at(0.0, 0.0, 4.0)));  // behind 3
  scene.objects.push_back(make_object(3, square(0.1), at(0.0, 0.0, 2.0)));  // occluder
  scene.objects.push_back(make_object(4, square(0.4), at(0.0, 0.8, 4.0)));  // behind furniture
  scene.background.push_back(make_object(0, square(0.1), at(0.0, 0.4, 2.0)));
  const Renderer renderer(scene, 2);
  const Frame f = renderer.render(0, false);
  std::map<uint32_t, double> vf;
  for (const auto& o : f.objects) vf[o.id] = o.visible_fraction;
  ASSERT_EQ(vf.size(), 4u);
  EXPECT_DOUBLE_EQ(vf[1], 1.0);
  EXPECT_DOUBLE_EQ(vf[3], 1.0);
  // The occluder covers (0.1 / 2)^2 / (0.4 / 4)^2 = 1/4 of the square behind it.
  EXPECT_NEAR(vf[2], 0.75, 0.02);
  EXPECT_NEAR(vf[4], 0.75, 0.02);  // background occludes too

  // Without the occluder, the same object is fully visible.
  scene.objects.erase(scene.objects.begin() + 2);
  const Frame g = Renderer(scene, 1).render(0, false);
  for (const auto& o : g.objects) {
    if (o.id == 2) {
      EXPECT_DOUBLE_EQ(o.visible_fraction, 1.0);
    }
  }
}

TEST(Renderer, ResultsDoNotDependOnTheThreadCount) {
  Scene scene = tiny();
  scene.noise.enabled = true;  // noise included: it is keyed by pixel
  const Frame a = Renderer(scene, 1).render(4, true);
  for (const int threads : {2, 5}) {
    const Frame b = Renderer(scene, threads).render(4, true);
    EXPECT_EQ(a.rgb.data, b.rgb.data);
    EXPECT_EQ(a.depth.data, b.depth.data);
    EXPECT_EQ(a.instance.data, b.instance.data);
    ASSERT_EQ(a.objects.size(), b.objects.size());
    for (size_t i = 0; i < a.objects.size(); ++i) {
      EXPECT_EQ(a.objects[i].id, b.objects[i].id);
      EXPECT_EQ(a.objects[i].visible_fraction, b.objects[i].visible_fraction);
    }
    ASSERT_EQ(a.detections.size(), b.detections.size());
    for (size_t i = 0; i < a.detections.size(); ++i) {
      EXPECT_EQ(a.detections[i].box.x_min, b.detections[i].box.x_min);
      EXPECT_EQ(a.detections[i].class_id, b.detections[i].class_id);
    }
  }
  // And the noise did something: the same frame without noise differs.
  const Frame clean = Renderer(scene, 2).render(4, false);
  EXPECT_NE(a.depth.data, clean.depth.data);
  EXPECT_NE(a.rgb.data, clean.rgb.data);
  EXPECT_EQ(a.instance.data, clean.instance.data);
}

TEST(Renderer, TinyRendersItsTwentyFrames) {
  const Scene& scene = tiny();
  const Renderer renderer(scene, 2);
  ASSERT_EQ(renderer.num_frames(), 20);
  for (int i = 0; i < 20; ++i) {
    const Frame f = renderer.render(i, true);
    EXPECT_EQ(f.index, i);
    EXPECT_NEAR(f.timestamp, i / 30.0, 1e-12);
    EXPECT_TRUE(f.has_pose);
    EXPECT_EQ(f.rgb.width, 160);
    EXPECT_EQ(f.rgb.height, 120);
    EXPECT_EQ(f.rgb.channels, 3);
    EXPECT_EQ(f.depth.data.size(), 160u * 120u);
    EXPECT_GE(f.objects.size(), 3u) << "frame " << i;
    EXPECT_GE(f.detections.size(), 2u) << "frame " << i;
    // Inside a closed room every ray returns (tiny has no noise, hence no holes).
    for (const float d : f.depth.data) ASSERT_GT(d, 0.0f);
    // The camera looks at the table: the centre pixel is near the target.
    EXPECT_NEAR(f.depth.at(80, 60), (f.T_wc.translation() - Eigen::Vector3d(0, 0, 0.8)).norm(),
                0.3);
  }
}

}  // namespace
}  // namespace dqo::sim
