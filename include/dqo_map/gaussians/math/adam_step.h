#pragma once
// One Adam step of one Gaussian's attribute, shared by GaussianAdam (src/gaussians/adam.cpp) and
// the CUDA training engine's kernel, so that both update a Gaussian by the same operations.
// The bias corrections c1 = 1 − β1^t and c2 = 1 − β2^t are per Gaussian (t: its own step count)
// and taken in double, as is the ratio of the corrected moments: t reaches thousands, where
// β2^t in float loses the digits that matter early on.

#include "dqo_map/gaussians/math/types.h"

namespace dqo::gs {

struct AdamCorrection {
  double c1, c2;
};

DQO_HD AdamCorrection adam_correction(float beta1, float beta2, unsigned step) {
  return {1.0 - pow(static_cast<double>(beta1), static_cast<double>(step)),
          1.0 - pow(static_cast<double>(beta2), static_cast<double>(step))};
}

// `width` values at x with their moments m and v; g null: a zero gradient.
DQO_HD void adam_update(float* x, float* m, float* v, const float* g, int width, float lr, float beta1, float beta2,
                        float eps, AdamCorrection c) {
  for (int k = 0; k < width; ++k) {
    const float gk = g ? g[k] : 0.f;
    m[k] = beta1 * m[k] + (1.f - beta1) * gk;
    v[k] = beta2 * v[k] + (1.f - beta2) * gk * gk;
    const double m_hat = m[k] / c.c1;
    const double v_hat = v[k] / c.c2;
    x[k] -= static_cast<float>(lr * m_hat / (sqrt(v_hat) + eps));
  }
}

// A quaternion back to unit norm after its step (the identity when it collapsed).
DQO_HD void normalise_quaternion(float* q) {
  const float norm = hd_sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  if (norm > 1e-12f) {
    for (int k = 0; k < 4; ++k) q[k] /= norm;
  } else {
    q[0] = 1.f, q[1] = q[2] = q[3] = 0.f;
  }
}

DQO_HD void clamp_unit(float* c, int width) {
  for (int k = 0; k < width; ++k) c[k] = c[k] < 0.f ? 0.f : (c[k] > 1.f ? 1.f : c[k]);
}

}  // namespace dqo::gs
