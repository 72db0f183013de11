// Undistortion: a synthetic distorted image of known points maps back to their pinhole positions,
// depth is resampled without blending, and bad calibrations or image sizes are refused. The
// distortion models are written out here (not taken from OpenCV) so that the check is independent.
#include <cmath>
#include <set>

#include <gtest/gtest.h>

#include "dqo_map/tracking/undistortion.h"

namespace {

using dqo::tracking::CameraCalibration;
using dqo::tracking::Undistorter;

constexpr int kW = 320;
constexpr int kH = 240;

CameraCalibration calibration(const std::string& model) {
  CameraCalibration c;
  c.width = kW;
  c.height = kH;
  c.K = {250.0, 0.0, 161.3, 0.0, 248.0, 118.7, 0.0, 0.0, 1.0};
  // The rectified camera differs a little from K, as a calibrated P may.
  c.P = {240.0, 0.0, 159.5, 0.0, 0.0, 240.0, 119.5, 0.0, 0.0, 0.0, 1.0, 0.0};
  c.distortion_model = model;
  if (model == "plumb_bob") {
    c.D = {-0.28, 0.07, 0.0012, -0.0008, 0.01};
  } else {
    // The Azure Kinect colour camera's coefficients are of this size.
    c.D = {0.52, -2.6, 0.0007, -0.0003, 1.45, 0.40, -2.45, 1.38};
  }
  return c;
}

// Rectified pixel -> raw pixel by the model's equations.
Eigen::Vector2d distort(const CameraCalibration& c, const Eigen::Vector2d& uv) {
  const double x = (uv.x() - c.P[2]) / c.P[0];
  const double y = (uv.y() - c.P[6]) / c.P[5];
  double d[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  for (size_t i = 0; i < c.D.size(); ++i) d[i] = c.D[i];
  const double r2 = x * x + y * y;
  const double radial = (1 + d[0] * r2 + d[1] * r2 * r2 + d[4] * r2 * r2 * r2) /
                        (1 + d[5] * r2 + d[6] * r2 * r2 + d[7] * r2 * r2 * r2);
  const double xd = x * radial + 2 * d[2] * x * y + d[3] * (r2 + 2 * x * x);
  const double yd = y * radial + d[2] * (r2 + 2 * y * y) + 2 * d[3] * x * y;
  return {c.K[0] * xd + c.K[1] * yd + c.K[2], c.K[4] * yd + c.K[5]};
}

std::vector<Eigen::Vector2d> known_points() {
  std::vector<Eigen::Vector2d> points;
  for (double v = 30.0; v <= kH - 30.0; v += 30.0) {
    for (double u = 30.0; u <= kW - 30.0; u += 32.5) points.emplace_back(u + 0.3, v - 0.2);
  }
  return points;
}

class UndistortionModels : public ::testing::TestWithParam<std::string> {};

TEST_P(UndistortionModels, KnownPointsMapBackWithinHalfAPixel) {
  const CameraCalibration c = calibration(GetParam());
  std::string error;
  const auto u = Undistorter::create(c, &error);
  ASSERT_TRUE(u) << error;
  EXPECT_FALSE(u->is_identity());
  EXPECT_EQ(u->camera().fx, 240.0);
  EXPECT_EQ(u->camera().cx, 159.5);

  // Gaussian dots drawn where the lens puts the known points.
  const auto points = known_points();
  constexpr double kSigma = 1.2;
  dqo::ImageRgb8 raw(kW, kH, 3, 0);
  std::vector<float> acc(kW * kH, 0.f);
  for (const auto& p : points) {
    const Eigen::Vector2d d = distort(c, p);
    for (int y = std::max(0, int(d.y()) - 6); y <= std::min(kH - 1, int(d.y()) + 6); ++y) {
      for (int x = std::max(0, int(d.x()) - 6); x <= std::min(kW - 1, int(d.x()) + 6); ++x) {
        const double r2 = (x - d.x()) * (x - d.x()) + (y - d.y()) * (y - d.y());
        acc[y * kW + x] += static_cast<float>(250.0 * std::exp(-0.5 * r2 / (kSigma * kSigma)));
      }
    }
  }
  for (int i = 0; i < kW * kH; ++i) {
    const auto v = static_cast<uint8_t>(std::min(255.f, std::round(acc[i])));
    for (int ch = 0; ch < 3; ++ch) raw.data[3 * i + ch] = v;
  }
  dqo::ImageRgb8 rect;
  ASSERT_TRUE(u->rectify_rgb(raw, &rect, &error)) << error;
  ASSERT_EQ(rect.width, kW);
  ASSERT_EQ(rect.channels, 3);

  double worst = 0.0;
  for (const auto& p : points) {
    double sum = 0.0, sx = 0.0, sy = 0.0;
    for (int y = int(p.y()) - 7; y <= int(p.y()) + 7; ++y) {
      for (int x = int(p.x()) - 7; x <= int(p.x()) + 7; ++x) {
        const double w = rect.at(x, y, 1);
        sum += w;
        sx += w * x;
        sy += w * y;
      }
    }
    ASSERT_GT(sum, 500.0) << "no dot near " << p.transpose();
    const double err = (Eigen::Vector2d(sx / sum, sy / sum) - p).norm();
    worst = std::max(worst, err);
    EXPECT_LT(err, 0.5) << "dot at " << p.transpose();
  }
  RecordProperty("worst_px", std::to_string(worst));

  // The point maps agree with the model both ways.
  for (const auto& p : points) {
    const Eigen::Vector2d d = distort(c, p);
    EXPECT_LT((u->distort_point(p) - d).norm(), 1e-6);
    EXPECT_LT((u->rectify_point(d) - p).norm(), 1e-4);
  }
}

INSTANTIATE_TEST_SUITE_P(Models, UndistortionModels, ::testing::Values("plumb_bob", "rational_polynomial"));

TEST(Undistortion, DepthIsResampledWithoutBlending) {
  const auto u = Undistorter::create(calibration("rational_polynomial"), nullptr);
  ASSERT_TRUE(u);
  // Two planes meeting at a vertical edge, and a hole.
  dqo::DepthImage raw(kW, kH, 1, 1.0f);
  for (int y = 0; y < kH; ++y) {
    for (int x = kW / 2; x < kW; ++x) raw.at(x, y) = 3.0f;
  }
  for (int y = 100; y < 110; ++y) {
    for (int x = 50; x < 60; ++x) raw.at(x, y) = 0.0f;
  }
  dqo::DepthImage rect;
  std::string error;
  ASSERT_TRUE(u->rectify_depth(raw, &rect, &error)) << error;
  std::set<float> values(rect.data.begin(), rect.data.end());
  for (float v : values) EXPECT_TRUE(v == 0.0f || v == 1.0f || v == 3.0f) << v;
  EXPECT_EQ(values.count(1.0f), 1u);
  EXPECT_EQ(values.count(3.0f), 1u);
}

TEST(Undistortion, ZeroDistortionIsACopy) {
  CameraCalibration c = calibration("plumb_bob");
  c.D.assign(5, 0.0);
  c.P = {};
  const auto u = Undistorter::create(c, nullptr);
  ASSERT_TRUE(u);
  EXPECT_TRUE(u->is_identity());
  EXPECT_EQ(u->camera().fx, 250.0);
  EXPECT_EQ(u->camera().cy, 118.7);
  dqo::ImageRgb8 raw(kW, kH, 4, 7);
  raw.at(3, 4, 2) = 99;
  dqo::ImageRgb8 rect;
  ASSERT_TRUE(u->rectify_rgb(raw, &rect, nullptr));
  EXPECT_EQ(rect.data, raw.data);
  EXPECT_EQ(u->rectify_point({10.5, 20.25}), Eigen::Vector2d(10.5, 20.25));
  // An empty model with no coefficients is a pinhole camera too (a CameraInfo left blank).
  c.distortion_model = "";
  c.D.clear();
  EXPECT_TRUE(Undistorter::create(c, nullptr));
}

TEST(Undistortion, RefusesBadCalibrationsAndSizes) {
  std::string error;
  CameraCalibration c = calibration("plumb_bob");
  c.distortion_model = "equidistant";
  EXPECT_FALSE(Undistorter::create(c, &error));
  EXPECT_NE(error.find("equidistant"), std::string::npos);
  c = calibration("plumb_bob");
  c.D.push_back(0.1);
  c.D.push_back(0.1);
  c.D.push_back(0.1);
  c.D.push_back(0.1);
  EXPECT_FALSE(Undistorter::create(c, &error));
  EXPECT_NE(error.find("takes 5"), std::string::npos) << error;
  c = calibration("plumb_bob");
  c.K[0] = 0.0;
  EXPECT_FALSE(Undistorter::create(c, &error));
  c = calibration("plumb_bob");
  c.width = 0;
  EXPECT_FALSE(Undistorter::create(c, &error));

  const auto u = Undistorter::create(calibration("plumb_bob"), &error);
  ASSERT_TRUE(u) << error;
  dqo::ImageRgb8 small(kW / 2, kH / 2, 3), out;
  EXPECT_FALSE(u->rectify_rgb(small, &out, &error));
  EXPECT_NE(error.find("160x120"), std::string::npos) << error;
  dqo::DepthImage two_channels(kW, kH, 2), dout;
  EXPECT_FALSE(u->rectify_depth(two_channels, &dout, &error));
}

}  // namespace
