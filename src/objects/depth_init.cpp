#include "depth_init.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace dqo::objects {
namespace {

QuadricInitResult failure(InitStatus status, const std::string& message) {
  QuadricInitResult r;
  r.status = status;
  r.error = message;
  return r;
}

// Samples of valid depth in [u0, u1) x [v0, v1), at most about `budget` of them (strided).
std::vector<double> samples_in(const DepthView& depth, double u0d, double v0d, double u1d, double v1d,
                               const DepthInitParams& params, int budget) {
  const int u0 = std::max(0, static_cast<int>(std::ceil(u0d)));
  const int v0 = std::max(0, static_cast<int>(std::ceil(v0d)));
  const int u1 = std::min(depth.width, static_cast<int>(std::ceil(u1d)));
  const int v1 = std::min(depth.height, static_cast<int>(std::ceil(v1d)));
  std::vector<double> out;
  if (u1 <= u0 || v1 <= v0) return out;
  const double area = static_cast<double>(u1 - u0) * (v1 - v0);
  const int stride = std::max(1, static_cast<int>(std::floor(std::sqrt(area / budget))));
  for (int v = v0; v < v1; v += stride) {
    for (int u = u0; u < u1; u += stride) {
      const double d = depth.at(u, v);
      if (std::isfinite(d) && d >= params.min_depth && d <= params.max_depth) out.push_back(d);
    }
  }
  return out;
}

double quantile(std::vector<double>& v, double q) {
  const size_t k = static_cast<size_t>(std::clamp(q, 0.0, 1.0) * static_cast<double>(v.size() - 1));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
  return v[k];
}

}  // namespace

QuadricInitResult initialise_from_depth_robust(const Box2d& box, const PinholeCamera& camera,
                                               const SE3& T_wc, const DepthView& depth,
                                               const DepthInitParams& params) {
  if (!box.valid() || depth.data == nullptr || depth.width <= 0 || depth.height <= 0 ||
      !(camera.fx > 0.0) || !(camera.fy > 0.0)) {
    return failure(InitStatus::kInvalidInput, "invalid box, camera or depth image");
  }
  const double w = box.width(), h = box.height();
  std::vector<double> centre = samples_in(depth, box.x_min + 0.25 * w, box.y_min + 0.25 * h,
                                          box.x_max - 0.25 * w, box.y_max - 0.25 * h, params, 400);
  if (centre.size() < 4) return failure(InitStatus::kNoValidDepth, "no valid depth in the box's centre");
  const double front = quantile(centre, params.low_quantile);
  // Lateral semi-axes at the front surface bound how deep the object can reach.
  const double lateral_max = 0.5 * std::max(w / camera.fx, h / camera.fy) * front;
  const double lateral_min = 0.5 * std::min(w / camera.fx, h / camera.fy) * front;
  std::vector<double> all = samples_in(depth, box.x_min, box.y_min, box.x_max, box.y_max, params, 1500);
  std::vector<double> object;
  for (const double d : all) {
    if (d >= front - 0.02 && d <= front + 2.0 * lateral_max) object.push_back(d);
  }
  double spread = 0.0;
  if (object.size() >= 4) {
    std::vector<double> copy = object;
    spread = quantile(copy, params.high_quantile) - quantile(object, params.low_quantile);
  }
  const double c = std::clamp(spread, std::max(params.min_semi_axis, 0.5 * lateral_min),
                              std::max(params.min_semi_axis, lateral_max));
  const double z_c = front + c;
  const Eigen::Vector2d uv = box.centre();
  const Eigen::Vector3d centre_c = camera.back_project(uv.x(), uv.y(), z_c);
  Eigen::Vector3d axes(0.5 * w * z_c / camera.fx, 0.5 * h * z_c / camera.fy, c);
  axes = axes.cwiseMax(params.min_semi_axis);
  QuadricInitResult r;
  r.ok = true;
  r.status = InitStatus::kOk;
  r.quadric = DualQuadric::from_params(T_wc * centre_c, T_wc.rotation(), axes);
  r.num_depth_samples = static_cast<int>(object.size());
  return r;
}

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
