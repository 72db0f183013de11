#include "dqo_map/common/tum_trajectory.h"

#include <algorithm>
#include <cmath>
#include <tuple>

#include "dqo_map/common/text_util.h"

namespace dqo {

using text::fail;
using text::format_double;
using text::located;

bool write_tum_trajectory(const std::string& path, const Trajectory& poses, std::string* error) {
  std::string text = "# timestamp tx ty tz qx qy qz qw\n";
  for (const auto& [t, T_wc] : poses) {
    const Eigen::Vector3d& p = T_wc.translation();
    const Eigen::Quaterniond& q = T_wc.quaternion();
    text += format_double(t) + ' ' + format_double(p.x()) + ' ' + format_double(p.y()) + ' ' +
            format_double(p.z()) + ' ' + format_double(q.x()) + ' ' + format_double(q.y()) + ' ' +
            format_double(q.z()) + ' ' + format_double(q.w()) + '\n';
  }
  return text::write_file_atomically(path, text, error);
}

std::optional<Trajectory> read_tum_trajectory(const std::string& path, std::string* error) {
  std::vector<text::TextLine> lines;
  if (!text::read_text_lines(path, &lines, error)) return std::nullopt;
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
      if (!text::parse_double(line.tokens[k], &v[k])) {
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
  // Candidates within the window come from a sorted copy of b, so long streams cost N log N.
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

}  // namespace dqo
