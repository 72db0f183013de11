// YOLOX's raw export: the grid decode against boxes worked out here level by level, the layout told
// from YOLOv5 (and v8) by shape and input size with the ambiguous cases refused, the output check
// that refuses a model read in the wrong layout, YOLOX's input convention (BGR, 0..255, top-left
// letterbox) and its inverse, an ONNX model with a known YOLOX output end to end, and the real
// YOLOX-Nano (../shared/models/yolox_nano) on a real TUM frame against boxes drawn by hand.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <random>

#include "dqo_map/detector/letterbox.h"
#include "dqo_map/detector/yolo_decode.h"
#include "dqo_map/detector/yolo_detector.h"
#include "dqo_map/detector/yolo_input.h"
#include "dqo_map/detector/yolo_layout.h"
#include "yolo_fixture.h"

#ifdef DQO_DETECT_TOOL  // built where io/ is (the tool needs it too): the real-frame test reads a PNG
#include "dqo_map/io/image_io.h"
#endif

namespace dqo::detector {
namespace {

// The grid points of a YOLOX output in the export's order, enumerated level by level: stride 8,
// then 16, then 32, each grid row after row.
struct Point {
  int gx, gy, stride;
};
std::vector<Point> grid_points_in_order(int w, int h) {
  std::vector<Point> out;
  for (const int s : {8, 16, 32})
    for (int gy = 0; gy < h / s; ++gy)
      for (int gx = 0; gx < w / s; ++gx) out.push_back({gx, gy, s});
  return out;
}

// A YOLOX row: offsets and log sizes in strides, objectness, class scores.
struct XRow {
  float dx, dy, lw, lh, obj;
  std::vector<float> classes;
};
std::vector<float> rows_to_output(const std::vector<XRow>& rows) {
  std::vector<float> out;
  for (const XRow& r : rows) {
    out.insert(out.end(), {r.dx, r.dy, r.lw, r.lh, r.obj});
    out.insert(out.end(), r.classes.begin(), r.classes.end());
  }
  return out;
}

// Background as a trained model gives it: a box of one stride at each grid point, low scores.
std::vector<XRow> background(int n, int nc, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  std::vector<XRow> rows(n);
  for (XRow& r : rows) {
    r = {u(rng), u(rng), u(rng) - 0.5f, u(rng) - 0.5f, 0.02f * u(rng), std::vector<float>(nc)};
    for (float& c : r.classes) c = 0.1f * u(rng);
  }
  return rows;
}

TEST(Yolox, DecodesGridOffsetsOnEachStrideAsWorkedOutLevelByLevel) {
  // A 96x64 input (not square: a swapped width and height shows): 12x8 + 6x4 + 3x2 = 126 points.
  const int w = 96, h = 64, nc = 3;
  const std::vector<Point> points = grid_points_in_order(w, h);
  ASSERT_EQ(points.size(), 126u);
  EXPECT_EQ(grid_points(w, h), 126);
  EXPECT_EQ(grid_points(416, 416), 3549) << "52x52 + 26x26 + 13x13";
  OutputLayout l;
  std::string error;
  ASSERT_TRUE(identify_layout({{1, 126, 5 + nc}}, YoloLayout::kAuto, nc, w, h, &l, &error)) << error;
  ASSERT_EQ(l.layout, YoloLayout::kX);
  EXPECT_TRUE(l.objectness());
  EXPECT_FALSE(l.channels_first());

  std::vector<XRow> rows = background(126, nc, 3);
  // Three objects, one per level, at points found in the enumeration above.
  auto index_of = [&](int gx, int gy, int s) {
    for (size_t j = 0; j < points.size(); ++j)
      if (points[j].gx == gx && points[j].gy == gy && points[j].stride == s) return static_cast<int>(j);
    return -1;
  };
  const int a = index_of(11, 7, 8), b = index_of(2, 3, 16), c = index_of(1, 0, 32);
  ASSERT_EQ(a, 95);
  ASSERT_EQ(b, 96 + 3 * 6 + 2);
  ASSERT_EQ(c, 120 + 1);
  rows[a] = {0.25f, 0.75f, std::log(3.f), std::log(0.5f), 0.9f, {0.1f, 0.8f, 0.2f}};  // cup 0.72
  rows[b] = {-0.5f, 0.5f, 0.f, std::log(2.f), 0.8f, {0.1f, 0.2f, 0.5f}};              // book 0.4
  rows[c] = {0.5f, 1.5f, std::log(1.5f), std::log(1.25f), 0.7f, {0.95f, 0.1f, 0.f}};   // person 0.665
  const std::vector<float> out = rows_to_output(rows);

  // Every candidate's box: centre (offset + grid point) x stride, size exp(log size) x stride.
  for (size_t j = 0; j < points.size(); ++j) {
    const Point& p = points[j];
    const XRow& r = rows[j];
    const double cx = (r.dx + p.gx) * p.stride, cy = (r.dy + p.gy) * p.stride;
    const double bw = std::exp(r.lw) * p.stride, bh = std::exp(r.lh) * p.stride;
    const Box2d box = candidate_box(out.data(), l, static_cast<int>(j));
    ASSERT_NEAR(box.x_min, cx - bw / 2, 1e-4) << "candidate " << j;
    ASSERT_NEAR(box.y_min, cy - bh / 2, 1e-4) << "candidate " << j;
    ASSERT_NEAR(box.x_max, cx + bw / 2, 1e-4) << "candidate " << j;
    ASSERT_NEAR(box.y_max, cy + bh / 2, 1e-4) << "candidate " << j;
    int gx = -1, gy = -1, s = -1;
    ASSERT_TRUE(grid_cell(l, static_cast<int>(j), &gx, &gy, &s));
    ASSERT_EQ(gx, p.gx);
    ASSERT_EQ(gy, p.gy);
    ASSERT_EQ(s, p.stride);
  }
  int gx = 0, gy = 0, s = 0;
  EXPECT_FALSE(grid_cell(l, 126, &gx, &gy, &s));

  // The three objects, scored objectness x class, in input pixels (worked by hand).
  DecodeParams params;
  const std::vector<Candidate> kept = non_max_suppression(decode_candidates(out.data(), l, params), params);
  ASSERT_EQ(kept.size(), 3u);
  struct Want { int index, cls; float score; double x0, y0, x1, y1; };
  const Want want[] = {
      // (11.25 * 8, 7.75 * 8) = (90, 62), 24 x 4
      {a, 1, 0.72f, 78, 60, 102, 64},
      // person: (1.5 * 32, 1.5 * 32) = (48, 48), 48 x 40
      {c, 0, 0.665f, 24, 28, 72, 68},
      // (1.5 * 16, 3.5 * 16) = (24, 56), 16 x 32
      {b, 2, 0.4f, 16, 40, 32, 72},
  };
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(kept[k].index, want[k].index) << k;
    EXPECT_EQ(kept[k].class_id, want[k].cls) << k;
    EXPECT_NEAR(kept[k].score, want[k].score, 1e-6) << k;
    EXPECT_NEAR(kept[k].box.x_min, want[k].x0, 1e-4) << k;
    EXPECT_NEAR(kept[k].box.y_min, want[k].y0, 1e-4) << k;
    EXPECT_NEAR(kept[k].box.x_max, want[k].x1, 1e-4) << k;
    EXPECT_NEAR(kept[k].box.y_max, want[k].y1, 1e-4) << k;
  }
}

TEST(Yolox, LayoutFromRowsAndInputSizeAmbiguousOnesRefused) {
  OutputLayout l;
  std::string error;
  struct Case { std::vector<int> shape; int w, h; YoloLayout want; int candidates; };
  const Case cases[] = {
      {{1, 3549, 85}, 416, 416, YoloLayout::kX, 3549},    // YOLOX-Nano/Tiny: 52² + 26² + 13²
      {{1, 10647, 85}, 416, 416, YoloLayout::kV5, 10647}, // YOLOv5 at 416: 3 anchors each
      {{1, 8400, 85}, 640, 640, YoloLayout::kX, 8400},    // YOLOX-S..X at 640
      {{1, 25200, 85}, 640, 640, YoloLayout::kV5, 25200},
      {{1, 25500, 85}, 640, 640, YoloLayout::kV5, 25500}, // YOLOv5 P6: 3 x (8400 + 10²)
      {{1, 84, 8400}, 640, 640, YoloLayout::kV8, 8400},   // columns: YOLOv8, whatever N
      {{1, 84, 3549}, 416, 416, YoloLayout::kV8, 3549},
      {{3549, 85}, 416, 416, YoloLayout::kX, 3549},       // without the batch
      {{1, 3150, 85}, 320, 480, YoloLayout::kX, 3150},    // 40x60 + 20x30 + 10x15
  };
  for (const Case& c : cases) {
    const std::string what = shape_to_string(c.shape) + " at " + std::to_string(c.w) + "x" + std::to_string(c.h);
    ASSERT_TRUE(identify_layout({c.shape}, YoloLayout::kAuto, 80, c.w, c.h, &l, &error)) << what << ": " << error;
    EXPECT_EQ(l.layout, c.want) << what;
    EXPECT_EQ(l.num_candidates, c.candidates) << what;
    EXPECT_EQ(l.num_classes, 80) << what;
    EXPECT_EQ(l.input_width, c.w);
  }
  // YOLOX's rows at another input size than given: neither YOLOv5's 3 G nor YOLOX's G.
  EXPECT_FALSE(identify_layout({{1, 3549, 85}}, YoloLayout::kAuto, 80, 640, 640, &l, &error));
  EXPECT_NE(error.find("25200"), std::string::npos) << error;
  EXPECT_NE(error.find("8400"), std::string::npos) << error;
  EXPECT_NE(error.find("input_size"), std::string::npos) << error;
  EXPECT_NE(error.find("set layout"), std::string::npos) << error;
  EXPECT_FALSE(identify_layout({{1, 3550, 85}}, YoloLayout::kAuto, 80, 416, 416, &l, &error));
  // Declared, the layout is taken: v5 with any N (custom anchors), yolox only with its N.
  ASSERT_TRUE(identify_layout({{1, 3549, 85}}, YoloLayout::kV5, 80, 416, 416, &l, &error)) << error;
  EXPECT_EQ(l.layout, YoloLayout::kV5);
  ASSERT_TRUE(identify_layout({{1, 8400, 85}}, YoloLayout::kX, 80, 640, 640, &l, &error)) << error;
  EXPECT_EQ(l.layout, YoloLayout::kX);
  EXPECT_FALSE(identify_layout({{1, 25200, 85}}, YoloLayout::kX, 80, 640, 640, &l, &error));
  EXPECT_NE(error.find("8400 rows"), std::string::npos) << error;
  EXPECT_FALSE(identify_layout({{1, 84, 8400}}, YoloLayout::kX, 80, 640, 640, &l, &error)) << "columns";
  // YOLOX has no -seg export.
  EXPECT_FALSE(identify_layout({{1, 8400, 117}, {1, 32, 160, 160}}, YoloLayout::kAuto, 80, 640, 640, &l, &error));
  EXPECT_NE(error.find("no mask prototypes"), std::string::npos) << error;
  // The name.
  YoloLayout parsed = YoloLayout::kAuto;
  ASSERT_TRUE(parse_yolo_layout("yolox", &parsed));
  EXPECT_EQ(parsed, YoloLayout::kX);
  EXPECT_STREQ(to_string(YoloLayout::kX), "yolox");
}

TEST(Yolox, OutputCheckRefusesAnOutputReadInTheWrongLayout) {
  const int w = 416, h = 416, nc = 80, n = grid_points(w, h);
  const std::vector<float> raw = rows_to_output(background(n, nc, 5));
  OutputLayout x;
  std::string error;
  ASSERT_TRUE(identify_layout({{1, n, 5 + nc}}, YoloLayout::kAuto, nc, w, h, &x, &error)) << error;
  EXPECT_TRUE(check_output(raw.data(), x, &error)) << error;
  // The same values read as YOLOv5's pixels: every centre within 1 pixel of the corner.
  OutputLayout v5 = x;
  v5.layout = YoloLayout::kV5;
  EXPECT_FALSE(check_output(raw.data(), v5, &error));
  EXPECT_NE(error.find("YOLOv5"), std::string::npos) << error;
  // Decoded pixels (YOLOX exported with decode_in_inference) read as grid offsets: centres far out.
  std::vector<float> decoded = raw;
  const std::vector<Point> points = grid_points_in_order(w, h);
  for (int j = 0; j < n; ++j) {
    float* r = &decoded[static_cast<size_t>(j) * (5 + nc)];
    const Box2d b = candidate_box(raw.data(), x, j);
    r[0] = static_cast<float>(b.centre().x()), r[1] = static_cast<float>(b.centre().y());
    r[2] = static_cast<float>(b.width()), r[3] = static_cast<float>(b.height());
  }
  EXPECT_TRUE(check_output(decoded.data(), v5, &error)) << error;
  EXPECT_FALSE(check_output(decoded.data(), x, &error));
  // NaN, and scores that are logits rather than probabilities.
  std::vector<float> bad = raw;
  bad[7] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(check_output(bad.data(), x, &error));
  EXPECT_NE(error.find("NaN"), std::string::npos) << error;
  bad = raw;
  bad[4] = -3.f;  // objectness before the sigmoid
  EXPECT_FALSE(check_output(bad.data(), x, &error));
  EXPECT_NE(error.find("not [0, 1]"), std::string::npos) << error;
}

TEST(Yolox, TopLeftLetterboxMapsBoxesBackByTheScaleAlone) {
  // TUM's 640x480 into 416x416: r = 0.65, 416x312 in the top-left corner, 104 rows of padding below.
  const Letterbox a = Letterbox::make(640, 480, 416, 416, /*top_left=*/true);
  EXPECT_DOUBLE_EQ(a.scale, 0.65);
  EXPECT_EQ(a.resized_width, 416);
  EXPECT_EQ(a.resized_height, 312);
  EXPECT_EQ(a.pad_left, 0);
  EXPECT_EQ(a.pad_top, 0);
  const Box2d b = a.to_source(Box2d{65, 13, 130, 312});
  EXPECT_NEAR(b.x_min, 100, 1e-9);
  EXPECT_NEAR(b.y_min, 20, 1e-9);
  EXPECT_NEAR(b.x_max, 200, 1e-9);
  EXPECT_NEAR(b.y_max, 480, 1e-9);
  // The centred letterbox of the same image puts 52 rows above: the same input box is 80 px higher.
  const Letterbox c = Letterbox::make(640, 480, 416, 416);
  EXPECT_EQ(c.pad_top, 52);
  EXPECT_NEAR(c.to_source(Box2d{65, 60, 130, 100}).y_min, (60 - 52) / 0.65, 1e-9);
  // YOLOX sizes the image int(h r), Ultralytics round(h r): 200 * 64 / 300 = 42.67.
  EXPECT_EQ(Letterbox::make(300, 200, 64, 64, true).resized_height, 42);
  EXPECT_EQ(Letterbox::make(300, 200, 64, 64, false).resized_height, 43);
}

TEST(Yolox, InputConventionPerLayoutAndTheBlobItMakes) {
  const InputConvention x = resolve_input_convention({}, YoloLayout::kX);
  EXPECT_EQ(x.channels, ChannelOrder::kBgr);
  EXPECT_EQ(x.scale, 1.0);
  EXPECT_EQ(x.pad, PadPlacement::kTopLeft);
  for (const YoloLayout u : {YoloLayout::kV5, YoloLayout::kV8, YoloLayout::kV10}) {
    const InputConvention c = resolve_input_convention({}, u);
    EXPECT_EQ(c.channels, ChannelOrder::kRgb);
    EXPECT_DOUBLE_EQ(c.scale, 1.0 / 255.0);
    EXPECT_EQ(c.pad, PadPlacement::kCentre);
  }
  InputConvention wanted;
  ASSERT_TRUE(parse_channel_order("rgb", &wanted.channels));
  ASSERT_TRUE(parse_input_scale("1/255", &wanted.scale));
  EXPECT_EQ(resolve_input_convention(wanted, YoloLayout::kX).channels, ChannelOrder::kRgb) << "overrides stay";
  EXPECT_DOUBLE_EQ(resolve_input_convention(wanted, YoloLayout::kX).scale, 1.0 / 255.0);
  EXPECT_EQ(resolve_input_convention(wanted, YoloLayout::kX).pad, PadPlacement::kTopLeft);
  EXPECT_FALSE(parse_input_scale("-1", &wanted.scale));
  EXPECT_FALSE(parse_pad_placement("bottom", &wanted.pad));

  // A 32x16 image into a 32x32 input (scale 1, no resampling): pixel values chosen per channel.
  ImageRgb8 im(32, 16, 3);
  auto r = [](int u, int v) { return static_cast<uint8_t>(7 * u + v); };
  auto g = [](int, int v) { return static_cast<uint8_t>(100 + 3 * v); };
  auto b = [](int u, int v) { return static_cast<uint8_t>(200 + u - v); };
  for (int v = 0; v < 16; ++v)
    for (int u = 0; u < 32; ++u) {
      uint8_t* p = &im.data[(static_cast<size_t>(v) * 32 + u) * 3];
      p[0] = r(u, v), p[1] = g(u, v), p[2] = b(u, v);
    }
  std::vector<float> blob;
  // YOLOX: channel 0 is blue, values 0..255, the image in rows 0-15, grey 114 below.
  make_input_blob(im, Letterbox::make(32, 16, 32, 32, true), x, &blob);
  ASSERT_EQ(blob.size(), 3u * 32 * 32);
  auto at = [&](int c, int v, int u) { return blob[(static_cast<size_t>(c) * 32 + v) * 32 + u]; };
  size_t wrong = 0;
  for (int v = 0; v < 32; ++v)
    for (int u = 0; u < 32; ++u) {
      const bool in = v < 16;
      wrong += at(0, v, u) != (in ? b(u, v) : 114);
      wrong += at(1, v, u) != (in ? g(u, v) : 114);
      wrong += at(2, v, u) != (in ? r(u, v) : 114);
    }
  EXPECT_EQ(wrong, 0u) << "YOLOX input";
  // Ultralytics: channel 0 is red, values / 255, 8 grey rows above the image.
  make_input_blob(im, Letterbox::make(32, 16, 32, 32), resolve_input_convention({}, YoloLayout::kV8), &blob);
  wrong = 0;
  for (int v = 0; v < 32; ++v)
    for (int u = 0; u < 32; ++u) {
      const bool in = v >= 8 && v < 24;
      wrong += std::abs(at(0, v, u) - (in ? r(u, v - 8) : 114) / 255.f) > 1e-6f;
      wrong += std::abs(at(2, v, u) - (in ? b(u, v - 8) : 114) / 255.f) > 1e-6f;
    }
  EXPECT_EQ(wrong, 0u) << "Ultralytics input";
}

// ONNX models with a constant YOLOX output (yolo_fixture.h), 64x64 input: 8x8 + 4x4 + 2x2 = 84 rows.
class YoloxModelTest : public ::testing::Test {
 protected:
  void SetUp() override { test::write_text(dir_.file("names.txt"), "person\ncup\nbook\n"); }
  YoloParams params(const std::string& model) const {
    YoloParams p;
    p.model = dir_.file(model);
    p.classes = dir_.file("names.txt");
    p.input_width = p.input_height = 64;
    return p;
  }
  test::TempDir dir_;
};

TEST_F(YoloxModelTest, DetectsThroughTheTopLeftLetterboxAndRefusesDecodedRowsUnderAuto) {
  const std::vector<Point> points = grid_points_in_order(64, 64);
  std::vector<XRow> rows = background(84, 3, 9);
  for (size_t j = 0; j < points.size(); ++j) {
    if (points[j].stride == 8 && points[j].gx == 3 && points[j].gy == 4)  // cup: (28, 34), 20 x 8
      rows[j] = {0.5f, 0.25f, std::log(2.5f), 0.f, 1.f, {0.05f, 0.9f, 0.1f}};
    if (points[j].stride == 32 && points[j].gx == 1 && points[j].gy == 1)  // person: (32, 32), 16 x 16
      rows[j] = {0.f, 0.f, std::log(0.5f), std::log(0.5f), 0.8f, {0.75f, 0.1f, 0.1f}};
  }
  ASSERT_TRUE(test::make_model(dir_, "x.onnx", 64, 64, {{{1, 84, 8}, rows_to_output(rows)}}));
  std::string error;
  auto det = YoloDetector::create(params("x.onnx"), &error);
  ASSERT_TRUE(det) << error;
  EXPECT_EQ(det->layout().layout, YoloLayout::kX);
  EXPECT_EQ(det->input_convention().channels, ChannelOrder::kBgr);
  EXPECT_TRUE(det->input_convention().top_left());
  // A 320x240 image: scale 0.2, no padding above, so image = input / 0.2.
  const YoloDetections r = det->detect(ImageRgb8(320, 240, 3, 90));
  ASSERT_EQ(r.detections.size(), 2u);
  EXPECT_EQ(r.detections[0].class_name, "cup");
  EXPECT_NEAR(r.detections[0].score, 0.9f, 1e-6);
  EXPECT_NEAR(r.detections[0].box.x_min, (28 - 10) / 0.2, 1e-3);
  EXPECT_NEAR(r.detections[0].box.y_min, (34 - 4) / 0.2, 1e-3);
  EXPECT_NEAR(r.detections[0].box.x_max, (28 + 10) / 0.2, 1e-3);
  EXPECT_NEAR(r.detections[0].box.y_max, (34 + 4) / 0.2, 1e-3);
  EXPECT_EQ(r.detections[1].class_name, "person");
  EXPECT_NEAR(r.detections[1].score, 0.6f, 1e-6);
  EXPECT_NEAR(r.detections[1].box.x_min, 24 / 0.2, 1e-3);
  EXPECT_NEAR(r.detections[1].box.y_max, 40 / 0.2, 1e-3);
  // Declared as v5, the same output is refused: its boxes are not pixels.
  YoloParams p = params("x.onnx");
  p.layout = YoloLayout::kV5;
  EXPECT_FALSE(YoloDetector::create(p, &error));
  EXPECT_NE(error.find("not what the v5 layout gives"), std::string::npos) << error;
  EXPECT_NE(error.find("Set layout"), std::string::npos) << error;

  // YOLOX's row count with decoded pixel boxes: anchor-free, but not YOLOX's raw output.
  ASSERT_TRUE(test::make_model(dir_, "decoded.onnx", 64, 64,
                               {{{1, 84, 8}, test::make_output({{32, 30, 20, 8, 1, 0.9f, 1.f, {}}}, 84, 3, 0, true)}}));
  EXPECT_FALSE(YoloDetector::create(params("decoded.onnx"), &error));
  EXPECT_NE(error.find("decode_in_inference"), std::string::npos) << error;
  EXPECT_NE(error.find("set layout v5"), std::string::npos) << error;
  p = params("decoded.onnx");
  p.layout = YoloLayout::kV5;
  det = YoloDetector::create(p, &error);
  ASSERT_TRUE(det) << error;
  ASSERT_EQ(det->detect(ImageRgb8(320, 240, 3, 90)).detections.size(), 1u);

  // Scores before the sigmoid.
  for (XRow& row : rows) row.obj = 4.f * row.obj - 2.f;
  ASSERT_TRUE(test::make_model(dir_, "logits.onnx", 64, 64, {{{1, 84, 8}, rows_to_output(rows)}}));
  EXPECT_FALSE(YoloDetector::create(params("logits.onnx"), &error));
  EXPECT_NE(error.find("not [0, 1]"), std::string::npos) << error;
}

#ifdef DQO_DETECT_TOOL
// The real YOLOX-Nano on TUM fr1/desk frame 1305031463.927664 (a sharp one): the laptop in the
// top-left corner and the blue "Learning OpenCV"-sized book right of centre, boxed by hand on the
// image (corners read off a 20-pixel grid). A wrong letterbox (centred: 80 px off in y), channel
// order or decode loses them.
TEST(YoloxReal, NanoFindsTheLaptopAndTheBookOnARealDeskFrame) {
  std::error_code ec;
  const std::filesystem::path shared = (std::filesystem::canonical(DQO_SOURCE_DIR, ec) / "../shared").lexically_normal();
  const std::string model = (shared / "models/yolox_nano/yolox_nano.onnx").string();
  const std::string frame = (shared / "data/tum_fr1_desk_330/rgb/1305031463.927664.png").string();
  if (!std::filesystem::exists(model) || !std::filesystem::exists(frame)) {
    GTEST_SKIP() << "real model or frame not found (" << model << ", " << frame << ")";
  }
  YoloParams p;
  p.model = model;
  p.classes = DQO_SOURCE_DIR "/config/coco.names";
  p.input_width = p.input_height = 416;
  std::string error;
  auto det = YoloDetector::create(p, &error);
  ASSERT_TRUE(det) << error;
  EXPECT_EQ(det->layout().layout, YoloLayout::kX);
  EXPECT_EQ(det->layout().num_candidates, 3549);
  const auto image = read_rgb_image(frame, &error);
  ASSERT_TRUE(image) << error;
  const YoloDetections r = det->detect(*image);
  struct Truth { const char* name; Box2d box; };
  const Truth truths[] = {{"laptop", Box2d{0, 0, 125, 163}}, {"book", Box2d{322, 242, 528, 392}}};
  for (const Truth& t : truths) {
    double best = 0.0;
    for (const Detection2d& d : r.detections) {
      if (d.class_name == t.name) best = std::max(best, iou(d.box, t.box));
    }
    EXPECT_GE(best, 0.6) << t.name << ": no detection of that class overlaps the hand-drawn box enough";
  }
  for (const Detection2d& d : r.detections) {
    std::printf("  %s %.2f  %.0f %.0f %.0f %.0f\n", d.class_name.c_str(), d.score, d.box.x_min, d.box.y_min,
                d.box.x_max, d.box.y_max);
  }
}
#endif

}  // namespace
}  // namespace dqo::detector
