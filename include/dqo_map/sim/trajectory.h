#pragma once
// Camera paths: poses T_wc of the optical frame (x right, y down, z forward) in a z-up world.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "dqo_map/geometry/se3.h"

namespace dqo::sim {

struct TrajectoryPose {
  double timestamp = 0.0;
  SE3 T_wc;
};

// Camera at `position` looking at `target`, the image's up as close to world +z as possible.
// Looking straight up or down is legal: the world x axis then stands in for the up direction.
SE3 look_at(const Eigen::Vector3d& position, const Eigen::Vector3d& target);

struct OrbitParams {
  Eigen::Vector3d target = Eigen::Vector3d::Zero();
  double radius = 1.0;
  double height = 1.0;            // camera z in the world
  double height_amplitude = 0.0;  // the height swings by ± this, twice per orbit: varied views
  double start_deg = 0.0;         // azimuth of the first frame, from world +x, counter-clockwise
  double arc_deg = 360.0;         // a full orbit does not repeat its first frame
};
std::vector<TrajectoryPose> make_orbit(const OrbitParams& params, int frames, double fps);

// A hand-held walk: the position follows a centripetal Catmull-Rom spline through the waypoints
// at constant speed, the gaze a spline through the look-at points (one per waypoint), and a
// smooth seeded shake (sums of slow sinusoids) is added to both, as a hand would.
struct WalkParams {
  std::vector<Eigen::Vector3d> waypoints;  // >= 2
  std::vector<Eigen::Vector3d> look_at;    // as many as waypoints
  double jitter_position = 0.0;            // metres, amplitude of the shake
  double jitter_rotation_deg = 0.0;        // degrees, amplitude of the shake
  uint64_t seed = 0;
};
std::vector<TrajectoryPose> make_walk(const WalkParams& params, int frames, double fps);

}  // namespace dqo::sim
