#pragma once
// Timestamped poses in the TUM RGB-D format, and the timestamp matching that TUM data needs
// (image streams against each other, images against ground truth, estimates against ground truth).
//
// TUM trajectory file: one pose per line, `t tx ty tz qx qy qz qw` (seconds; T_world_camera as a
// translation and a unit quaternion, scalar last); lines starting with '#' and blank lines are
// comments. Written with the shortest decimal text that parses back to the same double (exact).

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "dqo_map/geometry/se3.h"

namespace dqo {

using TimedPose = std::pair<double, SE3>;  // (timestamp in seconds, T_world_camera)
using Trajectory = std::vector<TimedPose>;

// Writes atomically (temporary sibling, then rename), with a header comment line.
bool write_tum_trajectory(const std::string& path, const Trajectory& poses,
                          std::string* error = nullptr);

// Poses in file order. Errors name the file and line: wrong number of fields, a field that is not
// a finite number, a quaternion of (near) zero norm. Quaternions are normalised.
std::optional<Trajectory> read_tum_trajectory(const std::string& path,
                                              std::string* error = nullptr);

// Pairs (i, j) of a[i] and b[j] with |a[i] - b[j]| <= max_difference, each index used at most
// once, chosen greedily by increasing difference (as TUM's associate.py does); sorted by i.
std::vector<std::pair<int, int>> associate_timestamps(const std::vector<double>& a,
                                                      const std::vector<double>& b,
                                                      double max_difference);

struct PoseLookupParams {
  // Interpolate between the two poses around t (translation linearly, rotation by slerp) when
  // they are at most max_gap apart; otherwise, and outside the trajectory's time span, take the
  // nearest pose if it lies within max_difference of t.
  bool interpolate = true;
  double max_gap = 0.1;          // seconds between the two poses around t
  double max_difference = 0.02;  // seconds to the nearest pose
};

// The pose at time t from a trajectory sorted by time; nullopt where the rules above give none.
std::optional<SE3> pose_at(const Trajectory& trajectory, double t,
                           const PoseLookupParams& params = {});

}  // namespace dqo
