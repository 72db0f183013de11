#pragma once
// Poses of a trajectory at image timestamps (interpolated). The TUM trajectory file format and the
// timestamp association (read_tum_trajectory, associate_timestamps) are in common/tum_trajectory.h.

#include <optional>
#include <utility>
#include <vector>

#include "dqo_map/common/tum_trajectory.h"
#include "dqo_map/geometry/se3.h"

namespace dqo {

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
