#pragma once
// ORB features of one RGB-D frame, after ORB-SLAM2's extractor: FAST corners found over a grid of
// cells on every level of a scale pyramid (a lower threshold where a cell has nothing stronger),
// spread evenly over the cells, oriented by the intensity centroid and described by OpenCV's
// rotated BRIEF; each keypoint carries the depth measured under it.
//
// Private to tracking/: OpenCV stays out of include/dqo_map.

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>

#include "dqo_map/common/image.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/tracking/tracker_params.h"
#include "fast_cells.h"

namespace dqo::tracking {

using Descriptor = std::array<uint64_t, 4>;  // 256 bits, OpenCV's ORB byte order

inline int hamming(const Descriptor& a, const Descriptor& b) {
  return __builtin_popcountll(a[0] ^ b[0]) + __builtin_popcountll(a[1] ^ b[1]) +
         __builtin_popcountll(a[2] ^ b[2]) + __builtin_popcountll(a[3] ^ b[3]);
}

struct Keypoint {
  Eigen::Vector2f uv;     // level-0 pixel coordinates
  float angle = 0.0f;     // degrees in [0, 360), intensity-centroid orientation
  float response = 0.0f;  // FAST score
  int octave = 0;         // pyramid level it was found on
  float depth = 0.0f;     // metres; 0 = no valid depth in [min_depth, max_depth]
  // The steepest change of depth towards a neighbour one level-pixel away, in metres per level-0
  // pixel: how much the depth moves when the keypoint is off by a pixel. Large across a depth
  // edge (or beside a hole), where the depth of a corner is ambiguous.
  float depth_slope = 0.0f;
  // Extra σ (metres) of the depth where depth and colour were not captured together (the
  // Tracker sets it: PoseOptimiserParams::asynchronous_depth_sigma_per_m2); 0 otherwise.
  float depth_sync_sigma = 0.0f;
};

// The scales of the pyramid, shared by extraction, matching and the optimisers.
struct ScalePyramid {
  std::vector<float> scale;       // factor^level
  std::vector<float> inv_scale;
  std::vector<float> sigma2;      // variance of a keypoint position (px², level-0 units): scale²
  std::vector<float> inv_sigma2;
  float log_factor = 0.0f;

  ScalePyramid() = default;
  ScalePyramid(float factor, int levels);
  int levels() const { return static_cast<int>(scale.size()); }

  // The level at which a point with scale-invariance limit max_distance is expected to be found
  // when seen from `distance` (ORB-SLAM2's PredictScale).
  int predict_level(float distance, float max_distance) const;
};

constexpr int kKeypointGridCellPx = 16;  // the side of OrbFrame::grid's cells (level-0 pixels)

// Keypoint indices bucketed in square cells of the level-0 image, for window queries.
class KeypointGrid {
 public:
  void build(const std::vector<Keypoint>& keypoints, int width, int height, int cell_px);

  // Indices of keypoints inside the square window of half-side `radius` around `centre` whose
  // octave lies in [min_level, max_level] (max_level < 0: no upper bound).
  void query(const std::vector<Keypoint>& keypoints, const Eigen::Vector2f& centre, float radius,
             int min_level, int max_level, std::vector<int>* out) const;

 private:
  int cell_px_ = 16;
  int cols_ = 0;
  int rows_ = 0;
  std::vector<std::vector<int>> cells_;
};

struct OrbFrame {
  std::vector<Keypoint> keypoints;
  std::vector<Descriptor> descriptors;  // parallel to keypoints
  KeypointGrid grid;

  size_t size() const { return keypoints.size(); }
  bool has_depth(int i) const { return keypoints[i].depth > 0.0f; }
  // The keypoint's 3D point in the camera frame (needs has_depth(i)).
  Eigen::Vector3d point_c(int i, const PinholeCamera& camera) const {
    const Keypoint& k = keypoints[i];
    return camera.back_project(k.uv.x(), k.uv.y(), k.depth);
  }
  // The descriptors as an N x 32 CV_8U matrix (no copy; valid while `descriptors` is unchanged).
  cv::Mat descriptor_mat() const;
};

class OrbExtractor {
 public:
  explicit OrbExtractor(const OrbParams& params);

  const ScalePyramid& scales() const { return scales_; }

  // rgb: 3 channels; depth in metres, the same size (0 or NaN = none).
  void extract(const ImageRgb8& rgb, const DepthImage& depth, OrbFrame* out);

  // The same from a grey image (tests).
  void extract_grey(const cv::Mat& grey, const DepthImage* depth, OrbFrame* out);

 private:
  void build_pyramid(const cv::Mat& grey);
  void detect_level(int level, std::vector<cv::KeyPoint>* out);
  void describe_level(int level, std::vector<cv::KeyPoint>* keypoints, cv::Mat* descriptors);

  OrbParams params_;
  ScalePyramid scales_;
  std::vector<int> features_per_level_;
  std::vector<int> umax_;  // half-width of the orientation patch per row offset
  std::vector<cv::Mat> levels_;
  CellGrid cells_;  // detect_level's scratch, reused
  cv::Ptr<cv::ORB> describer_;
};

}  // namespace dqo::tracking
