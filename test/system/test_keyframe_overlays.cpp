// Overlays of the object stage (objects/object_overlay.h, system/keyframe_overlays.h): label
// placement checked geometrically on the rectangles the drawing uses, and one PNG per keyframe
// from the offline pipeline on the `tiny` scene.

#include <gtest/gtest.h>

#include <stdlib.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "dqo_map/io/image_io.h"
#include "dqo_map/io/mesh_io.h"
#include "dqo_map/objects/object_overlay.h"
#include "dqo_map/sim/scene_frame_source.h"
#include "dqo_map/sim/scene_loader.h"
#include "dqo_map/system/keyframe_overlays.h"
#include "dqo_map/system/offline_stages.h"

namespace dqo {
namespace {

namespace fs = std::filesystem;
using objects::LabelRequest;
using objects::PlacedLabel;

bool inside(const Box2d& r, int width, int height) {
  return r.x_min >= 0.0 && r.y_min >= 0.0 && r.x_max <= width && r.y_max <= height;
}

// Every placed rectangle inside the image, no two sharing interior.
void expect_disjoint_inside(const std::vector<Box2d>& rects, int width, int height) {
  for (size_t i = 0; i < rects.size(); ++i) {
    EXPECT_TRUE(inside(rects[i], width, height))
        << "label " << i << " at " << rects[i].x_min << "," << rects[i].y_min << " .. " << rects[i].x_max
        << "," << rects[i].y_max;
    for (size_t j = i + 1; j < rects.size(); ++j) {
      EXPECT_EQ(intersection(rects[i], rects[j]).area(), 0.0) << "labels " << i << " and " << j << " overlap";
    }
  }
}

std::vector<Box2d> placed_rects(const std::vector<PlacedLabel>& placed) {
  std::vector<Box2d> out;
  for (const PlacedLabel& p : placed) {
    if (p.rect.valid()) out.push_back(p.rect);
  }
  return out;
}

// Circular hue distance, computed here apart from the palette's own.
double hue_gap(double a, double b) {
  const double d = std::abs(a - b);
  return std::min(d, 1.0 - d);
}

TEST(ObjectPalette, ObjectsOfOneMapGetHuesApartAndLowerIdsKeepTheirs) {
  using objects::ObjectId;
  // The demo's bottle #4 and cup #17: golden-ratio hues 0.034 apart (two blues).
  const double golden4 = std::fmod(0.1 + 0.618033988749895 * 4, 1.0);
  const double golden17 = std::fmod(0.1 + 0.618033988749895 * 17, 1.0);
  ASSERT_LT(hue_gap(golden4, golden17), 0.04);
  const objects::ObjectPalette demo({17, 4, 2, 5});
  EXPECT_GE(hue_gap(demo.hue(4), demo.hue(17)), objects::ObjectPalette::kMinHueGap);
  EXPECT_DOUBLE_EQ(demo.hue(4), golden4);  // the lower ID keeps its own
  EXPECT_EQ(demo.colour(4), objects::overlay_colour(4));
  EXPECT_NE(demo.colour(17), objects::overlay_colour(17));

  // A room's worth of scattered IDs: every pair at least the gap apart.
  std::mt19937 rng(7);
  std::vector<ObjectId> ids;
  for (int k = 0; k < 12; ++k) ids.push_back(1 + rng() % 120);
  const objects::ObjectPalette room(ids);
  for (size_t a = 0; a < ids.size(); ++a) {
    for (size_t b = 0; b < ids.size(); ++b) {
      if (ids[a] == ids[b]) continue;
      EXPECT_GE(hue_gap(room.hue(ids[a]), room.hue(ids[b])), objects::ObjectPalette::kMinHueGap - 1e-12)
          << ids[a] << " and " << ids[b];
    }
  }
  // Objects added later never change the colours of those with lower IDs.
  std::vector<ObjectId> more = ids;
  for (ObjectId id = 121; id < 126; ++id) more.push_back(id);
  const objects::ObjectPalette later(more);
  for (const ObjectId id : ids) EXPECT_DOUBLE_EQ(later.hue(id), room.hue(id)) << id;
  // An ID outside the palette: its own colour.
  EXPECT_EQ(room.colour(999), objects::overlay_colour(999));
}

TEST(LabelPlacement, ALoneBoxIsLabelledAboveAndAtTheTopEdgeBelow) {
  LabelRequest r;
  r.anchor = {100, 50, 180, 120};
  r.width = 60;
  r.height = 14;
  auto placed = objects::place_labels({r}, 320, 240);
  ASSERT_TRUE(placed[0].rect.valid());
  EXPECT_TRUE(placed[0].adjacent);
  EXPECT_LE(placed[0].rect.y_max, r.anchor.y_min);  // above, clear of the box
  EXPECT_DOUBLE_EQ(placed[0].rect.x_min, r.anchor.x_min);

  r.anchor = {100, 0, 180, 70};  // no room above: below, not pushed over the box's own top
  placed = objects::place_labels({r}, 320, 240);
  ASSERT_TRUE(placed[0].rect.valid());
  EXPECT_GE(placed[0].rect.y_min, r.anchor.y_max);
}

TEST(LabelPlacement, IdenticalBoxesGetLabelsThatDoNotOverlap) {
  LabelRequest r;
  r.anchor = {100, 50, 180, 120};
  r.width = 60;
  r.height = 14;
  const auto placed = objects::place_labels({r, r, r}, 320, 240);
  for (const PlacedLabel& p : placed) {
    ASSERT_TRUE(p.rect.valid());
    EXPECT_TRUE(p.adjacent);
  }
  EXPECT_LE(placed[0].rect.y_max, r.anchor.y_min);  // above
  EXPECT_GE(placed[1].rect.y_min, r.anchor.y_max);  // below
  EXPECT_GE(placed[2].rect.y_min, r.anchor.y_min);  // inside, top
  EXPECT_LE(placed[2].rect.y_max, r.anchor.y_max);
  expect_disjoint_inside(placed_rects(placed), 320, 240);
}

TEST(LabelPlacement, ManyCrowdedLabelsNeitherOverlapNorLeaveTheImage) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    const int width = 320, height = 240;
    std::uniform_real_distribution<double> x(-30.0, 350.0), y(-20.0, 260.0), size(5.0, 90.0);
    std::uniform_real_distribution<double> lw(25.0, 80.0), cx(120.0, 200.0), cy(90.0, 150.0);
    std::vector<LabelRequest> labels;
    for (int k = 0; k < 40; ++k) {
      LabelRequest r;
      if (k % 3 == 0) {  // an ellipse's centre in a crowd in the middle
        r.kind = LabelRequest::Anchor::kPoint;
        const double px = cx(rng), py = cy(rng);
        r.anchor = {px - 4, py - 4, px + 4, py + 4};
      } else {  // boxes anywhere, some across the border
        const double x0 = x(rng), y0 = y(rng);
        r.anchor = {x0, y0, x0 + size(rng), y0 + size(rng)};
      }
      r.width = lw(rng);
      r.height = 13;
      labels.push_back(r);
    }
    // With room to search the whole image every label finds a place (40 labels of at most 80 x 13
    // fill well under half of it).
    const auto everywhere = objects::place_labels(labels, width, height, 400.0);
    for (size_t k = 0; k < everywhere.size(); ++k) EXPECT_TRUE(everywhere[k].rect.valid()) << "label " << k;
    expect_disjoint_inside(placed_rects(everywhere), width, height);
    // With the default search radius some may be left out; those placed still obey the rules.
    const auto nearby = objects::place_labels(labels, width, height);
    expect_disjoint_inside(placed_rects(nearby), width, height);
    int left_out = 0;
    for (size_t k = 0; k < nearby.size(); ++k) {
      if (!nearby[k].rect.valid()) {
        ++left_out;
        continue;
      }
      EXPECT_NEAR(nearby[k].rect.width(), labels[k].width, 1e-9);  // moved, never resized
      EXPECT_NEAR(nearby[k].rect.height(), labels[k].height, 1e-9);
    }
    EXPECT_LE(left_out, 4);
  }
}

