// detections_from_mask: boxes, classes and the renumbered instance image against what the test
// drew into the mask itself (shapes placed at known pixels), and the per-pixel relation between
// the input labels and the output instance image.
#include <gtest/gtest.h>

#include <random>
#include <set>

#include "dqo_map/common/mask_detections.h"

namespace dqo {
namespace {

// Fills the pixels of a disc (centre, radius) and returns its tight pixel extent.
struct Drawn {
  int min_x = 1 << 30, min_y = 1 << 30, max_x = -1, max_y = -1, pixels = 0;
};
Drawn draw_disc(LabelImage* img, uint32_t label, double cx, double cy, double r) {
  Drawn d;
  for (int y = 0; y < img->height; ++y) {
    for (int x = 0; x < img->width; ++x) {
      if ((x - cx) * (x - cx) + (y - cy) * (y - cy) > r * r) continue;
      img->at(x, y) = label;
      d.min_x = std::min(d.min_x, x), d.max_x = std::max(d.max_x, x);
      d.min_y = std::min(d.min_y, y), d.max_y = std::max(d.max_y, y);
      ++d.pixels;
    }
  }
  return d;
}

TEST(MaskDetections, BoxesClassesAndInstanceImage) {
  LabelImage mask(64, 48, 1, 0);
  // Labels out of order and with gaps, as real masks (object IDs) have.
  const Drawn d7 = draw_disc(&mask, 7, 20.0, 20.0, 6.0);
  const Drawn d3 = draw_disc(&mask, 3, 50.0, 10.0, 4.0);
  const Drawn d9 = draw_disc(&mask, 9, 10.0, 40.0, 5.0);
  MaskDetectionParams params;
  params.min_pixels = 1;
  params.classes[3] = {11, "cup"};
  params.classes[9] = {12, "book"};
  const MaskDetections r = detections_from_mask(mask, params);

  ASSERT_EQ(r.detections.size(), 3u);
  ASSERT_EQ(r.labels, (std::vector<uint32_t>{3, 7, 9}));
  const Drawn* drawn[] = {&d3, &d7, &d9};
  for (size_t k = 0; k < 3; ++k) {
    const Box2d& b = r.detections[k].box;
    EXPECT_DOUBLE_EQ(b.x_min, std::max(0.0, drawn[k]->min_x - 0.5)) << k;
    EXPECT_DOUBLE_EQ(b.x_max, std::min(64.0, drawn[k]->max_x + 0.5)) << k;
    EXPECT_DOUBLE_EQ(b.y_min, std::max(0.0, drawn[k]->min_y - 0.5)) << k;
    EXPECT_DOUBLE_EQ(b.y_max, std::min(48.0, drawn[k]->max_y + 0.5)) << k;
    EXPECT_EQ(r.pixel_counts[k], drawn[k]->pixels);
    EXPECT_FLOAT_EQ(r.detections[k].score, params.score);
  }
  EXPECT_EQ(r.detections[0].class_id, 11);
  EXPECT_EQ(r.detections[0].class_name, "cup");
  EXPECT_EQ(r.detections[1].class_id, params.default_class.class_id);  // 7 is not in the table
  EXPECT_EQ(r.detections[1].class_name, params.default_class.class_name);
  EXPECT_EQ(r.detections[2].class_name, "book");

  // Value k+1 exactly where the mask holds labels[k].
  ASSERT_EQ(r.instance.width, 64);
  ASSERT_EQ(r.instance.height, 48);
  for (size_t i = 0; i < mask.data.size(); ++i) {
    const uint16_t v = r.instance.data[i];
    if (mask.data[i] == 0) {
      EXPECT_EQ(v, 0) << i;
    } else {
      ASSERT_GE(v, 1) << i;
      EXPECT_EQ(r.labels[v - 1], mask.data[i]) << i;
    }
  }
}

TEST(MaskDetections, SmallAndUnknownInstancesAreDropped) {
  LabelImage mask(40, 30, 1, 0);
  const Drawn big = draw_disc(&mask, 5, 15.0, 15.0, 5.0);
  const Drawn small = draw_disc(&mask, 6, 33.0, 5.0, 1.0);
  draw_disc(&mask, 8, 33.0, 22.0, 4.0);  // unknown class
  ASSERT_LT(small.pixels, 10);
  MaskDetectionParams params;
  params.min_pixels = 10;
  params.skip_unknown = true;
  params.classes[5] = {1, "a"};
  params.classes[6] = {2, "b"};
  const MaskDetections r = detections_from_mask(mask, params);
  ASSERT_EQ(r.detections.size(), 1u);
  EXPECT_EQ(r.labels[0], 5u);
  EXPECT_EQ(r.pixel_counts[0], big.pixels);
  EXPECT_EQ(r.dropped_small, 1);
  EXPECT_EQ(r.dropped_unknown, 1);
  // Dropped instances are 0 in the instance image: it describes the published detections only.
  size_t ones = 0;
  for (size_t i = 0; i < mask.data.size(); ++i) {
    EXPECT_EQ(r.instance.data[i] != 0, mask.data[i] == 5) << i;
    ones += r.instance.data[i] == 1;
  }
  EXPECT_EQ(ones, static_cast<size_t>(big.pixels));
}

TEST(MaskDetections, ColourLabelsAndRandomMasks) {
  EXPECT_EQ(pack_rgb(0x12, 0x34, 0x56), 0x123456u);
  EXPECT_EQ(pack_rgb(0, 0, 0), 0u);
  // Random labels (colours) on random pixels: every box encloses its pixels exactly.
  std::mt19937 rng(3);
  LabelImage mask(50, 37, 1, 0);
  std::uniform_int_distribution<int> pick(0, 5);
  const uint32_t colours[] = {0, pack_rgb(255, 0, 0), pack_rgb(0, 255, 0), pack_rgb(0, 0, 255),
                              pack_rgb(1, 2, 3), pack_rgb(255, 255, 255)};
  for (auto& l : mask.data) l = colours[pick(rng)];
  MaskDetectionParams params;
  params.min_pixels = 1;
  const MaskDetections r = detections_from_mask(mask, params);
  ASSERT_EQ(r.detections.size(), 5u);
  for (size_t k = 0; k < r.labels.size(); ++k) {
    double x0 = 1e9, y0 = 1e9, x1 = -1e9, y1 = -1e9;
    int n = 0;
    for (int y = 0; y < mask.height; ++y) {
      for (int x = 0; x < mask.width; ++x) {
        if (mask.at(x, y) != r.labels[k]) continue;
        x0 = std::min(x0, x - 0.5), x1 = std::max(x1, x + 0.5);
        y0 = std::min(y0, y - 0.5), y1 = std::max(y1, y + 0.5);
        ++n;
      }
    }
    EXPECT_EQ(r.pixel_counts[k], n);
    EXPECT_DOUBLE_EQ(r.detections[k].box.x_min, std::max(0.0, x0));
    EXPECT_DOUBLE_EQ(r.detections[k].box.y_min, std::max(0.0, y0));
    EXPECT_DOUBLE_EQ(r.detections[k].box.x_max, std::min(50.0, x1));
    EXPECT_DOUBLE_EQ(r.detections[k].box.y_max, std::min(37.0, y1));
  }
}

TEST(MaskDetections, EmptyAndMalformedMasks) {
  const MaskDetections empty = detections_from_mask(LabelImage(8, 8, 1, 0), MaskDetectionParams());
  EXPECT_TRUE(empty.detections.empty());
  EXPECT_EQ(empty.instance.width, 8);
  LabelImage three(4, 4, 3, 1);  // not one channel
  EXPECT_TRUE(detections_from_mask(three, MaskDetectionParams()).detections.empty());
  LabelImage bad(4, 4, 1, 1);
  bad.data.resize(3);  // size disagrees with width x height
  EXPECT_TRUE(detections_from_mask(bad, MaskDetectionParams()).detections.empty());
}

}  // namespace
TEST(MaskDetections, InstanceImageForDetections) {
  // Two objects; detection 0 names object 7 by its gt_id, detection 1 has none and takes the ID
  // with most pixels in its box (5); where both claim pixels the higher score wins.
  InstanceImage gt(6, 2, 1, 0);
  gt.data = {7, 7, 7, 5, 5, 0,  //
             7, 7, 5, 5, 5, 0};
  std::vector<Detection2d> d(2);
  d[0].gt_id = 7;
  d[0].score = 0.9f;
  d[0].box = {-0.5, -0.5, 2.5, 1.5};
  d[1].score = 0.5f;
  d[1].box = {1.5, -0.5, 4.5, 1.5};
  const InstanceImage out = instance_for_detections(gt, d);
  const std::vector<uint16_t> expected = {1, 1, 1, 2, 2, 0,  //
                                          1, 1, 2, 2, 2, 0};
  EXPECT_EQ(out.data, expected);
}

}  // namespace dqo
