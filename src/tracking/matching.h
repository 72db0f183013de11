#pragma once
// Data association between a frame's keypoints and 3D points: search by projection from a pose
// guess (window around the projection, Hamming distance, ratio test, orientation consistency)
// and brute-force descriptor matching for PnP (ORB-SLAM2's ORBmatcher without bag of words).

#include <cstdint>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"
#include "orb_frame.h"

namespace dqo::tracking {

constexpr int kHammingHigh = 100;  // ORB-SLAM2's TH_HIGH
constexpr int kHammingLow = 50;    // ORB-SLAM2's TH_LOW

// A 3D point to look for in a frame.
struct ProjectionCandidate {
  uint64_t map_point = 0;  // 0 for a point that lives only in the last frame
  Eigen::Vector3d p_w = Eigen::Vector3d::Zero();
  Descriptor descriptor{};
  int level = 0;         // octave it was last seen at (frame-to-frame search)
  float angle = -1.0f;   // keypoint angle it was last seen with; < 0: no orientation check
  // For map points (check_viewing): mean viewing direction and scale-invariance range.
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  float min_distance = 0.0f;
  float max_distance = 0.0f;
};

struct ProjectionSearch {
  double radius_px = 7.0;      // window half-side at level 0, multiplied by the level's scale
  int levels_below = 1;        // octave window around the expected level
  int levels_above = 1;
  int max_distance = kHammingHigh;
  float ratio = 1.0f;          // best < ratio * second best at the same level (1: off)
  bool check_orientation = true;  // needs the candidates' angles
  // Map points: predict the level from the distance, skip points seen at more than 60° from
  // their mean viewing direction or outside their distance range (ORB-SLAM2's isInFrustum).
  bool check_viewing = false;
};

struct Match {
  int keypoint = -1;
  int candidate = -1;
  int distance = 0;
};

// Projects every candidate with T_wc and matches it to the best keypoint of the frame inside its
// window; a keypoint keeps only its best candidate. Keypoints with `taken[k]` set are skipped.
// `in_frustum` (optional) receives, per candidate, whether it projected into the image and passed
// the viewing checks.
std::vector<Match> search_by_projection(const OrbFrame& frame, const PinholeCamera& camera,
                                        const ScalePyramid& scales, const SE3& T_wc,
                                        const std::vector<ProjectionCandidate>& candidates,
                                        const ProjectionSearch& search,
                                        const std::vector<char>* taken,
                                        std::vector<char>* in_frustum);

// Keeps the matches whose change of keypoint angle falls in the three fullest bins of a 30-bin
// histogram (the second and third only with at least a tenth of the first's count).
// reference_angle(m) gives the angle the matched point had; < 0 leaves the match alone.
template <typename AngleOf>
void keep_consistent_orientation(const OrbFrame& frame, AngleOf reference_angle,
                                 std::vector<Match>* matches);

// Brute-force matching of query descriptors to train descriptors: best match below max_distance
// and below ratio × the second best. Returns (query index, train index); each train index once.
std::vector<std::pair<int, int>> match_descriptors(const std::vector<Descriptor>& query,
                                                   const std::vector<Descriptor>& train,
                                                   float ratio, int max_distance);

// ---------------------------------------------------------------- implementation of the template

void orientation_filter(const std::vector<float>& rotation_deg, std::vector<char>* keep);

template <typename AngleOf>
void keep_consistent_orientation(const OrbFrame& frame, AngleOf reference_angle,
                                 std::vector<Match>* matches) {
  std::vector<float> rotation(matches->size(), -1.0f);
  for (size_t i = 0; i < matches->size(); ++i) {
    const float ref = reference_angle((*matches)[i]);
    if (ref < 0.0f) continue;
    float r = frame.keypoints[(*matches)[i].keypoint].angle - ref;
    if (r < 0.0f) r += 360.0f;
    rotation[i] = r;
  }
  std::vector<char> keep;
  orientation_filter(rotation, &keep);
  size_t out = 0;
  for (size_t i = 0; i < matches->size(); ++i)
    if (keep[i]) (*matches)[out++] = (*matches)[i];
  matches->resize(out);
}

}  // namespace dqo::tracking