TEST(LabelPlacement, LabelsThatCannotFitAreLeftOut) {
  LabelRequest big;
  big.anchor = {10, 10, 20, 20};
  big.width = 400;  // wider than the image
  big.height = 12;
  LabelRequest fill;
  fill.anchor = {0, 0, 100, 20};
  fill.width = 100;
  fill.height = 20;  // exactly the image
  const auto placed = objects::place_labels({big, fill, fill}, 100, 20);
  EXPECT_FALSE(placed[0].rect.valid());
  EXPECT_TRUE(placed[1].rect.valid());
  EXPECT_FALSE(placed[2].rect.valid());  // the image is full
}

// A crowd of objects (a 5 x 5 grid of small ellipsoids a metre away, candidates among them), each
// with a detection: the overlay's labels, as drawn, do not overlap and stay in the image.
TEST(ObjectOverlay, CrowdedObjectsLabelsAreDisjointAndInTheImage) {
  PinholeCamera camera;
  camera.width = 640;
  camera.height = 480;
  camera.fx = camera.fy = 525.0;
  camera.cx = 319.5;
  camera.cy = 239.5;
  const SE3 T_wc;  // the world is the camera
  std::vector<objects::MapObject> objs;
  std::vector<objects::OverlayDetection> dets;
  for (int i = 0; i < 25; ++i) {
    objects::MapObject o;
    o.id = static_cast<objects::ObjectId>(i + 1);
    o.state = i % 4 == 3 ? objects::ObjectState::kCandidate : objects::ObjectState::kConfirmed;
    o.class_name = i % 2 ? "keyboard" : "cup";
    const Eigen::Vector3d centre(-0.3 + 0.15 * (i % 5), -0.2 + 0.1 * (i / 5), 1.0);
    o.quadric = DualQuadric::from_params(centre, Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.05, 0.04, 0.05));
    o.has_quadric = true;
    objs.push_back(o);
    const Eigen::Vector2d c = camera.project(centre);
    objects::OverlayDetection d;
    d.box = {c.x() - 30, c.y() - 25, c.x() + 30, c.y() + 25};
    d.class_name = o.class_name;
    d.score = 0.5f;
    d.object_id = o.id;
    dets.push_back(d);
  }
  const objects::OverlayLayout layout = objects::layout_object_overlay(camera, T_wc, dets, objs);
  EXPECT_EQ(layout.ellipses.size(), 25u);
  int candidates = 0;
  for (const auto& e : layout.ellipses) candidates += !e.confirmed;
  EXPECT_EQ(candidates, 6);
  ASSERT_EQ(layout.labels.size(), 50u);
  std::vector<Box2d> rects;
  int placed = 0;
  for (const auto& l : layout.labels) {
    if (!l.placed.rect.valid()) continue;
    ++placed;
    rects.push_back(l.placed.rect);
  }
  expect_disjoint_inside(rects, camera.width, camera.height);
  EXPECT_GE(placed, 45);  // a few detection labels may find no room near their box
  // Confirmed objects' labels come first and all find room.
  for (size_t k = 0; k < 19; ++k) {
    EXPECT_EQ(layout.labels[k].text.back() == '?', false);
    EXPECT_TRUE(layout.labels[k].placed.rect.valid()) << layout.labels[k].text;
  }
  EXPECT_EQ(layout.labels[19].text, "#4 keyboard?");
}

