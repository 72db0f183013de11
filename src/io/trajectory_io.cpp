#include "dqo_map/io/trajectory_io.h"

#include <algorithm>
#include <cmath>
#include <tuple>

namespace dqo {

std::vector<std::pair<int, int>> associate_timestamps(const std::vector<double>& a,
                                                      const std::vector<double>& b,
                                                      double max_difference) {
  // Candidates within the window, found through b sorted by time.
  std::vector<int> b_order(b.size());
  for (size_t j = 0; j < b.size(); ++j) b_order[j] = static_cast<int>(j);
  std::sort(b_order.begin(), b_order.end(), [&](int x, int y) { return b[x] < b[y]; });
  std::vector<double> b_sorted(b.size());
  for (size_t k = 0; k < b.size(); ++k) b_sorted[k] = b[b_order[k]];

  std::vector<std::tuple<double, int, int>> candidates;  // (|difference|, i, j)
  for (size_t i = 0; i < a.size(); ++i) {
    auto it = std::lower_bound(b_sorted.begin(), b_sorted.end(), a[i] - max_difference);
    for (; it != b_sorted.end() && *it <= a[i] + max_difference; ++it) {
      const int j = b_order[it - b_sorted.begin()];
      candidates.emplace_back(std::abs(a[i] - b[j]), static_cast<int>(i), j);
    }
  }
  std::sort(candidates.begin(), candidates.end());
  std::vector<bool> used_a(a.size(), false), used_b(b.size(), false);
  std::vector<std::pair<int, int>> matches;
  for (const auto& [diff, i, j] : candidates) {
    if (diff > max_difference || used_a[i] || used_b[j]) continue;
    used_a[i] = used_b[j] = true;
    matches.emplace_back(i, j);
  }
  std::sort(matches.begin(), matches.end());
  return matches;
}

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
