#pragma once
// Absolute trajectory error: estimated and ground-truth positions associated by timestamp, aligned
// by Umeyama (rotation + translation; scale optional, off for RGB-D), RMSE of what remains.

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "dqo_map/geometry/se3.h"

namespace dqo::eval {

using StampedPose = std::pair<double, SE3>;

struct AteParams {
  double max_time_difference = 0.02;  // seconds, for associating the two trajectories
  bool with_scale = false;
};

struct AteResult {
  int matched = 0;             // associated pose pairs
  double rmse_m = 0.0;
  double mean_m = 0.0;
  double median_m = 0.0;
  double max_m = 0.0;
  SE3 T_gt_est;                // the alignment applied to the estimate
  double scale = 1.0;
  std::vector<double> errors;  // per matched pair, in the estimate's order
};

// nullopt (and *error) when fewer than 3 pairs associate.
std::optional<AteResult> compute_ate(const std::vector<StampedPose>& estimate,
                                     const std::vector<StampedPose>& ground_truth,
                                     const AteParams& params, std::string* error);

}  // namespace dqo::eval