TEST(ObjectTable, ClassSharesCentreBoxAndObservations) {
  objects::MapObject o;
  o.id = 3;
  o.class_id = 41;
  o.class_name = "cup";
  o.class_votes = {{41, 3.0}, {45, 1.0}};
  o.has_quadric = true;
  o.quadric = DualQuadric::from_params({0.5, -0.25, 0.75}, Eigen::Matrix3d::Identity(), {0.05, 0.04, 0.06});
  o.observation_count = 12;
  const std::string table = system::object_table({o}, {{41, "cup"}, {45, "bowl"}});
  EXPECT_NE(table.find("cup 0.75, bowl 0.25"), std::string::npos) << table;
  EXPECT_NE(table.find("0.500 -0.250 0.750"), std::string::npos) << table;
  EXPECT_NE(table.find("0.10 0.08 0.12"), std::string::npos) << table;
  EXPECT_NE(table.find(" 12  0.500\n"), std::string::npos) << table;  // observations, P(exists) at log-odds 0
}

// The offline pipeline on `tiny` writes one overlay per keyframe, named by keyframe ID, of the
// keyframe's size, with something drawn on it; a second, shorter run into the same folder leaves
// only its own.
TEST(KeyframeOverlays, OnePngPerKeyframeFromTheOfflinePipeline) {
  std::string error;
  auto scene = sim::load_scene(std::string(DQO_SOURCE_DIR) + "/config/scenes/tiny.yaml", &dqo::load_mesh, &error);
  ASSERT_TRUE(scene) << error;
  const sim::SceneFrameSource source(std::move(*scene), 1.0, false, 2);
  char pattern[] = "/tmp/dqo_test_overlays_XXXXXX";
  ASSERT_NE(::mkdtemp(pattern), nullptr);
  const fs::path dir = fs::path(pattern) / "overlays";

  std::map<mapping::KeyframeId, ImageRgb8> images;  // each keyframe's own image, undrawn
  ImageRgb8 default_size;  // the first keyframe's overlay at the default min_width (640)
  auto run = [&](int max_frames, std::vector<mapping::KeyframeId>* keyframes) {
    mapping::GaussianMapperParams mp;
    mp.trainer.iterations = 5;
    mp.threads = 2;
    mapping::GaussianMapper mapper(mp);
    auto log = std::make_shared<system::OverlayLog>();
    std::string e;
    // Drawn at the keyframes' own size (1: no enlargement), to compare with their images.
    system::ObjectStageObserver write = system::overlay_writer(dir.string(), log, &e, 1);
    EXPECT_TRUE(write) << e;
    system::OfflineStages stages;
    system::add_object_stage(objects::ObjectMapperParams(), system::DetectionSource::kDataset,
                             system::LabelSource::kQuadrics, source.info(), &stages, {},
                             [&](const system::ObjectStageView& v) {
                               keyframes->push_back(v.keyframe.id);
                               images[v.keyframe.id] = v.keyframe.rgb;
                               if (keyframes->size() == 1) default_size = system::keyframe_overlay(v);
                               write(v);
                             });
    system::OfflineMappingParams params;
    params.max_frames = max_frames;
    const system::OfflineResult r = system::run_offline_mapping(source, stages, params, &mapper);
    EXPECT_TRUE(r.ok) << r.error;
    EXPECT_TRUE(log->error.empty()) << log->error;
    EXPECT_EQ(log->written, r.keyframes);
    return r.keyframes;
  };
  auto pngs = [&dir] {
    int n = 0;
    for (const auto& e : fs::directory_iterator(dir)) n += e.path().extension() == ".png";
    return n;
  };

  std::vector<mapping::KeyframeId> keyframes;
  const int count = run(-1, &keyframes);
  ASSERT_GT(count, 3);
  ASSERT_EQ(keyframes.size(), static_cast<size_t>(count));
  EXPECT_EQ(pngs(), count);
  int drawn = 0;
  for (const mapping::KeyframeId id : keyframes) {
    const fs::path p = dir / system::keyframe_overlay_name(id);
    auto image = read_rgb_image(p.string(), &error);
    ASSERT_TRUE(image) << error;
    EXPECT_EQ(image->width, source.info().camera.width);
    EXPECT_EQ(image->height, source.info().camera.height);
    // Boxes, ellipses and labels drawn over the keyframe's image.
    const ImageRgb8& original = images.at(id);
    ASSERT_EQ(original.data.size(), image->data.size());
    size_t changed = 0;
    for (size_t i = 0; i < image->data.size(); ++i) changed += image->data[i] != original.data[i];
    drawn += changed > 300;
  }
  EXPECT_GE(drawn, count - 1);  // the first keyframe may have no object yet
  // By default a 160 x 120 keyframe is drawn four times as large.
  EXPECT_EQ(default_size.width, 4 * source.info().camera.width);
  EXPECT_EQ(default_size.height, 4 * source.info().camera.height);

  std::vector<mapping::KeyframeId> fewer;
  const int second = run(6, &fewer);
  ASSERT_LT(second, count);
  EXPECT_EQ(pngs(), second);
  fs::remove_all(pattern);
}

}  // namespace
}  // namespace dqo
