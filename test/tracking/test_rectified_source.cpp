// A distorted dataset (camera.yaml with plumb_bob coefficients) seen through RectifiedFrameSource:
// the synthetic tabletop is rendered as a pinhole camera, then warped into a TUM-fr1-like lens
// by an independent route (cv::undistortPoints per raw pixel, not the Undistorter's remap), and
// the rectified frames must match the pinhole render and track as well as it does.
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>

#include "dqo_map/sim/renderer.h"
#include "dqo_map/sim/scene_loader.h"
#include "dqo_map/tracking/rectified_frame_source.h"
#include "dqo_map/tracking/tracker.h"

namespace {

using dqo::Frame;
using dqo::SE3;

// TUM fr1's lens (its README), k1 k2 p1 p2 k3.
const std::vector<double> kFr1 = {0.2624, -0.9531, -0.0054, 0.0026, 1.1633};

class VectorSource : public dqo::FrameSource {
 public:
  VectorSource(dqo::DatasetInfo info, std::vector<Frame> frames)
      : info_(std::move(info)), frames_(std::move(frames)) {}
  const dqo::DatasetInfo& info() const override { return info_; }
  int num_frames() const override { return static_cast<int>(frames_.size()); }
  std::optional<Frame> read_frame(int i, std::string*) const override { return frames_[i]; }

 private:
  dqo::DatasetInfo info_;
  std::vector<Frame> frames_;
};

// The raw image of a lens with coefficients D: raw pixel (u, v) sees the ray of pinhole pixel
// undistort(u, v). Colour bilinear, depth nearest (no blended surfaces); outside: 0.
Frame distort(const Frame& pinhole, const dqo::PinholeCamera& c, const std::vector<double>& D) {
  const int w = c.width, h = c.height;
  std::vector<cv::Point2f> raw;
  raw.reserve(static_cast<size_t>(w) * h);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) raw.emplace_back(static_cast<float>(u), static_cast<float>(v));
  const cv::Matx33d K(c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1);
  std::vector<cv::Point2f> ideal;
  cv::undistortPoints(raw, ideal, K, D, cv::noArray(), K,
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-6));
  Frame out = pinhole;
  out.rgb = dqo::ImageRgb8(w, h, 3);
  out.depth = dqo::DepthImage(w, h, 1);
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const cv::Point2f p = ideal[static_cast<size_t>(v) * w + u];
      const int x0 = static_cast<int>(std::floor(p.x)), y0 = static_cast<int>(std::floor(p.y));
      if (x0 < 0 || y0 < 0 || x0 + 1 >= w || y0 + 1 >= h) continue;
      const float ax = p.x - x0, ay = p.y - y0;
      for (int ch = 0; ch < 3; ++ch) {
        const float a = pinhole.rgb.at(x0, y0, ch) * (1 - ax) + pinhole.rgb.at(x0 + 1, y0, ch) * ax;
        const float b =
            pinhole.rgb.at(x0, y0 + 1, ch) * (1 - ax) + pinhole.rgb.at(x0 + 1, y0 + 1, ch) * ax;
        out.rgb.at(u, v, ch) = static_cast<uint8_t>(std::lround(a * (1 - ay) + b * ay));
      }
      out.depth.at(u, v) = pinhole.depth.at(static_cast<int>(std::lround(p.x)),
                                            static_cast<int>(std::lround(p.y)));
    }
  }
  return out;
}

class DistortedTabletop : public ::testing::Test {
 protected:
  static constexpr int kFrames = 30;
  static void SetUpTestSuite() {
    std::string error;
    scene_ = dqo::sim::load_scene(std::string(DQO_SOURCE_DIR) + "/config/scenes/tabletop.yaml",
                                  {}, &error)
                 .value();
    const dqo::sim::Renderer renderer(*scene_, 2);
    pinhole_ = std::make_unique<std::vector<Frame>>();
    distorted_ = std::make_unique<std::vector<Frame>>();
    for (int i = 0; i < kFrames; ++i) {
      pinhole_->push_back(renderer.render(i, true));
      distorted_->push_back(distort(pinhole_->back(), scene_->camera, kFr1));
    }
  }
  static void TearDownTestSuite() {
    pinhole_.reset();
    distorted_.reset();
    scene_.reset();
  }

  static std::shared_ptr<const dqo::FrameSource> distorted_source(const std::vector<double>& D) {
    dqo::DatasetInfo info;
    info.camera = scene_->camera;
    info.distortion_model = "plumb_bob";
    info.distortion = D;
    return std::make_shared<VectorSource>(info, *distorted_);
  }

