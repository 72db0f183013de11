#pragma once
// A robot's map is z up (REP-103): tracking_node anchors its map at the first pose of the camera's
// body frame (the root of the camera's tf tree, camera_base for the Azure Kinect), rotated so that
// z points against gravity while the heading of the body's x axis is kept. Gravity comes from the
// accelerometer at rest (it measures the reaction to gravity: a vector pointing up, averaged over
// the first samples) or from the floor (the dominant plane of the first frame's depth within
// `max_tilt_deg` of the expected up, whose normal points up).
//
// The tracker's own frame is its first camera's optical frame; the node turns its poses into the
// map with T_map_tracker = [R_map_body | 0] * T_body_cam * T_tracker_cam⁻¹ (the first tracked frame).
#include <cstdint>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "dqo_map/common/image.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"

namespace dqo::tracking {

enum class MapLevel { kAuto, kImu, kFloor, kNone };
// "auto" (the IMU where one publishes, else the floor), "imu", "floor", "none"; nullopt otherwise.
std::optional<MapLevel> map_level_from_string(const std::string& text);

// The rotation R_map_body that takes `up_b` (gravity's up in the body frame) to +z and keeps the
// heading of the body's x axis (its projection onto the horizontal becomes the map's +x; the y axis
// stands in where x is nearly vertical). up_b need not be normalised; it must not be zero.
Eigen::Matrix3d level_rotation(const Eigen::Vector3d& up_b);

// The mean of the first accelerometer samples (m/s², in the IMU's frame).
class GravityEstimator {
 public:
  explicit GravityEstimator(int samples) : wanted_(samples) {}
  // Non-finite samples are ignored; samples beyond the wanted count too ("the first moments").
  void add(const Eigen::Vector3d& accel);
  bool ready() const { return count_ >= wanted_; }
  int count() const { return count_; }
  // The unit up vector in the IMU's frame, and the mean's magnitude (≈ 9.81 at rest) in *g.
  std::optional<Eigen::Vector3d> up(double* g = nullptr) const;

 private:
  int wanted_;
  int count_ = 0;
  Eigen::Vector3d sum_ = Eigen::Vector3d::Zero();
};

struct FloorParams {
  int max_points = 4000;       // depth pixels sampled (on a regular grid)
  int iterations = 300;        // RANSAC hypotheses
  double inlier_m = 0.02;      // point-to-plane distance of an inlier
  double max_tilt_deg = 45.0;  // between the plane's normal and the expected up
  double min_inlier_fraction = 0.1;  // of the sampled points
  uint32_t seed = 1;
};

struct FloorPlane {
  Eigen::Vector3d up_c;  // unit normal in the camera frame, pointing to the camera's side (up)
  double height = 0.0;   // the camera's distance above the plane, metres
  int inliers = 0;
  int points = 0;
};

// The largest plane of `depth` (rectified, metres) whose normal lies within max_tilt_deg of
// `expected_up_c`, with the camera above it; nullopt and *error when there is none.
std::optional<FloorPlane> find_floor(const PinholeCamera& camera, const DepthImage& depth,
                                     const Eigen::Vector3d& expected_up_c, const FloorParams& params,
                                     std::string* error);

}  // namespace dqo::tracking
