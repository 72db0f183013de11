// The detector end to end on ONNX models built in the test (yolo_fixture.h): each export layout
// (YOLOv5, YOLOv8/v11, YOLOv10's one-to-many head, v8-seg, v5-seg) with known constant outputs
// gives exactly the boxes, classes, scores and masks worked out here by hand after letterbox
// inversion and NMS; each kind of unusable model gives a clear error at create().
#include <gtest/gtest.h>

#include <cmath>

#include "dqo_map/detector/yolo_detector.h"
#include "yolo_fixture.h"

namespace dqo::detector {
namespace {

using test::make_model;
using test::make_output;
using test::RawCandidate;
using test::TempDir;

constexpr int kIn = 64;  // model input 64x64; images 320x240: scale 0.2, 8 rows of padding above

std::vector<RawCandidate> scene() {
  return {
      {32, 30, 20, 8, 1, 0.9f, 1.f, {10.f, 0.f}},    // cup
      {33, 30, 20, 8, 1, 0.8f, 1.f, {0.f, 0.f}},     // cup, IoU 0.9 with the first: suppressed
      {32, 30, 20, 8, 2, 0.7f, 1.f, {0.f, 10.f}},    // book on the cup's box: kept (another class)
      {10, 10, 6, 6, 0, 0.2f, 1.f, {0.f, 0.f}},      // person below 0.25
      {50, 40, 12, 12, 0, 0.6f, 1.f, {-10.f, 0.f}},  // person
  };
}

// A random-looking image: the constant models ignore it, the pre-processing must not care.
ImageRgb8 image(int w = 320, int h = 240) {
  ImageRgb8 im(w, h, 3);
  for (size_t i = 0; i < im.data.size(); ++i) im.data[i] = static_cast<uint8_t>((i * 2654435761u) >> 24);
  return im;
}

class YoloDetectorTest : public ::testing::Test {
 protected:
  void SetUp() override { test::write_text(dir_.file("names.txt"), "person\ncup\nbook\n"); }
  YoloParams params(const std::string& model) const {
    YoloParams p;
    p.model = dir_.file(model);
    p.classes = dir_.file("names.txt");
    p.input_width = p.input_height = kIn;
    return p;
  }
  // Builds a model of `layout` (v5 rows or v8 columns) over scene(), with prototypes when seg.
  // YOLOv5 has 3 anchors x 84 grid points at 64x64, the v8 layout any number of candidates.
  bool build(const std::string& name, bool v5, bool seg) {
    const int nc = 3, nm = seg ? 2 : 0, n = v5 ? 252 : 12;
    std::vector<test::ModelOutput> outs;
    const std::vector<float> det = make_output(scene(), n, nc, nm, v5);
    outs.push_back({v5 ? std::vector<int>{1, n, 5 + nc + nm} : std::vector<int>{1, 4 + nc + nm, n}, det});
    if (seg) {  // prototype 0: +1 on columns 0-7, -1 on 8-15; prototype 1: 1
      std::vector<float> protos(2 * 16 * 16);
      for (int v = 0; v < 16; ++v)
        for (int u = 0; u < 16; ++u) protos[v * 16 + u] = u < 8 ? 1.f : -1.f, protos[256 + v * 16 + u] = 1.f;
      outs.push_back({{1, 2, 16, 16}, protos});
    }
    return make_model(dir_, name, kIn, kIn, outs);
  }
  TempDir dir_;
};

// What every layout must give for scene() on a 320x240 image: boxes (x_in - 0) / 0.2, (y_in - 8) / 0.2.
void expect_scene(const YoloDetections& r, const std::string& what) {
  ASSERT_EQ(r.detections.size(), 3u) << what;
  const struct { int cls; const char* name; float score; double x0, y0, x1, y1; } want[] = {
      {1, "cup", 0.9f, 110, 90, 210, 130}, {2, "book", 0.7f, 110, 90, 210, 130}, {0, "person", 0.6f, 220, 130, 280, 190}};
  for (int k = 0; k < 3; ++k) {
    const Detection2d& d = r.detections[k];
    EXPECT_EQ(d.class_id, want[k].cls) << what << " #" << k;
    EXPECT_EQ(d.class_name, want[k].name) << what;
    EXPECT_FLOAT_EQ(d.score, want[k].score) << what;
    EXPECT_NEAR(d.box.x_min, want[k].x0, 1e-3) << what;
    EXPECT_NEAR(d.box.y_min, want[k].y0, 1e-3) << what;
    EXPECT_NEAR(d.box.x_max, want[k].x1, 1e-3) << what;
    EXPECT_NEAR(d.box.y_max, want[k].y1, 1e-3) << what;
  }
}

TEST_F(YoloDetectorTest, EveryBoxLayoutGivesTheSameDetections) {
  ASSERT_TRUE(build("v8.onnx", false, false));
  ASSERT_TRUE(build("v5.onnx", true, false));
  for (const auto& [file, layout, name] :
       {std::tuple{"v8.onnx", YoloLayout::kAuto, "v8 auto"}, std::tuple{"v8.onnx", YoloLayout::kV8, "v8"},
        std::tuple{"v8.onnx", YoloLayout::kV10, "v10 one-to-many"}, std::tuple{"v5.onnx", YoloLayout::kAuto, "v5 auto"},
        std::tuple{"v5.onnx", YoloLayout::kV5, "v5"}}) {
    YoloParams p = params(file);
    p.layout = layout;
    std::string error;
    auto det = YoloDetector::create(p, &error);
    ASSERT_TRUE(det) << name << ": " << error;
    EXPECT_FALSE(det->segments());
    const YoloDetections r = det->detect(image());
    expect_scene(r, name);
    EXPECT_TRUE(r.instance.empty());
  }
}

TEST_F(YoloDetectorTest, SegModelsGiveTheInstanceImageTheBetterDetectionWinning) {
  ASSERT_TRUE(build("v8seg.onnx", false, true));
  ASSERT_TRUE(build("v5seg.onnx", true, true));
  for (const char* file : {"v8seg.onnx", "v5seg.onnx"}) {
    std::string error;
    auto det = YoloDetector::create(params(file), &error);
    ASSERT_TRUE(det) << file << ": " << error;
    ASSERT_TRUE(det->segments());
    const YoloDetections r = det->detect(image());
    expect_scene(r, file);
    ASSERT_EQ(r.instance.width, 320);
    ASSERT_EQ(r.instance.height, 240);
    // Prototype column of image pixel x: 0.05 (x + 0.5) - 0.5; the +1 side left of 7.5. Cup: the
    // left of its box; the book (same box, mask everywhere): the right; person: its whole box.
    size_t wrong = 0;
    for (int y = 0; y < 240; ++y)
      for (int x = 0; x < 320; ++x) {
        const bool left = 0.05 * (x + 0.5) - 0.5 < 7.5;
        const double cx = x + 0.5, cy = y + 0.5;
        uint16_t want = 0;
        if (cx >= 110 && cx <= 210 && cy >= 90 && cy <= 130) want = left ? 1 : 2;
        else if (cx >= 220 && cx <= 280 && cy >= 130 && cy <= 190) want = 3;
        if (r.instance.at(x, y) != want && wrong++ < 5)
          ADD_FAILURE() << file << " pixel " << x << "," << y << ": " << r.instance.at(x, y) << ", want " << want;
      }
    EXPECT_EQ(wrong, 0u) << file;
  }
}

TEST_F(YoloDetectorTest, KeepAndIgnoreClassesByName) {
  ASSERT_TRUE(build("v8.onnx", false, false));
  YoloParams p = params("v8.onnx");
  p.ignore_classes = {"book"};
  std::string error;
  auto det = YoloDetector::create(p, &error);
  ASSERT_TRUE(det) << error;
  std::vector<std::string> names;
  for (const auto& d : det->detect(image()).detections) names.push_back(d.class_name);
  EXPECT_EQ(names, std::vector<std::string>({"cup", "person"}));
  p.ignore_classes.clear();
  p.keep_classes = {"person"};
  det = YoloDetector::create(p, &error);
  ASSERT_TRUE(det) << error;
  const auto only = det->detect(image()).detections;
  ASSERT_EQ(only.size(), 1u);
  EXPECT_EQ(only[0].class_name, "person");
  // Other image sizes letterbox differently: a 240x320 (portrait) image pads the sides by 8.
  p.keep_classes.clear();
  det = YoloDetector::create(p, &error);
  ASSERT_TRUE(det) << error;
  const auto portrait = det->detect(image(240, 320)).detections;
  ASSERT_EQ(portrait.size(), 3u);
  EXPECT_NEAR(portrait[0].box.x_min, (22 - 8) / 0.2, 1e-3);
  EXPECT_NEAR(portrait[0].box.y_min, 26 / 0.2, 1e-3);
}

TEST_F(YoloDetectorTest, UnusableModelsAreRefusedAtStartWithAReason) {
  std::string error;
  auto expect_error = [&](const YoloParams& p, const std::string& part, const char* what) {
    error.clear();
    EXPECT_FALSE(YoloDetector::create(p, &error)) << what;
    EXPECT_NE(error.find(part), std::string::npos) << what << ": " << error;
  };
  expect_error(params("missing.onnx"), "model file not found", "missing file");
  test::write_text(dir_.file("text.onnx"), "this is not a protobuf\n");
  expect_error(params("text.onnx"), "not an ONNX model", "not ONNX");
  ASSERT_TRUE(make_model(dir_, "topk.onnx", kIn, kIn, {}, /*topk=*/true));
  expect_error(params("topk.onnx"), "one-to-many head", "YOLOv10 NMS-free (TopK)");
  ASSERT_TRUE(make_model(dir_, "image.onnx", kIn, kIn, {{{1, 2, 3, 4}, std::vector<float>(24, 0.5f)}}));
  expect_error(params("image.onnx"), "no [1, A, B] detection output", "a layout that matches none");
  ASSERT_TRUE(build("v8.onnx", false, false));
  test::write_text(dir_.file("four.txt"), "person\ncup\nbook\nlaptop\n");
  YoloParams p = params("v8.onnx");
  p.classes = dir_.file("four.txt");
  expect_error(p, "4 names", "a class file of the wrong length");
  p = params("v8.onnx");
  p.keep_classes = {"laptop"};
  expect_error(p, "'laptop'", "a class to keep that the names do not hold");
  p = params("v8.onnx");
  p.input_width = 100;
  expect_error(p, "multiples of 32", "input size");
  p = params("v8.onnx");
  p.classes = dir_.file("no_such_names.txt");
  expect_error(p, "cannot open", "names file missing");
  // A bad image is refused at detect(), and the detector goes on.
  p = params("v8.onnx");
  auto det = YoloDetector::create(p, &error);
  ASSERT_TRUE(det) << error;
  EXPECT_THROW(det->detect(ImageRgb8(10, 10, 1)), std::invalid_argument);
  EXPECT_EQ(det->detect(image()).detections.size(), 3u);
}

}  // namespace
}  // namespace dqo::detector
