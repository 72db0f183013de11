#include "dqo_map/common/tum_trajectory.h"

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

}  // namespace dqo
