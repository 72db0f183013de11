#include "dqo_map/eval/ate.h"

#include "dqo_map/common/tum_trajectory.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <tuple>

#include <Eigen/Geometry>

namespace dqo::eval {

std::optional<AteResult> compute_ate(const std::vector<StampedPose>& estimate,
                                     const std::vector<StampedPose>& ground_truth,
                                     const AteParams& params, std::string* error) {
  std::vector<double> t_est, t_gt;
  t_est.reserve(estimate.size());
  t_gt.reserve(ground_truth.size());
  for (const auto& p : estimate) t_est.push_back(p.first);
  for (const auto& p : ground_truth) t_gt.push_back(p.first);
  const auto pairs = associate_timestamps(t_est, t_gt, params.max_time_difference);
  if (pairs.size() < 3) {
    if (error) {
      *error = std::to_string(pairs.size()) + " of " + std::to_string(estimate.size()) +
               " estimated poses have a ground-truth pose within " +
               std::to_string(params.max_time_difference) +
               " s; the alignment needs at least 3 (do the two files share a time base?)";
    }
    return std::nullopt;
  }

  const int n = static_cast<int>(pairs.size());
  Eigen::Matrix3Xd p_est(3, n), p_gt(3, n);
  for (int k = 0; k < n; ++k) {
    p_est.col(k) = estimate[pairs[k].first].second.translation();
    p_gt.col(k) = ground_truth[pairs[k].second].second.translation();
  }
  if (!p_est.allFinite() || !p_gt.allFinite()) {
    if (error) *error = "a matched position is not finite";
    return std::nullopt;
  }

  // Umeyama's closed form: p_gt ≈ s R p_est + t in the least-squares sense.
  const Eigen::Matrix4d T = Eigen::umeyama(p_est, p_gt, params.with_scale);
  AteResult r;
  r.matched = n;
  r.scale = params.with_scale ? T.block<3, 1>(0, 0).norm() : 1.0;
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>() / r.scale;
  const Eigen::Vector3d t = T.topRightCorner<3, 1>();
  r.T_gt_est = SE3::from_rotation_translation(R, t);

  r.errors.resize(n);
  double sum = 0.0, sum_sq = 0.0;
  for (int k = 0; k < n; ++k) {
    const double e = (r.scale * (R * p_est.col(k)) + t - p_gt.col(k)).norm();
    r.errors[k] = e;
    sum += e;
    sum_sq += e * e;
    r.max_m = std::max(r.max_m, e);
  }
  r.mean_m = sum / n;
  r.rmse_m = std::sqrt(sum_sq / n);
  std::vector<double> sorted = r.errors;
  std::sort(sorted.begin(), sorted.end());
  r.median_m = n % 2 ? sorted[n / 2] : 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]);
  return r;
}

}  // namespace dqo::eval
