#include "depth_init.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace dqo::objects {
namespace {

double quantile(std::vector<double>& v, double q) {
  const size_t k = static_cast<size_t>(std::clamp(q, 0.0, 1.0) * static_cast<double>(v.size() - 1));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
  return v[k];
}

}  // namespace

double depth_disagreement(const DualQuadric& quadric, const std::vector<DepthEvidence>& evidence) {
  std::vector<double> residuals;
  for (const DepthEvidence& e : evidence) {
    if (e.depth == nullptr) continue;
    const Eigen::Vector3d axis = e.T_cw.rotation().row(2).transpose();  // optical axis in world
    const Eigen::Matrix3d S = e.depth->shape_matrix();
    const double half_depth = std::sqrt(std::max(0.0, axis.dot(S * axis)));
    const double z_q = (e.T_cw * quadric.centre()).z();
    const double z_d = (e.T_cw * e.depth->centre()).z();
    residuals.push_back(std::abs(z_q - z_d) / (half_depth + 0.05));
  }
  if (residuals.empty()) return std::numeric_limits<double>::quiet_NaN();
  return quantile(residuals, 0.5);
}

}  // namespace dqo::objects
