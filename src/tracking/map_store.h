#pragma once
// The tracker's own sparse map: keyframes and map points in ID-keyed stores with one owner (the
// Tracker, on its thread). Objects refer to each other by ID, never by pointer, so erasing one
// leaves nothing dangling; the local BA thread never touches the store, it gets a snapshot
// (local_ba.h) and hands results back.

#include <cstdint>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"
#include "orb_frame.h"

namespace dqo::tracking {

constexpr uint64_t kNoId = 0;  // IDs start at 1

struct MapPoint {
  uint64_t id = kNoId;
  Eigen::Vector3d p_w = Eigen::Vector3d::Zero();
  Descriptor descriptor{};                        // the observation closest to all others
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // mean viewing direction (unit)
  float min_distance = 0.0f;                      // scale-invariance range (ORB-SLAM2)
  float max_distance = 0.0f;
  std::vector<std::pair<uint64_t, int>> observations;  // (keyframe ID, keypoint index)
  uint64_t first_keyframe = kNoId;
  uint64_t created_at_keyframe_count = 0;  // the store's keyframe count when it was created
  int visible = 1;  // frames whose frustum it fell into
  int found = 1;    // frames that matched it

  float found_ratio() const { return static_cast<float>(found) / std::max(1, visible); }
  int observation_of(uint64_t keyframe) const;  // keypoint index, -1 when not observed there
};

struct KeyFrame {
  uint64_t id = kNoId;
  uint64_t frame_number = 0;  // the tracker's frame counter when it was taken
  SE3 T_wc;
  OrbFrame features;
  std::vector<uint64_t> map_points;  // per keypoint: map point ID or kNoId
  // Covisibility: other keyframes sharing at least one map point, with the count.
  std::unordered_map<uint64_t, int> covisibility;
  std::vector<std::pair<int, uint64_t>> ordered_covisible;  // (weight, ID), heaviest first
  // Dense odometry from the previous keyframe (kNoId when some frame between them was not
  // densely aligned): the tracked relative pose and its information (right perturbation).
  uint64_t odometry_from = kNoId;
  SE3 T_odometry;  // T_from_this
  Eigen::Matrix<double, 6, 6> odometry_information = Eigen::Matrix<double, 6, 6>::Zero();
};

class MapStore {
 public:
  // Add objects and get their new IDs (the `id` fields are overwritten).
  uint64_t add_keyframe(KeyFrame keyframe);
  uint64_t add_map_point(MapPoint point);

  KeyFrame* keyframe(uint64_t id);
  const KeyFrame* keyframe(uint64_t id) const;
  MapPoint* map_point(uint64_t id);
  const MapPoint* map_point(uint64_t id) const;

  // Links a point and a keypoint of a keyframe (both ways). Replaces an earlier link of that
  // keypoint.
  void add_observation(uint64_t point, uint64_t keyframe, int keypoint);
  // Unlinks; a point left with no observation is erased.
  void erase_observation(uint64_t point, uint64_t keyframe);
  // Erases the point and every link to it.
  void erase_map_point(uint64_t point);

  // Recomputes a keyframe's covisibility from its map points and updates its neighbours' weights.
  void update_covisibility(uint64_t keyframe);
  // The keyframe's map points seen by at least min_observations keyframes (ORB-SLAM2's
  // TrackedMapPoints, used by the keyframe policy).
  int tracked_points(uint64_t keyframe, int min_observations) const;
  // Up to n covisible keyframes, heaviest first.
  std::vector<uint64_t> covisible(uint64_t keyframe, size_t n) const;

  // Distinctive descriptor, viewing direction and distance range from the point's observations.
  void update_point_appearance(uint64_t point, const ScalePyramid& scales);

  void clear();
  size_t num_keyframes() const { return keyframes_.size(); }
  size_t num_map_points() const { return points_.size(); }
  uint64_t keyframes_created() const { return next_keyframe_id_ - 1; }
  const std::unordered_map<uint64_t, KeyFrame>& keyframes() const { return keyframes_; }
  const std::unordered_map<uint64_t, MapPoint>& map_points() const { return points_; }

 private:
  std::unordered_map<uint64_t, KeyFrame> keyframes_;
  std::unordered_map<uint64_t, MapPoint> points_;
  uint64_t next_keyframe_id_ = 1;
  uint64_t next_point_id_ = 1;
};

}  // namespace dqo::tracking
