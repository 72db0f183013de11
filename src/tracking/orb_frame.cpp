#include "orb_frame.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include <opencv2/imgproc.hpp>

#include "fast_cells.h"

namespace dqo::tracking {
namespace {

constexpr int kPatchSize = 31;
constexpr int kHalfPatch = 15;
// ORB's descriptor reads a rotated 31x31 patch: keypoints stay this far from the border (OpenCV's
// compute() drops nearer ones), and FAST's circle needs 3 pixels more around the search area.
constexpr int kEdge = 19;
constexpr int kFastRadius = 3;

// The steepest one-sided change of depth from (x, y) to its four neighbours `step` pixels away,
// per pixel; a neighbour without depth counts as a 10 % jump (a hole beside a keypoint usually
// means an edge).
float depth_slope(const DepthImage& depth, int x, int y, int step) {
  const float z = depth.at(x, y);
  float slope = 0.0f;
  const int dx[4] = {step, -step, 0, 0};
  const int dy[4] = {0, 0, step, -step};
  for (int i = 0; i < 4; ++i) {
    const int nx = x + dx[i], ny = y + dy[i];
    if (nx < 0 || ny < 0 || nx >= depth.width || ny >= depth.height) continue;
    const float zn = depth.at(nx, ny);
    const float jump = std::isfinite(zn) && zn > 0.0f ? std::abs(zn - z) : 0.1f * z;
    slope = std::max(slope, jump / static_cast<float>(step));
  }
  return slope;
}

}  // namespace

// ---------------------------------------------------------------- ScalePyramid

ScalePyramid::ScalePyramid(float factor, int levels) {
  scale.resize(levels);
  inv_scale.resize(levels);
  sigma2.resize(levels);
  inv_sigma2.resize(levels);
  float s = 1.0f;
  for (int l = 0; l < levels; ++l) {
    scale[l] = s;
    inv_scale[l] = 1.0f / s;
    sigma2[l] = s * s;
    inv_sigma2[l] = 1.0f / (s * s);
    s *= factor;
  }
  log_factor = std::log(factor);
}

int ScalePyramid::predict_level(float distance, float max_distance) const {
  if (distance <= 0.0f) return 0;
  const int level = static_cast<int>(std::ceil(std::log(max_distance / distance) / log_factor));
  return std::clamp(level, 0, levels() - 1);
}

// ---------------------------------------------------------------- KeypointGrid

void KeypointGrid::build(const std::vector<Keypoint>& keypoints, int width, int height,
                         int cell_px) {
  cell_px_ = std::max(1, cell_px);
  cols_ = std::max(1, (width + cell_px_ - 1) / cell_px_);
  rows_ = std::max(1, (height + cell_px_ - 1) / cell_px_);
  cells_.assign(static_cast<size_t>(cols_) * rows_, {});
  for (size_t i = 0; i < keypoints.size(); ++i) {
    const int cx = std::clamp(static_cast<int>(keypoints[i].uv.x()) / cell_px_, 0, cols_ - 1);
    const int cy = std::clamp(static_cast<int>(keypoints[i].uv.y()) / cell_px_, 0, rows_ - 1);
    cells_[static_cast<size_t>(cy) * cols_ + cx].push_back(static_cast<int>(i));
  }
}

void KeypointGrid::query(const std::vector<Keypoint>& keypoints, const Eigen::Vector2f& centre,
                         float radius, int min_level, int max_level,
                         std::vector<int>* out) const {
  out->clear();
  if (cells_.empty()) return;
  const int x0 = std::max(0, static_cast<int>(std::floor((centre.x() - radius) / cell_px_)));
  const int x1 = std::min(cols_ - 1, static_cast<int>(std::floor((centre.x() + radius) / cell_px_)));
  const int y0 = std::max(0, static_cast<int>(std::floor((centre.y() - radius) / cell_px_)));
  const int y1 = std::min(rows_ - 1, static_cast<int>(std::floor((centre.y() + radius) / cell_px_)));
  for (int cy = y0; cy <= y1; ++cy) {
    for (int cx = x0; cx <= x1; ++cx) {
      for (const int i : cells_[static_cast<size_t>(cy) * cols_ + cx]) {
        const Keypoint& k = keypoints[i];
        if (k.octave < min_level || (max_level >= 0 && k.octave > max_level)) continue;
        if (std::abs(k.uv.x() - centre.x()) > radius || std::abs(k.uv.y() - centre.y()) > radius)
          continue;
        out->push_back(i);
      }
    }
  }
}

// ---------------------------------------------------------------- OrbFrame

cv::Mat OrbFrame::descriptor_mat() const {
  if (descriptors.empty()) return cv::Mat(0, 32, CV_8U);
  return cv::Mat(static_cast<int>(descriptors.size()), 32, CV_8U,
                 const_cast<uint64_t*>(descriptors.front().data()));
}

// ---------------------------------------------------------------- OrbExtractor

OrbExtractor::OrbExtractor(const OrbParams& params)
    : params_(params), scales_(params.scale_factor, std::max(1, params.num_levels)) {
  const int levels = scales_.levels();
  // Features per level fall geometrically with the level's area ratio (ORB-SLAM2).
  const double f = 1.0 / params_.scale_factor;
  double per_level = params_.num_features * (1.0 - f) / (1.0 - std::pow(f, levels));
  features_per_level_.resize(levels);
  int assigned = 0;
  for (int l = 0; l < levels - 1; ++l) {
    features_per_level_[l] = static_cast<int>(std::round(per_level));
    assigned += features_per_level_[l];
    per_level *= f;
  }
  features_per_level_[levels - 1] = std::max(0, params_.num_features - assigned);

  // The orientation patch is a disc of radius 15: umax_[dv] is its half-width at row offset dv.
  umax_.resize(kHalfPatch + 1);
  for (int dv = 0; dv <= kHalfPatch; ++dv)
    umax_[dv] = static_cast<int>(std::floor(std::sqrt(kHalfPatch * kHalfPatch - dv * dv) + 0.5));

  // One level, no detection: the describer only computes rBRIEF for the keypoints it is given,
  // with their angle (it blurs the level itself, as ORB does).
  describer_ = cv::ORB::create(params_.num_features, 1.2f, 1, kEdge, 0, 2, cv::ORB::HARRIS_SCORE,
                               kPatchSize, params_.fast_threshold);
}

void OrbExtractor::build_pyramid(const cv::Mat& grey) {
  const int levels = scales_.levels();
  levels_.resize(levels);
  levels_[0] = grey;
  for (int l = 1; l < levels; ++l) {
    const cv::Size size(static_cast<int>(std::round(grey.cols * scales_.inv_scale[l])),
                        static_cast<int>(std::round(grey.rows * scales_.inv_scale[l])));
    if (size.width < 2 * kEdge + 1 || size.height < 2 * kEdge + 1) {
      levels_[l] = cv::Mat();
      continue;
    }
    cv::resize(levels_[l - 1], levels_[l], size, 0, 0, cv::INTER_LINEAR);
  }
}

void OrbExtractor::detect_level(int level, std::vector<cv::KeyPoint>* out) {
  out->clear();
  const cv::Mat& image = levels_[level];
  const int wanted = features_per_level_[level];
  if (image.empty() || wanted <= 0) return;
  const int margin = kEdge - kFastRadius;
  const cv::Rect roi(margin, margin, image.cols - 2 * margin, image.rows - 2 * margin);
  if (roi.width <= 2 * kFastRadius || roi.height <= 2 * kFastRadius) return;

  // Per cell the corners that pass the high threshold, or where there are none those that pass
  // the low one (fast_cells.h; ORB-SLAM2 retries per cell instead).
  const int cell = std::max(8, params_.grid_cell_px);
  detect_cell_corners(image, roi, cell, params_.fast_threshold, params_.min_fast_threshold,
                      &cells_);
  size_t most = 0;
  for (auto& c : cells_.cells) {
    for (cv::KeyPoint& k : c) {
      k.pt.x += margin;
      k.pt.y += margin;
    }
    std::sort(c.begin(), c.end(),
              [](const cv::KeyPoint& a, const cv::KeyPoint& b) { return a.response > b.response; });
    most = std::max(most, c.size());
  }
  // Spread: the best corner of every cell first, then the second best, and so on; within one
  // rank the stronger corners go first, so the last rank taken keeps the best of its candidates.
  std::vector<cv::KeyPoint> rank;
  for (size_t r = 0; r < most && static_cast<int>(out->size()) < wanted; ++r) {
    rank.clear();
    for (const auto& c : cells_.cells)
      if (r < c.size()) rank.push_back(c[r]);
    const size_t room = static_cast<size_t>(wanted) - out->size();
    if (rank.size() > room) {
      std::partial_sort(rank.begin(), rank.begin() + static_cast<long>(room), rank.end(),
                        [](const cv::KeyPoint& a, const cv::KeyPoint& b) {
                          return a.response > b.response;
                        });
      rank.resize(room);
    }
    out->insert(out->end(), rank.begin(), rank.end());
  }

  // Intensity-centroid orientation on the unblurred level (ORB's IC_Angle).
  const int step = static_cast<int>(image.step1());
  for (cv::KeyPoint& k : *out) {
    const uchar* centre = image.ptr<uchar>(cvRound(k.pt.y), cvRound(k.pt.x));
    int m01 = 0, m10 = 0;
    for (int u = -kHalfPatch; u <= kHalfPatch; ++u) m10 += u * centre[u];
    for (int v = 1; v <= kHalfPatch; ++v) {
      int v_sum = 0;
      const int d = umax_[v];
      for (int u = -d; u <= d; ++u) {
        const int val_plus = centre[u + v * step], val_minus = centre[u - v * step];
        v_sum += val_plus - val_minus;
        m10 += u * (val_plus + val_minus);
      }
      m01 += v * v_sum;
    }
    float angle = cv::fastAtan2(static_cast<float>(m01), static_cast<float>(m10));
    if (angle >= 360.0f) angle -= 360.0f;
    k.angle = angle;
    k.octave = 0;  // the describer works on this level alone
    k.size = kPatchSize;
  }
}

void OrbExtractor::describe_level(int level, std::vector<cv::KeyPoint>* keypoints,
                                  cv::Mat* descriptors) {
  for (size_t i = 0; i < keypoints->size(); ++i) (*keypoints)[i].class_id = static_cast<int>(i);
  describer_->compute(levels_[level], *keypoints, *descriptors);
}

void OrbExtractor::extract(const ImageRgb8& rgb, const DepthImage& depth, OrbFrame* out) {
  const cv::Mat colour(rgb.height, rgb.width, CV_8UC3, const_cast<uint8_t*>(rgb.data.data()));
  cv::Mat grey;
  cv::cvtColor(colour, grey, cv::COLOR_RGB2GRAY);
  extract_grey(grey, &depth, out);
}

void OrbExtractor::extract_grey(const cv::Mat& grey, const DepthImage* depth, OrbFrame* out) {
  out->keypoints.clear();
  out->descriptors.clear();
  build_pyramid(grey);
  std::vector<cv::KeyPoint> level_keypoints;
  cv::Mat level_descriptors;
  for (int l = 0; l < scales_.levels(); ++l) {
    detect_level(l, &level_keypoints);
    if (level_keypoints.empty()) continue;
    describe_level(l, &level_keypoints, &level_descriptors);
    const float s = scales_.scale[l];
    for (size_t i = 0; i < level_keypoints.size(); ++i) {
      const cv::KeyPoint& k = level_keypoints[i];
      Keypoint kp;
      // Pixel centres at integer coordinates on every level (cv::resize's convention): level
      // pixel x covers level-0 [x s, (x + 1) s), centre (x + 0.5) s - 0.5. ORB-SLAM2's x s is up
      // to 1.3 px off at the top level.
      kp.uv = Eigen::Vector2f((k.pt.x + 0.5f) * s - 0.5f, (k.pt.y + 0.5f) * s - 0.5f);
      kp.angle = k.angle;
      kp.response = k.response;
      kp.octave = l;
      if (depth != nullptr && !depth->empty()) {
        const int x = std::clamp(static_cast<int>(std::lround(kp.uv.x())), 0, depth->width - 1);
        const int y = std::clamp(static_cast<int>(std::lround(kp.uv.y())), 0, depth->height - 1);
        const float z = depth->at(x, y);
        if (std::isfinite(z) && z >= params_.min_depth && z <= params_.max_depth) {
          kp.depth = z;
          kp.depth_slope = depth_slope(*depth, x, y, std::max(1, static_cast<int>(std::lround(s))));
        }
      }
      Descriptor d;
      std::memcpy(d.data(), level_descriptors.ptr<uchar>(static_cast<int>(i)), 32);
      out->keypoints.push_back(kp);
      out->descriptors.push_back(d);
    }
  }
  out->grid.build(out->keypoints, grey.cols, grey.rows, kKeypointGridCellPx);
}

}  // namespace dqo::tracking
