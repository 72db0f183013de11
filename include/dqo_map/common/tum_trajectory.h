#pragma once
// Timestamped poses in the TUM RGB-D trajectory format, read by sim/ (scene trajectories) and io/
// (datasets), written by io/.
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
// once, chosen greedily by increasing difference (as TUM's associate.py does); sorted by i. Used for
// image streams against each other, images against ground truth and estimates against ground truth.
std::vector<std::pair<int, int>> associate_timestamps(const std::vector<double>& a,
                                                      const std::vector<double>& b,
                                                      double max_difference);

}  // namespace dqo
