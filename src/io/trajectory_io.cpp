#include "dqo_map/io/trajectory_io.h"

#include <algorithm>
#include <cmath>
#include <tuple>

#include "text_util.h"

namespace dqo {

using io_detail::fail;
using io_detail::format_double;
using io_detail::located;

bool write_tum_trajectory(const std::string& path, const Trajectory& poses, std::string* error) {
  std::string text = "# timestamp tx ty tz qx qy qz qw\n";
  for (const auto& [t, T_wc] : poses) {
    const Eigen::Vector3d& p = T_wc.translation();
    const Eigen::Quaterniond& q = T_wc.quaternion();
    text += format_double(t) + ' ' + format_double(p.x()) + ' ' + format_double(p.y()) + ' ' +
            format_double(p.z()) + ' ' + format_double(q.x()) + ' ' + format_double(q.y()) + ' ' +
            format_double(q.z()) + ' ' + format_double(q.w()) + '\n';
  }
  return io_detail::write_file_atomically(path, text, error);
}

std::optional<Trajectory> read_tum_trajectory(const std::string& path, std::string* error) {
  std::vector<io_detail::TextLine> lines;
  if (!io_detail::read_text_lines(path, &lines, error)) return std::nullopt;
  Trajectory poses;
  poses.reserve(lines.size());
  for (const auto& line : lines) {
    if (line.tokens.size() != 8) {
      fail(error, located(path, line.number,
                          "expected 8 fields (t tx ty tz qx qy qz qw), found " +
                              std::to_string(line.tokens.size())));
      return std::nullopt;
    }
    double v[8];
    for (int k = 0; k < 8; ++k) {
      if (!io_detail::parse_double(line.tokens[k], &v[k])) {
        fail(error, located(path, line.number,
                            "field " + std::to_string(k + 1) + " '" + line.tokens[k] +
                                "' is not a finite number"));
        return std::nullopt;
      }
    }
    const Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);  // Eigen's constructor takes w first
    if (q.norm() < 1e-6) {
      fail(error, located(path, line.number, "quaternion has (near) zero norm"));
      return std::nullopt;
    }
    poses.emplace_back(v[0], SE3(q, Eigen::Vector3d(v[1], v[2], v[3])));
  }
  return poses;
}

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
