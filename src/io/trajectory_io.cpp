#include "dqo_map/io/trajectory_io.h"

#include <algorithm>
#include <cmath>
#include <tuple>

namespace dqo {

std::optional<SE3> pose_at(const Trajectory& trajectory, double t,
                           const PoseLookupParams& params) {
  if (trajectory.empty()) return std::nullopt;
  // First pose with time >= t.
  const auto after = std::lower_bound(
      trajectory.begin(), trajectory.end(), t,
      [](const TimedPose& pose, double time) { return pose.first < time; });
  if (after != trajectory.end() && after->first == t) return after->second;

  if (params.interpolate && after != trajectory.begin() && after != trajectory.end()) {
    const TimedPose& p0 = *(after - 1);
    const TimedPose& p1 = *after;
    const double gap = p1.first - p0.first;
    if (gap > 0.0 && gap <= params.max_gap) {
      const double s = (t - p0.first) / gap;
      const Eigen::Vector3d p =
          (1.0 - s) * p0.second.translation() + s * p1.second.translation();
      // Eigen's slerp takes the shorter arc (it flips the sign of q1 when needed).
      const Eigen::Quaterniond q = p0.second.quaternion().slerp(s, p1.second.quaternion());
      return SE3(q, p);
    }
  }

  const TimedPose* nearest = nullptr;
  if (after != trajectory.end()) nearest = &*after;
  if (after != trajectory.begin()) {
    const TimedPose& before = *(after - 1);
    if (!nearest || t - before.first <= nearest->first - t) nearest = &before;
  }
  if (nearest && std::abs(nearest->first - t) <= params.max_difference) return nearest->second;
  return std::nullopt;
}

}  // namespace dqo