  // RMS position error of the tracked frames (the world is the first camera's); every frame must
  // be tracked.
  static double track(const dqo::FrameSource& source) {
    // The local BA inside track(), so the two runs compared differ by their images alone, not
    // by when a worker thread finished (LocalBaParams::synchronous).
    dqo::tracking::TrackerParams params;
    params.local_ba.synchronous = true;
    dqo::tracking::Tracker tracker(source.info().camera, params);
    double sum = 0.0;
    for (int i = 0; i < source.num_frames(); ++i) {
      const auto f = source.read_frame(i);
      const dqo::tracking::RgbdInput input{f->timestamp, &f->rgb, &f->depth, std::nullopt};
      const dqo::tracking::TrackResult r = tracker.track(input);
      EXPECT_EQ(r.state, dqo::tracking::TrackingState::kOk) << "frame " << i;
      if (r.state != dqo::tracking::TrackingState::kOk) return INFINITY;
      const SE3 truth = (*pinhole_)[0].T_wc.inverse() * f->T_wc;
      sum += (r.T_wc.translation() - truth.translation()).squaredNorm();
    }
    return std::sqrt(sum / source.num_frames());
  }

  static inline std::optional<dqo::sim::Scene> scene_;
  static inline std::unique_ptr<std::vector<Frame>> pinhole_;
  static inline std::unique_ptr<std::vector<Frame>> distorted_;
};

TEST_F(DistortedTabletop, RectifiedImagesMatchThePinholeRender) {
  std::string error;
  const auto source = dqo::tracking::rectified(distorted_source(kFr1), &error);
  ASSERT_TRUE(source) << error;
  EXPECT_TRUE(source->info().distortion_model.empty());
  EXPECT_EQ(source->info().camera.fx, scene_->camera.fx);
  const auto f = source->read_frame(5, &error);
  ASSERT_TRUE(f) << error;
  const Frame& truth = (*pinhole_)[5];
  const Frame& raw = (*distorted_)[5];
  // Over the central half of the image (the border is lost to the lens): the rectified depth is
  // the pinhole depth nearly everywhere, the raw depth is not.
  int same_rectified = 0, same_raw = 0, valid = 0;
  double colour_error = 0.0;
  const int w = truth.depth.width, h = truth.depth.height;
  for (int v = h / 4; v < 3 * h / 4; ++v) {
    for (int u = w / 4; u < 3 * w / 4; ++u) {
      const float z = truth.depth.at(u, v);
      if (!(z > 0.0f)) continue;
      ++valid;
      same_rectified += std::abs(f->depth.at(u, v) - z) < 0.01f;
      same_raw += std::abs(raw.depth.at(u, v) - z) < 0.01f;
      colour_error += std::abs(f->rgb.at(u, v, 1) - truth.rgb.at(u, v, 1));
    }
  }
  ASSERT_GT(valid, 1000);
  EXPECT_GT(same_rectified, 0.95 * valid);
  EXPECT_LT(same_raw, 0.9 * same_rectified);
  EXPECT_LT(colour_error / valid, 6.0);  // grey levels: resampling twice blurs a little
}

TEST_F(DistortedTabletop, TrackedAsWellAsThePinholeRender) {
  std::string error;
  const auto rectified = dqo::tracking::rectified(distorted_source(kFr1), &error);
  ASSERT_TRUE(rectified) << error;
  dqo::DatasetInfo info;
  info.camera = scene_->camera;
  const VectorSource pinhole(info, *pinhole_);
  const double ate_pinhole = track(pinhole);
  const double ate_rectified = track(*rectified);
  EXPECT_LT(ate_pinhole, 0.005);
  EXPECT_LT(ate_rectified, std::max(1.5 * ate_pinhole, ate_pinhole + 0.002))
      << "pinhole " << ate_pinhole;
}

TEST(RectifiedSource, PinholeSourcesPassThroughAndBadLensesAreRefused) {
  dqo::DatasetInfo info;
  info.camera.width = 64;
  info.camera.height = 48;
  info.camera.fx = info.camera.fy = 50.0;
  info.camera.cx = 32.0;
  info.camera.cy = 24.0;
  auto pinhole = std::make_shared<VectorSource>(info, std::vector<Frame>{});
  std::string error;
  EXPECT_EQ(dqo::tracking::rectified(pinhole, &error), pinhole);  // no copy, no resampling
  info.distortion_model = "plumb_bob";
  info.distortion = {0, 0, 0, 0, 0};
  auto zero = std::make_shared<VectorSource>(info, std::vector<Frame>{});
  EXPECT_EQ(dqo::tracking::rectified(zero, &error), zero);
  info.distortion_model = "fisheye";
  info.distortion = {0.1, 0, 0, 0};
  EXPECT_EQ(dqo::tracking::rectified(std::make_shared<VectorSource>(info, std::vector<Frame>{}),
                                     &error),
            nullptr);
  EXPECT_NE(error.find("fisheye"), std::string::npos) << error;
}

}  // namespace
