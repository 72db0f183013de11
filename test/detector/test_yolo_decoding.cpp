// The detector's pure stages on arrays the test writes: the letterbox against Ultralytics' rule
// worked by hand, the output layouts (and their refusals), decoding and NMS, the instance masks.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "dqo_map/detector/class_names.h"
#include "dqo_map/detector/letterbox.h"
#include "dqo_map/detector/yolo_decode.h"
#include "dqo_map/detector/yolo_layout.h"
#include "dqo_map/detector/yolo_masks.h"
#include "yolo_fixture.h"

namespace dqo::detector {
namespace {

using test::make_output;
using test::RawCandidate;

TEST(Letterbox, MatchesUltralyticsRuleOnKnownSizes) {
  // 640x480 into 640x640: scale 1, 80 rows of padding above and below.
  const Letterbox a = Letterbox::make(640, 480, 640, 640);
  EXPECT_DOUBLE_EQ(a.scale, 1.0);
  EXPECT_EQ(a.resized_width, 640);
  EXPECT_EQ(a.resized_height, 480);
  EXPECT_EQ(a.pad_left, 0);
  EXPECT_EQ(a.pad_top, 80);
  // 1280x720 into 640x640: scale 0.5, 640x360, (640 - 360) / 2 = 140 above.
  const Letterbox b = Letterbox::make(1280, 720, 640, 640);
  EXPECT_DOUBLE_EQ(b.scale, 0.5);
  EXPECT_EQ(b.resized_height, 360);
  EXPECT_EQ(b.pad_top, 140);
  // 300x200 into 64x64: scale 64/300, 64 x round(42.67) = 43, padding 21 = 10.5: round(10.4) = 10 above.
  const Letterbox c = Letterbox::make(300, 200, 64, 64);
  EXPECT_DOUBLE_EQ(c.scale, 64.0 / 300.0);
  EXPECT_EQ(c.resized_height, 43);
  EXPECT_EQ(c.pad_top, 10);
  EXPECT_EQ(c.pad_left, 0);
  // A box back: input (0, 10)-(64, 53) is the whole image.
  const Box2d whole = c.to_source(Box2d{0, 10, 64, 10 + 64.0 * 200 / 300});
  EXPECT_NEAR(whole.x_min, 0, 1e-9);
  EXPECT_NEAR(whole.y_min, 0, 1e-9);
  EXPECT_NEAR(whole.x_max, 300, 1e-9);
  EXPECT_NEAR(whole.y_max, 200, 1e-9);
  EXPECT_THROW(Letterbox::make(0, 10, 64, 64), std::invalid_argument);
}

TEST(Letterbox, RoundTripsAndFitsOnRandomSizes) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> size(1, 4000), input(1, 40);
  for (int t = 0; t < 500; ++t) {
    const int w = size(rng), h = size(rng), iw = 32 * input(rng), ih = 32 * input(rng);
    const Letterbox l = Letterbox::make(w, h, iw, ih);
    ASSERT_LE(l.resized_width + l.pad_left, iw) << w << "x" << h << " into " << iw << "x" << ih;
    ASSERT_LE(l.resized_height + l.pad_top, ih);
    ASSERT_GE(l.pad_left, 0);
    ASSERT_GE(l.pad_top, 0);
    // One side fills the input (up to rounding).
    ASSERT_TRUE(std::abs(l.resized_width - iw) <= 1 || std::abs(l.resized_height - ih) <= 1);
    const double x = 0.37 * w, y = 0.81 * h;
    ASSERT_NEAR(l.to_source_x(l.to_input_x(x)), x, 1e-9 * w);
    ASSERT_NEAR(l.to_source_y(l.to_input_y(y)), y, 1e-9 * h);
  }
}

TEST(YoloLayout, PicksEachExportFromItsShapes) {
  OutputLayout l;
  std::string error;
  ASSERT_TRUE(identify_layout({{1, 84, 8400}}, YoloLayout::kAuto, 80, 640, 640, &l, &error)) << error;
  EXPECT_EQ(l.layout, YoloLayout::kV8);
  EXPECT_EQ(l.num_candidates, 8400);
  EXPECT_EQ(l.num_classes, 80);
  EXPECT_EQ(l.proto_output, -1);
  ASSERT_TRUE(identify_layout({{1, 25200, 85}}, YoloLayout::kAuto, 80, 640, 640, &l, &error)) << error;
  EXPECT_EQ(l.layout, YoloLayout::kV5);
  EXPECT_EQ(l.num_candidates, 25200);
  // -seg: prototypes second or first.
  ASSERT_TRUE(identify_layout({{1, 32, 160, 160}, {1, 116, 8400}}, YoloLayout::kAuto, 80, 640, 640, &l, &error)) << error;
  EXPECT_EQ(l.layout, YoloLayout::kV8);
  EXPECT_EQ(l.detection_output, 1);
  EXPECT_EQ(l.proto_output, 0);
  EXPECT_EQ(l.mask_dim, 32);
  EXPECT_EQ(l.num_classes, 80);
  EXPECT_EQ(l.proto_height, 160);
  ASSERT_TRUE(identify_layout({{1, 25200, 117}, {1, 32, 160, 160}}, YoloLayout::kAuto, 80, 640, 640, &l, &error)) << error;
  EXPECT_EQ(l.layout, YoloLayout::kV5);
  EXPECT_EQ(l.num_classes, 80);
  // Few candidates (as the tests' models have): the class count decides, not the shape's proportions.
  ASSERT_TRUE(identify_layout({{1, 7, 10}}, YoloLayout::kAuto, 3, 64, 64, &l, &error)) << error;
  EXPECT_EQ(l.layout, YoloLayout::kV8);
  ASSERT_TRUE(identify_layout({{1, 252, 8}}, YoloLayout::kAuto, 3, 64, 64, &l, &error)) << error;
  EXPECT_EQ(l.layout, YoloLayout::kV5) << "3 anchors x (8x8 + 4x4 + 2x2) = 252 rows at 64x64";
  // v10 (one-to-many head) is v8's layout when asked for.
  ASSERT_TRUE(identify_layout({{84, 8400}}, YoloLayout::kV10, 80, 640, 640, &l, &error)) << error;
  EXPECT_EQ(l.layout, YoloLayout::kV10);
  EXPECT_TRUE(l.channels_first());
}

TEST(YoloLayout, RefusesWhatMatchesNoExportWithAReason) {
  OutputLayout l;
  std::string error;
  EXPECT_FALSE(identify_layout({{1, 2, 3, 4}}, YoloLayout::kAuto, 80, 640, 640, &l, &error));
  EXPECT_NE(error.find("no [1, A, B] detection output"), std::string::npos) << error;
  EXPECT_FALSE(identify_layout({{1, 84, 8400}, {1, 84, 8400}}, YoloLayout::kAuto, 80, 640, 640, &l, &error));
  EXPECT_NE(error.find("match no YOLO export"), std::string::npos) << error;
  EXPECT_FALSE(identify_layout({{1, 300, 6}}, YoloLayout::kAuto, 80, 640, 640, &l, &error));
  EXPECT_NE(error.find("NMS-free"), std::string::npos) << error;
  // The class count: 81 names for an 80-class model.
  EXPECT_FALSE(identify_layout({{1, 84, 8400}}, YoloLayout::kAuto, 81, 640, 640, &l, &error));
  EXPECT_NE(error.find("81 names"), std::string::npos) << error;
  EXPECT_NE(error.find("80 classes"), std::string::npos) << error;
  EXPECT_FALSE(identify_layout({{1, 84, 8400}}, YoloLayout::kV5, 80, 640, 640, &l, &error)) << "8400 - 5 classes";
  EXPECT_FALSE(identify_layout({{1, 3, 3}}, YoloLayout::kAuto, 0, 640, 640, &l, &error));
}

// Three classes; candidates in input pixels of a 64x64 input.
std::vector<RawCandidate> scene() {
  return {
      {32, 30, 20, 8, 1, 0.9f, 1.f, {10.f, 0.f}},   // 0: cup
      {33, 30, 20, 8, 1, 0.8f, 1.f, {0.f, 0.f}},    // 1: cup, IoU 0.9 with 0: suppressed
      {32, 30, 20, 8, 2, 0.7f, 1.f, {0.f, 10.f}},   // 2: book, same box as 0: another class, kept
      {10, 10, 6, 6, 0, 0.2f, 1.f, {0.f, 0.f}},     // 3: person below the threshold
      {50, 40, 12, 12, 0, 0.6f, 1.f, {-10.f, 0.f}}, // 4: person
  };
}

TEST(YoloDecode, ScoresBoxesAndSuppressesInBothLayouts) {
  for (const bool v5 : {false, true}) {
    std::vector<RawCandidate> c = scene();
    if (v5) c.push_back({12, 50, 8, 10, 2, 0.8f, 0.5f, {}});  // 5: book at 0.5 * 0.8 = 0.4
    const int n = 12, nc = 3;
    const std::vector<float> out = make_output(c, n, nc, 0, v5);
    OutputLayout l;
    std::string error;
    ASSERT_TRUE(identify_layout({v5 ? std::vector<int>{1, n, 5 + nc} : std::vector<int>{1, 4 + nc, n}},
                                v5 ? YoloLayout::kV5 : YoloLayout::kAuto, nc, 64, 64, &l, &error)) << error;
    DecodeParams p;
    const std::vector<Candidate> all = decode_candidates(out.data(), l, p);
    ASSERT_EQ(all.size(), v5 ? 5u : 4u) << "above 0.25: 0, 1, 2, 4 (and 5)";
    EXPECT_EQ(all[0].index, 0);
    EXPECT_EQ(all[0].class_id, 1);
    EXPECT_FLOAT_EQ(all[0].score, 0.9f);
    EXPECT_DOUBLE_EQ(all[0].box.x_min, 22.0);
    EXPECT_DOUBLE_EQ(all[0].box.y_max, 34.0);
    const std::vector<Candidate> kept = non_max_suppression(all, p);
    std::vector<int> order;
    for (const auto& k : kept) order.push_back(k.index);
    EXPECT_EQ(order, v5 ? std::vector<int>({0, 2, 4, 5}) : std::vector<int>({0, 2, 4})) << (v5 ? "v5" : "v8");
    if (v5) { EXPECT_FLOAT_EQ(kept.back().score, 0.4f); }
    // Classes switched off, and the cap.
    p.class_enabled = {1, 1, 0};  // no books
    std::vector<int> no_books;
    for (const auto& k : non_max_suppression(decode_candidates(out.data(), l, p), p)) no_books.push_back(k.index);
    EXPECT_EQ(no_books, std::vector<int>({0, 4}));
    p.class_enabled.clear();
    p.max_detections = 1;
    EXPECT_EQ(non_max_suppression(all, p).size(), 1u);
    // A stricter IoU threshold keeps the overlapping cup too.
    p.max_detections = 100;
    p.nms_iou = 0.95f;
    EXPECT_EQ(non_max_suppression(all, p).size(), order.size() + 1);
  }
}

TEST(YoloMasks, InstanceImageFollowsPrototypesBoxesAndScores) {
  // Input 64x64, prototypes 2 x 16x16: prototype 0 is +1 on columns 0-7 and -1 on 8-15, prototype
  // 1 is 1 everywhere. Cup (coefficients 10, 0): the left half of its box; book (0, 10): all of the
  // same box, so the right half once the better cup has the left; person (-10, 0): the right half,
  // which is all of its box.
  const int n = 12, nc = 3, nm = 2, ph = 16, pw = 16;
  const std::vector<float> out = make_output(scene(), n, nc, nm, false);
  std::vector<float> protos(static_cast<size_t>(nm) * ph * pw);
  for (int v = 0; v < ph; ++v)
    for (int u = 0; u < pw; ++u) {
      protos[static_cast<size_t>(v) * pw + u] = u < 8 ? 1.f : -1.f;
      protos[static_cast<size_t>(ph * pw) + v * pw + u] = 1.f;
    }
  OutputLayout l;
  std::string error;
  ASSERT_TRUE(identify_layout({{1, 4 + nc + nm, n}, {1, nm, ph, pw}}, YoloLayout::kAuto, nc, 64, 64, &l, &error)) << error;
  DecodeParams p;
  const std::vector<Candidate> kept = non_max_suppression(decode_candidates(out.data(), l, p), p);
  ASSERT_EQ(kept.size(), 3u);
  const Letterbox lb = Letterbox::make(320, 240, 64, 64);  // scale 0.2, 8 rows of padding above
  const InstanceImage inst = instance_from_masks(out.data(), protos.data(), l, kept, lb, 0.5f);
  ASSERT_EQ(inst.width, 320);
  ASSERT_EQ(inst.height, 240);
  // Expected, worked out independently: image pixel x has input x 0.2 (x + 0.5) and prototype column
  // 0.05 (x + 0.5) - 0.5 (half-pixel centres); columns left of 7.5 are prototype 0's +1 side.
  // Boxes in the image: (x_in - 0) / 0.2, (y_in - 8) / 0.2.
  struct B { double x0, y0, x1, y1; };
  const B cup{110, 90, 210, 130}, person{220, 130, 280, 190};
  auto in = [](const B& b, int x, int y) { return x + 0.5 >= b.x0 && x + 0.5 <= b.x1 && y + 0.5 >= b.y0 && y + 0.5 <= b.y1; };
  size_t checked = 0, wrong = 0;
  for (int y = 0; y < 240; ++y)
    for (int x = 0; x < 320; ++x) {
      const double column = 0.05 * (x + 0.5) - 0.5;
      if (std::abs(column - 7.5) < 0.01) continue;
      const bool left = column < 7.5;
      uint16_t want = 0;
      if (in(cup, x, y)) want = left ? 1 : 2;   // cup (detection 0) or book (1)
      else if (in(person, x, y)) want = left ? 0 : 3;
      ++checked;
      if (inst.at(x, y) != want && wrong++ < 5) ADD_FAILURE() << "pixel " << x << "," << y << ": " << inst.at(x, y) << " want " << want;
    }
  EXPECT_EQ(wrong, 0u) << "of " << checked;
}

TEST(ClassNames, ReadsOneNamePerLineAndRefusesGaps) {
  test::TempDir dir;
  test::write_text(dir.file("ok.txt"), "person\n  dining table \ncup\n\n");
  std::string error;
  const auto names = read_class_names(dir.file("ok.txt"), &error);
  ASSERT_TRUE(names) << error;
  EXPECT_EQ(*names, std::vector<std::string>({"person", "dining table", "cup"}));
  test::write_text(dir.file("gap.txt"), "person\n\ncup\n");
  EXPECT_FALSE(read_class_names(dir.file("gap.txt"), &error));
  EXPECT_NE(error.find(":2: blank line"), std::string::npos) << error;
  EXPECT_FALSE(read_class_names(dir.file("missing.txt"), &error));
  test::write_text(dir.file("empty.txt"), "");
  EXPECT_FALSE(read_class_names(dir.file("empty.txt"), &error));
}

TEST(ClassNames, ShippedCocoListHasEightyClassesInOrder) {
  std::string error;
  const auto names = read_class_names(DQO_SOURCE_DIR "/config/coco.names", &error);
  ASSERT_TRUE(names) << error;
  ASSERT_EQ(names->size(), 80u);
  EXPECT_EQ(names->front(), "person");
  EXPECT_EQ((*names)[41], "cup");
  EXPECT_EQ((*names)[73], "book");
  EXPECT_EQ(names->back(), "toothbrush");
}

}  // namespace
}  // namespace dqo::detector
