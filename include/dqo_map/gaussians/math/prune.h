#pragma once
// Stage: the pruning's test of a Gaussian's size (GaussianTrainer::prune), written once for the
// host's loop and the device's kernel (the engine tests the values it holds without sending them).

#include "dqo_map/gaussians/math/types.h"

namespace dqo::gs {

// Whether the largest of the three log-scales exceeds max_log_scale (log of Params::max_scale).
DQO_HD bool oversized(const float* log_scale, float max_log_scale) {
  const float a = log_scale[0] > log_scale[1] ? log_scale[0] : log_scale[1];
  return (a > log_scale[2] ? a : log_scale[2]) > max_log_scale;
}

}  // namespace dqo::gs
