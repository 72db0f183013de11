#include "dqo_map/io/image_io.h"

#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "io_test_util.h"

namespace dqo {
namespace {

TEST(ImageIo, RgbPngRoundTripKeepsChannelOrder) {
  test::TempDir tmp;
  ImageRgb8 image(5, 3, 3);
  std::mt19937 rng(1);
  for (auto& v : image.data) v = static_cast<uint8_t>(rng());
  image.at(0, 0, 0) = 255;  // a pure red pixel: a BGR/RGB mix-up would show as blue
  image.at(0, 0, 1) = 0;
  image.at(0, 0, 2) = 0;
  std::string error;
  ASSERT_TRUE(write_png(tmp / "c.png", image, &error)) << error;
  const auto back = read_rgb_image(tmp / "c.png", &error);
  ASSERT_TRUE(back) << error;
  EXPECT_EQ(back->width, 5);
  EXPECT_EQ(back->height, 3);
  EXPECT_EQ(back->channels, 3);
  EXPECT_EQ(back->data, image.data);
}

TEST(ImageIo, ReadsAPngMadeElsewhereInRgbOrder) {
  // A 2x1 RGB PNG made outside OpenCV (Python's zlib): a red pixel, then a blue one.
  const unsigned char kPng[] = {
      0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48,
      0x44, 0x52, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x01, 0x08, 0x02, 0x00, 0x00,
      0x00, 0x7b, 0x40, 0xe8, 0xdd, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x44, 0x41, 0x54, 0x78,
      0x9c, 0x63, 0xf8, 0xcf, 0x00, 0x04, 0xff, 0x01, 0x07, 0x00, 0x01, 0xff, 0xe2, 0x23,
      0x9e, 0x59, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};
  test::TempDir tmp;
  {
    std::ofstream out(tmp / "rb.png", std::ios::binary);
    out.write(reinterpret_cast<const char*>(kPng), sizeof(kPng));
  }
  std::string error;
  const auto image = read_rgb_image(tmp / "rb.png", &error);
  ASSERT_TRUE(image) << error;
  EXPECT_EQ(image->data, (std::vector<uint8_t>{255, 0, 0, 0, 0, 255}));
}

TEST(ImageIo, U16PngRoundTripIsExact) {
  test::TempDir tmp;
  Image<uint16_t> image(4, 2, 1);
  image.data = {0, 1, 2, 255, 256, 1000, 65534, 65535};
  std::string error;
  ASSERT_TRUE(write_png(tmp / "d.png", image, &error)) << error;
  const auto back = read_png_u16(tmp / "d.png", &error);
  ASSERT_TRUE(back) << error;
  EXPECT_EQ(back->data, image.data);
  EXPECT_EQ(back->width, 4);
  EXPECT_EQ(back->height, 2);
}

TEST(ImageIo, GreyAndRgbaAreReadAsRgb) {
  test::TempDir tmp;
  Image<uint8_t> grey(2, 1, 1);
  grey.data = {10, 200};
  Image<uint8_t> rgba(1, 1, 4);
  rgba.data = {1, 2, 3, 4};
  std::string error;
  ASSERT_TRUE(write_png(tmp / "g.png", grey, &error)) << error;
  ASSERT_TRUE(write_png(tmp / "a.png", rgba, &error)) << error;
  const auto g = read_rgb_image(tmp / "g.png", &error);
  ASSERT_TRUE(g) << error;
  EXPECT_EQ(g->data, (std::vector<uint8_t>{10, 10, 10, 200, 200, 200}));
  const auto a = read_rgb_image(tmp / "a.png", &error);
  ASSERT_TRUE(a) << error;
  EXPECT_EQ(a->data, (std::vector<uint8_t>{1, 2, 3}));
}

TEST(ImageIo, WrongKindsAreErrorsNamingTheFile) {
  test::TempDir tmp;
  Image<uint16_t> depth(2, 2, 1, 7);
  ImageRgb8 rgb(2, 2, 3, 9);
  std::string error;
  ASSERT_TRUE(write_png(tmp / "d.png", depth, &error)) << error;
  ASSERT_TRUE(write_png(tmp / "c.png", rgb, &error)) << error;
  EXPECT_FALSE(read_rgb_image(tmp / "d.png", &error));  // 16-bit is not colour
  EXPECT_NE(error.find("d.png"), std::string::npos) << error;
  EXPECT_FALSE(read_png_u16(tmp / "c.png", &error));
  EXPECT_NE(error.find("c.png"), std::string::npos) << error;
  EXPECT_FALSE(read_png_u16(tmp / "missing.png", &error));
  EXPECT_NE(error.find("missing.png"), std::string::npos) << error;
  test::write_text(tmp / "junk.png", "not a png");
  EXPECT_FALSE(read_rgb_image(tmp / "junk.png", &error));
  EXPECT_FALSE(write_png(tmp / "x.jpg", rgb, &error));  // a PNG needs a .png name
  EXPECT_FALSE(write_png(tmp / "e.png", ImageRgb8(), &error));
  EXPECT_FALSE(write_png(tmp / "nodir/e.png", rgb, &error));
}

TEST(ImageIo, JpegIsCloseToTheOriginal) {
  test::TempDir tmp;
  ImageRgb8 image(16, 16, 3);
  for (int y = 0; y < 16; ++y) {
    for (int x = 0; x < 16; ++x) {
      image.at(x, y, 0) = static_cast<uint8_t>(200);
      image.at(x, y, 1) = static_cast<uint8_t>(60);
      image.at(x, y, 2) = static_cast<uint8_t>(20);
    }
  }
  std::string error;
  ASSERT_TRUE(write_jpeg(tmp / "c.jpg", image, 95, &error)) << error;
  const auto back = read_rgb_image(tmp / "c.jpg", &error);
  ASSERT_TRUE(back) << error;
  EXPECT_NEAR(back->at(8, 8, 0), 200, 4);
  EXPECT_NEAR(back->at(8, 8, 1), 60, 4);
  EXPECT_NEAR(back->at(8, 8, 2), 20, 4);
}

TEST(DepthEncoding, RoundsToTheScaleAndMarksOutOfRangeInvalid) {
  DepthImage depth(8, 1, 1);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  depth.data = {0.0f, 1.0f, 1.0004f, 1.0006f, -1.0f, nan, inf, 70.0f};
  const Image<uint16_t> stored = depth_to_u16(depth, 1000.0);
  EXPECT_EQ(stored.data, (std::vector<uint16_t>{0, 1000, 1000, 1001, 0, 0, 0, 0}));
  // 65.535 m is the last value that fits at scale 1000; 65.5355 rounds to 65536: invalid.
  DepthImage edge(3, 1, 1);
  edge.data = {65.535f, 65.5356f, 0.0004f};
  EXPECT_EQ(depth_to_u16(edge, 1000.0).data, (std::vector<uint16_t>{65535, 0, 0}));

  const DepthImage back = depth_from_u16(stored, 1000.0);
  EXPECT_EQ(back.data[1], 1.0f);
  EXPECT_EQ(back.data[3], static_cast<float>(1.001));
  EXPECT_EQ(back.data[0], 0.0f);
  EXPECT_EQ(quantise_depth(depth, 1000.0).data, back.data);
}

TEST(DepthEncoding, QuantisationIsIdempotent) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> uniform(0.0f, 12.0f);
  DepthImage depth(64, 64, 1);
  for (auto& d : depth.data) d = uniform(rng);
  for (const double scale : {1000.0, 5000.0, 6553.5}) {
    const DepthImage once = quantise_depth(depth, scale);
    EXPECT_EQ(quantise_depth(once, scale).data, once.data) << "scale " << scale;
    for (size_t i = 0; i < depth.data.size(); ++i) {
      if (once.data[i] == 0.0f) continue;
      ASSERT_LE(std::abs(once.data[i] - depth.data[i]), 0.5 / scale + 1e-6) << i;
    }
  }
}

}  // namespace
}  // namespace dqo
