// The YAML loader: strict errors naming file and line, mesh files through the loader callback,
// TUM trajectories, and the shipped scenes meeting what the issue asks of them.

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>

#include "dqo_map/sim/renderer.h"
#include "dqo_map/sim/scene_loader.h"
#include "sim_test_utils.h"

namespace dqo::sim {
namespace {

// Line numbers matter below: each line of this scene is known.
const char* const kLines[] = {
    "seed: 1",                                                               // 1
    "frames: 2",                                                             // 2
    "camera: {width: 32, height: 24, fx: 30, fy: 30, cx: 15.5, cy: 11.5}",   // 3
    "classes:",                                                              // 4
    "  - {id: 1, name: box}",                                                // 5
    "lighting: {ambient: 0.5}",                                              // 6
    "objects:",                                                              // 7
    "  - id: 1",                                                             // 8
    "    class: box",                                                        // 9
    "    pose: {position: [0, 0, 0]}",                                       // 10
    "    material: {colour: [0.5, 0.5, 0.5]}",                               // 11
    "    shape: {type: box, size: [0.2, 0.2, 0.2]}",                         // 12
    "trajectory: {type: orbit, target: [0, 0, 0], radius: 1, height: 0.5}",  // 13
};
constexpr int kNumLines = 13;

// The scene with line `line` (1-based) replaced by `text` (nullptr: removed).
std::string scene_text(int line = 0, const char* text = "") {
  std::string s;
  for (int i = 1; i <= kNumLines; ++i) {
    if (i == line) {
      if (text) s += std::string(text) + "\n";
    } else {
      s += std::string(kLines[i - 1]) + "\n";
    }
  }
  return s;
}

std::string load_error(const std::string& text, const MeshLoader& loader = {}) {
  std::string error;
  const auto scene = parse_scene(text, "scenes/bad.yaml", "scenes", loader, &error);
  EXPECT_FALSE(scene.has_value()) << "loaded although it should not";
  return error;
}

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

TEST(SceneLoader, TheTestSceneLoads) {
  std::string error;
  const auto scene = parse_scene(scene_text(), "ok.yaml", "", {}, &error);
  ASSERT_TRUE(scene.has_value()) << error;
  EXPECT_EQ(scene->num_frames(), 2);
  EXPECT_EQ(scene->objects.size(), 1u);
  EXPECT_EQ(scene->objects[0].class_name, "box");
  EXPECT_EQ(scene->name, "ok");
  EXPECT_TRUE(scene->noise.enabled);  // on unless the scene says otherwise
}

TEST(SceneLoader, UnknownKeyNamesFileAndLine) {
  const std::string e =
      load_error(scene_text(11, "    material: {colour: [0.5, 0.5, 0.5], colr: 1}"));
  EXPECT_TRUE(contains(e, "scenes/bad.yaml:11:")) << e;
  EXPECT_TRUE(contains(e, "unknown key 'colr'")) << e;
  const std::string top = load_error(scene_text(2, "framez: 2"));
  EXPECT_TRUE(contains(top, "scenes/bad.yaml:")) << top;
  EXPECT_TRUE(contains(top, "'frames'") || contains(top, "'framez'")) << top;
  const std::string nested = load_error(scene_text(10, "    pose: {position: [0, 0, 0], yaw: 3}"));
  EXPECT_TRUE(contains(nested, "scenes/bad.yaml:10:")) << nested;
  EXPECT_TRUE(contains(nested, "unknown key 'yaw'")) << nested;
}

TEST(SceneLoader, MissingFieldNamesFileAndLine) {
  const std::string e = load_error(scene_text(12, nullptr));
  EXPECT_TRUE(contains(e, "scenes/bad.yaml:8:")) << e;  // the object's map starts on line 8
  EXPECT_TRUE(contains(e, "missing field 'shape'")) << e;
  const std::string cam =
      load_error(scene_text(3, "camera: {width: 32, height: 24, fx: 30, cx: 15.5, cy: 11.5}"));
  EXPECT_TRUE(contains(cam, "scenes/bad.yaml:3:")) << cam;
  EXPECT_TRUE(contains(cam, "missing field 'fy'")) << cam;
}

TEST(SceneLoader, BadValuesNameFileAndLine) {
  std::string e = load_error(
      scene_text(13, "trajectory: {type: orbit, target: [0, 0, 0], radius: abc, height: 0.5}"));
  EXPECT_TRUE(contains(e, "scenes/bad.yaml:13:")) << e;
  EXPECT_TRUE(contains(e, "radius")) << e;
  e = load_error(scene_text(9, "    class: sofa"));
  EXPECT_TRUE(contains(e, "scenes/bad.yaml:9:") && contains(e, "'sofa'")) << e;
  e = load_error(scene_text(12, "    shape: {type: blob, size: [0.2, 0.2, 0.2]}"));
  EXPECT_TRUE(contains(e, "scenes/bad.yaml:12:") && contains(e, "unknown shape type 'blob'")) << e;
  e = load_error(scene_text(11, "    material: {colour: [0.5, 2.0, 0.5]}"));
  EXPECT_TRUE(contains(e, "scenes/bad.yaml:11:") && contains(e, "[0, 1]")) << e;
  e = load_error(scene_text(12, "    shape: {type: lathe, profile: [[0.1, 0], [0.1, 1], [0, 1]]}"));
  EXPECT_TRUE(contains(e, "scenes/bad.yaml:12:") && contains(e, "axis")) << e;
}

TEST(SceneLoader, SyntaxErrorNamesFileAndLine) {
  const std::string e = load_error(scene_text(6, "lighting: {ambient: 0.5"));
  EXPECT_TRUE(contains(e, "scenes/bad.yaml:")) << e;
}

TEST(SceneLoader, DuplicateObjectIdIsAnError) {
  std::string text = scene_text();
  text.insert(text.find("trajectory:"),
              "  - {id: 1, class: box, pose: {position: [1, 0, 0]}, material: {colour: [1, 1, 1]},"
              " shape: {type: box, size: [1, 1, 1]}}\n");
  const std::string e = load_error(text);
  EXPECT_TRUE(contains(e, "scenes/bad.yaml:13:") && contains(e, "used twice")) << e;
}

TEST(SceneLoader, MeshObjectsGoThroughTheLoader) {
  const std::string text = scene_text(12, "    shape: {type: mesh, file: meshes/tetra.ply}");
  // No loader: a clear error at the line of the mesh.
  std::string e = load_error(text);
  EXPECT_TRUE(contains(e, "scenes/bad.yaml:12:") && contains(e, "no mesh loader")) << e;
  // A failing loader: its message comes through.
  e = load_error(text, [](const std::string&, std::string* err) -> std::optional<TriangleMesh> {
    *err = "not a PLY file";
    return std::nullopt;
  });
  EXPECT_TRUE(contains(e, "scenes/bad.yaml:12:") && contains(e, "not a PLY file")) << e;
  // A working one: the path is resolved against the scene's folder, the mesh renders.
  std::string seen;
  const MeshLoader loader = [&](const std::string& path,
                                std::string*) -> std::optional<TriangleMesh> {
    seen = path;
    TriangleMesh m;
    m.vertices = {{0, 0, 0}, {0.3, 0, 0}, {0, 0.3, 0}, {0, 0, 0.3}};
    m.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
    return m;
  };
  std::string error;
  const auto scene = parse_scene(text, "scenes/ok.yaml", "scenes", loader, &error);
  ASSERT_TRUE(scene.has_value()) << error;
  EXPECT_EQ(seen, "scenes/meshes/tetra.ply");
  const Frame f = Renderer(*scene, 1).render(0, false);
  ASSERT_EQ(f.objects.size(), 1u);
  const DatasetInfo info = dataset_info(*scene);
  EXPECT_NEAR(info.objects[0].box.half_extents.x(), 0.15, 1e-12);
}

TEST(SceneLoader, TumTrajectoryFile) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "dqo_sim_tum_test";
  std::filesystem::create_directories(dir);
  {
    std::ofstream traj(dir / "traj.txt");
    traj << "# timestamp tx ty tz qx qy qz qw\n"
         << "1305031102.175304 1.0 2.0 3.0 0 0 0 1\n\n"
         << "1305031102.211214 1.1 2.0 3.0 0 0 0.7071067811865476 0.7071067811865476\n"
         << "1305031102.243211 1.2 2.0 3.0 0 0 0 1\n";
  }
  {
    std::ofstream yaml(dir / "scene.yaml");
    yaml << scene_text(13, "trajectory: {type: tum, file: traj.txt}");
  }
  std::string error;
  const auto scene = load_scene((dir / "scene.yaml").string(), {}, &error);
  ASSERT_TRUE(scene.has_value()) << error;
  ASSERT_EQ(scene->num_frames(), 2);  // frames: 2 of the file's 3
  EXPECT_DOUBLE_EQ(scene->trajectory[1].timestamp, 1305031102.211214);
  EXPECT_NEAR((scene->trajectory[1].T_wc.translation() - Eigen::Vector3d(1.1, 2.0, 3.0)).norm(), 0,
              1e-12);
  EXPECT_NEAR(scene->trajectory[1].T_wc.quaternion().z(), 0.7071067811865476, 1e-12);
  // Too few poses for the frames asked.
  {
    std::ofstream yaml(dir / "scene.yaml");
    std::string t = scene_text(13, "trajectory: {type: tum, file: traj.txt}");
    t.replace(t.find("frames: 2"), 9, "frames: 5");
    yaml << t;
  }
  EXPECT_FALSE(load_scene((dir / "scene.yaml").string(), {}, &error).has_value());
  EXPECT_TRUE(contains(error, "scene.yaml:13:") && contains(error, "fewer")) << error;
  std::filesystem::remove_all(dir);
}

TEST(SceneLoader, MissingFileIsAnError) {
  std::string error;
  EXPECT_FALSE(load_scene("/nonexistent/scene.yaml", {}, &error).has_value());
  EXPECT_TRUE(contains(error, "/nonexistent/scene.yaml")) << error;
}

TEST(SceneLoader, RotationsAsRpyAndQuaternionAgree) {
  std::string e1, e2;
  const auto a = parse_scene(scene_text(10, "    pose: {position: [0, 0, 0], rpy_deg: [0, 0, 90]}"),
                             "a.yaml", "", {}, &e1);
  const auto b = parse_scene(scene_text(10,
                                        "    pose: {position: [0, 0, 0], quaternion: [0, 0, "
                                        "0.7071067811865476, 0.7071067811865476]}"),
                             "b.yaml", "", {}, &e2);
  ASSERT_TRUE(a && b) << e1 << e2;
  EXPECT_NEAR((a->objects[0].T_wo.rotation() - b->objects[0].T_wo.rotation()).norm(), 0.0, 1e-12);
  const std::string both = load_error(scene_text(
      10, "    pose: {position: [0, 0, 0], rpy_deg: [0, 0, 9], quaternion: [0, 0, 0, 1]}"));
  EXPECT_TRUE(contains(both, "scenes/bad.yaml:10:") && contains(both, "at most one")) << both;
}

// ------------------------------------------------------------------ the simulated detector

// The test scene with three classes (lines 5-7; the rest moves down by two, trajectory on 15) and
// `noise` appended from line 16 on.
std::string detector_scene(const std::string& noise) {
  return scene_text(5, "  - {id: 1, name: box}\n  - {id: 2, name: can}\n  - {id: 3, name: jar}") +
         noise;
}

std::optional<Scene> parse_ok(const std::string& text, const SceneOverrides& overrides = {}) {
  std::string error;
  auto scene = parse_scene(text, "ok.yaml", "", {}, &error, overrides);
  EXPECT_TRUE(scene.has_value()) << error;
  return scene;
}

TEST(SceneLoader, DetectorProfileSetsTheRatesAndKeysOverrideThem) {
  const auto kind = parse_ok(detector_scene(""));
  ASSERT_TRUE(kind);
  EXPECT_EQ(kind->noise.detection.profile, DetectorProfile::kKind);
  EXPECT_DOUBLE_EQ(kind->noise.detection.miss_rate, 0.10);
  EXPECT_DOUBLE_EQ(kind->noise.detection.false_positive_recurring, 0.0);
  EXPECT_FALSE(kind->noise.detection.confusion_within_groups);

  const auto real = parse_ok(detector_scene("noise:\n  detections: {profile: real}\n"));
  ASSERT_TRUE(real);
  const DetectionNoiseParams& r = real->noise.detection;
  EXPECT_EQ(r.profile, DetectorProfile::kReal);
  EXPECT_DOUBLE_EQ(r.miss_rate, 0.6);
  EXPECT_DOUBLE_EQ(r.confusion_rate, 0.3);
  EXPECT_DOUBLE_EQ(r.false_positive_rate, 0.10);
  EXPECT_DOUBLE_EQ(r.false_positive_recurring, 0.5);
  EXPECT_TRUE(r.confusion_within_groups);
  EXPECT_GT(r.box_jitter_px, 3.0);

  // Keys beside the profile win over it, wherever they stand.
  const auto mixed = parse_ok(detector_scene(
      "noise:\n  detections: {miss_rate: 0.5, profile: real, false_positive_recurring: 0,\n"
      "               confusion_groups: [[box, jar]], clutter_spots: 3, min_box_px: 4}\n"));
  ASSERT_TRUE(mixed);
  const DetectionNoiseParams& m = mixed->noise.detection;
  EXPECT_EQ(m.profile, DetectorProfile::kReal);
  EXPECT_DOUBLE_EQ(m.miss_rate, 0.5);
  EXPECT_DOUBLE_EQ(m.false_positive_recurring, 0.0);
  EXPECT_DOUBLE_EQ(m.confusion_rate, 0.3);  // the profile's
  EXPECT_EQ(m.clutter_spots, 3);
  EXPECT_DOUBLE_EQ(m.min_box_px, 4.0);
  ASSERT_EQ(m.confusion_groups.size(), 1u);
  EXPECT_EQ(m.confusion_groups[0], (std::vector<int>{1, 3}));
}

TEST(SceneLoader, CommandLineProfileReplacesTheFilesRates) {
  const std::string text = detector_scene(
      "noise:\n  detections: {profile: kind, miss_rate: 0.2, min_box_px: 4,\n"
      "               confusion_groups: [[can, jar]]}\n");
  SceneOverrides real;
  real.detector_profile = DetectorProfile::kReal;
  const auto a = parse_ok(text, real);
  ASSERT_TRUE(a);
  EXPECT_EQ(a->noise.detection.profile, DetectorProfile::kReal);
  EXPECT_DOUBLE_EQ(a->noise.detection.miss_rate, 0.6);  // not the file's 0.2
  EXPECT_DOUBLE_EQ(a->noise.detection.min_box_px, 4.0);  // the file's threshold stays
  EXPECT_EQ(a->noise.detection.confusion_groups.size(), 1u);  // and its groups
  // Without a noise block too; and back to kind from a real scene.
  EXPECT_DOUBLE_EQ(parse_ok(detector_scene(""), real)->noise.detection.miss_rate, 0.6);
  SceneOverrides kind;
  kind.detector_profile = DetectorProfile::kKind;
  const auto b = parse_ok(detector_scene("noise:\n  detections: {profile: real}\n"), kind);
  EXPECT_DOUBLE_EQ(b->noise.detection.miss_rate, 0.10);
  EXPECT_FALSE(b->noise.detection.confusion_within_groups);
}

TEST(SceneLoader, BadDetectorProfilesAndGroupsAreRefused) {
  std::string e = load_error(detector_scene("noise:\n  detections: {profile: realistic}\n"));
  EXPECT_TRUE(contains(e, "scenes/bad.yaml:17:") && contains(e, "unknown detector profile") &&
              contains(e, "'realistic'") && contains(e, "kind, real"))
      << e;
  e = load_error(detector_scene("noise:\n  detections:\n    confusion_groups: [[box, cat]]\n"));
  EXPECT_TRUE(contains(e, "scenes/bad.yaml:18:") && contains(e, "class 'cat'") &&
              contains(e, "not in 'classes'"))
      << e;
  e = load_error(
      detector_scene("noise:\n  detections:\n    confusion_groups: [[box, can], [jar, box]]\n"));
  EXPECT_TRUE(contains(e, "scenes/bad.yaml:18:") && contains(e, "'box'") &&
              contains(e, "confusion group 1 already"))
      << e;
  e = load_error(detector_scene("noise:\n  detections:\n    confusion_groups: [[box]]\n"));
  EXPECT_TRUE(contains(e, "two or more")) << e;
  e = load_error(detector_scene("noise:\n  detections:\n    confusion_groups: [box, can]\n"));
  EXPECT_TRUE(contains(e, "two or more")) << e;
  e = load_error(detector_scene("noise:\n  detections: {false_positive_recurring: 1.5}\n"));
  EXPECT_TRUE(contains(e, "false_positive_recurring")) << e;
  e = load_error(detector_scene("noise:\n  detections: {clutter_spots: -1}\n"));
  EXPECT_TRUE(contains(e, "clutter_spots")) << e;
  e = load_error(detector_scene("noise:\n  detections: {profile: [real]}\n"));
  EXPECT_TRUE(contains(e, "profile")) << e;
}

// ------------------------------------------------------------------ the shipped scenes

Scene load(const std::string& name) {
  std::string error;
  auto scene = load_scene(testing::scene_path(name), {}, &error);
  EXPECT_TRUE(scene.has_value()) << error;
  return scene ? *scene : Scene();
}

std::set<int> classes_of(const Scene& s) {
  std::set<int> c;
  for (const auto& o : s.objects) c.insert(o.class_id);
  return c;
}

TEST(ShippedScenes, TabletopAndItsPlainTwin) {
  for (const char* name : {"tabletop", "tabletop_plain"}) {
    const Scene s = load(name);
    EXPECT_EQ(s.objects.size(), 4u) << name;
    EXPECT_EQ(classes_of(s).size(), 4u) << name;
    EXPECT_EQ(s.camera.width, 640);
    EXPECT_EQ(s.camera.height, 480);
    EXPECT_GE(s.num_frames(), 250);
    EXPECT_TRUE(s.noise.enabled);
    for (const auto& o : s.objects) EXPECT_NE(o.shape->type_name(), "ellipsoid") << name;
    const auto gt = ground_truth_objects(s);
    std::map<std::string, Eigen::Vector3d> size;
    for (const auto& g : gt) size[g.class_name] = 2.0 * g.box.half_extents;
    EXPECT_NEAR((size["book"] - Eigen::Vector3d(0.22, 0.16, 0.04)).norm(), 0.0, 1e-9);
    EXPECT_NEAR(size["cup"].z(), 0.10, 1e-9);
    EXPECT_NEAR(size["cup"].y(), 0.08, 1e-3);  // the body's width (the handle sticks out along x)
    EXPECT_NEAR(size["bottle"].z(), 0.25, 1e-9);
  }
  // The plain twin has the same geometry with uniform materials only.
  const Scene t = load("tabletop"), p = load("tabletop_plain");
  for (size_t i = 0; i < t.objects.size(); ++i) {
    EXPECT_EQ(t.objects[i].T_wo.translation(), p.objects[i].T_wo.translation());
  }
  for (const auto* list : {&p.objects, &p.background}) {
    for (const auto& o : *list) {
      EXPECT_EQ(o.material.type, TextureType::kUniform);
      for (const auto& m : o.part_materials) EXPECT_EQ(m.type, TextureType::kUniform);
    }
  }
}

TEST(ShippedScenes, ConfusionGroupsOfTabletopAndRoom) {
  auto names = [](const Scene& s, const std::vector<int>& group) {
    std::set<std::string> n;
    for (const int c : group) n.insert(s.classes.at(c));
    return n;
  };
  const Scene t = load("tabletop");
  EXPECT_EQ(t.noise.detection.profile, DetectorProfile::kKind);  // no profile given
  ASSERT_EQ(t.noise.detection.confusion_groups.size(), 2u);
  EXPECT_EQ(names(t, t.noise.detection.confusion_groups[0]),
            (std::set<std::string>{"laptop", "book"}));
  EXPECT_EQ(names(t, t.noise.detection.confusion_groups[1]),
            (std::set<std::string>{"cup", "bottle"}));
  const Scene r = load("room");
  EXPECT_EQ(r.noise.detection.profile, DetectorProfile::kKind);
  std::set<int> grouped;
  for (const auto& g : r.noise.detection.confusion_groups) grouped.insert(g.begin(), g.end());
  EXPECT_GE(grouped.size(), 12u);  // most of the 16 classes have look-alikes
  EXPECT_EQ(names(r, r.noise.detection.confusion_groups[0]),
            (std::set<std::string>{"cup", "bowl", "vase", "bottle"}));
}

TEST(ShippedScenes, TinyAndOcclusion) {
  const Scene tiny = load("tiny");
  EXPECT_EQ(tiny.num_frames(), 20);
  EXPECT_EQ(tiny.camera.width, 160);
  EXPECT_EQ(tiny.camera.height, 120);
  EXPECT_FALSE(tiny.noise.enabled);
  const Scene occ = load("occlusion");
  EXPECT_GE(occ.objects.size(), 3u);
  EXPECT_TRUE(occ.noise.enabled);
}

// Counts the pieces (4-connected components) of an object's pixels.
int pieces(const InstanceImage& img, uint16_t id) {
  std::vector<int> label(img.data.size(), 0);
  int count = 0;
  std::vector<int> stack;
  for (size_t start = 0; start < img.data.size(); ++start) {
    if (img.data[start] != id || label[start]) continue;
    ++count;
    stack.push_back(static_cast<int>(start));
    label[start] = count;
    while (!stack.empty()) {
      const int k = stack.back();
      stack.pop_back();
      const int x = k % img.width, y = k / img.width;
      const int nb[4][2] = {{x - 1, y}, {x + 1, y}, {x, y - 1}, {x, y + 1}};
      for (const auto& n : nb) {
        if (n[0] < 0 || n[1] < 0 || n[0] >= img.width || n[1] >= img.height) continue;
        const int j = n[1] * img.width + n[0];
        if (img.data[j] == id && !label[j]) {
          label[j] = count;
          stack.push_back(j);
        }
      }
    }
  }
  return count;
}

TEST(ShippedScenes, OcclusionSplitsObjectsIntoPieces) {
  Scene s = load("occlusion");
  // A quarter of the resolution is enough to see the split and keeps the test quick.
  s.camera.fx /= 4;
  s.camera.fy /= 4;
  s.camera.cx = (s.camera.cx + 0.5) / 4 - 0.5;
  s.camera.cy = (s.camera.cy + 0.5) / 4 - 0.5;
  s.camera.width /= 4;
  s.camera.height /= 4;
  const Renderer r(s, 2);
  std::set<uint32_t> split;
  for (int i = 0; i < s.num_frames(); i += 10) {
    const Frame f = r.render(i, false);
    for (const auto& o : f.objects) {
      if (pieces(f.instance, static_cast<uint16_t>(o.id)) >= 2) split.insert(o.id);
    }
  }
  EXPECT_GE(split.size(), 2u);
}

TEST(ShippedScenes, RoomMeetsTheIssuesRequirements) {
  Scene s = load("room");
  EXPECT_GE(s.objects.size(), 15u);
  EXPECT_GE(classes_of(s).size(), 6u);
  EXPECT_GE(s.num_frames(), 600);
  EXPECT_EQ(s.camera.width, 1200);
  EXPECT_EQ(s.camera.height, 680);
  for (const auto& o : s.objects) {
    EXPECT_NE(o.shape->type_name(), "ellipsoid");
    EXPECT_NE(o.shape->type_name(), "mesh");  // primitives and procedural meshes only
  }
  // At least two pairs of same-class objects within 0.3 m of each other (surface to surface).
  const auto gt = ground_truth_objects(s);
  int close_pairs = 0;
  for (size_t i = 0; i < gt.size(); ++i) {
    for (size_t j = i + 1; j < gt.size(); ++j) {
      if (gt[i].class_id != gt[j].class_id) continue;
      double gap = 1e9;
      const auto& vs = gt[i].mesh.vertices;
      const size_t step = std::max<size_t>(1, vs.size() / 300);
      for (size_t k = 0; k < vs.size(); k += step) {
        gap = std::min(gap, testing::point_mesh_distance(vs[k], gt[j].mesh));
      }
      close_pairs += gap < 0.3;
    }
  }
  EXPECT_GE(close_pairs, 2);
  // At least three objects hidden by 30 % or more in some view (every 8th frame at 1/4 size).
  s.camera.fx /= 4;
  s.camera.fy /= 4;
  s.camera.cx = (s.camera.cx + 0.5) / 4 - 0.5;
  s.camera.cy = (s.camera.cy + 0.5) / 4 - 0.5;
  s.camera.width /= 4;
  s.camera.height /= 4;
  const Renderer r(s, 2);
  std::map<uint32_t, double> min_vf;
  for (int i = 0; i < s.num_frames(); i += 8) {
    const Frame f = r.render(i, false);
    for (const auto& o : f.objects) {
      if (o.box.width() * o.box.height() < 30.0) continue;  // too small to count at 1/4 size
      auto [it, fresh] = min_vf.try_emplace(o.id, 1.0);
      it->second = std::min(it->second, o.visible_fraction);
    }
  }
  int hidden = 0;
  for (const auto& [id, vf] : min_vf) hidden += vf <= 0.7;
  EXPECT_GE(hidden, 3);
  EXPECT_GE(min_vf.size(), 15u) << "every object is seen at some point of the walk";
}

}  // namespace
}  // namespace dqo::sim
