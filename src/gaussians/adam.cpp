#include "dqo_map/gaussians/adam.h"

#include <algorithm>
#include <cmath>

namespace dqo::gs {
namespace {

// Removes, in place, the `width` values of every item i with remove[i] != 0.
template <typename T>
void compact(std::vector<T>* v, const std::vector<uint8_t>& remove, size_t width) {
  size_t out = 0;
  for (size_t i = 0; i < remove.size(); ++i) {
    if (remove[i]) continue;
    if (out != i) std::copy_n(v->begin() + i * width, width, v->begin() + out * width);
    ++out;
  }
  v->resize(out * width);
}

// One Adam update of `width` values starting at `x`, with bias corrections c1 = 1 − β1^t and
// c2 = 1 − β2^t. Returns nothing; `g` may be null (zero gradient).
inline void adam_update(float* x, float* m, float* v, const float* g, size_t width, float lr,
                        float beta1, float beta2, float eps, double c1, double c2) {
  for (size_t k = 0; k < width; ++k) {
    const float gk = g ? g[k] : 0.f;
    m[k] = beta1 * m[k] + (1.f - beta1) * gk;
    v[k] = beta2 * v[k] + (1.f - beta2) * gk * gk;
    const double m_hat = m[k] / c1;
    const double v_hat = v[k] / c2;
    x[k] -= static_cast<float>(lr * m_hat / (std::sqrt(v_hat) + eps));
  }
}

}  // namespace

void GaussianAdam::resize_for(const GaussianMap& map) {
  const size_t n = map.size();
  auto grow = [n](Moments* mo, size_t width) {
    mo->m.resize(n * width, 0.f);
    mo->v.resize(n * width, 0.f);
  };
  grow(&position_, 3);
  grow(&log_scale_, 3);
  grow(&rotation_, 4);
  grow(&opacity_, 1);
  grow(&colour_, 3);
  steps_.resize(n, 0);
}

void GaussianAdam::remove_if(const std::vector<uint8_t>& remove) {
  auto shrink = [&remove](Moments* mo, size_t width) {
    compact(&mo->m, remove, width);
    compact(&mo->v, remove, width);
  };
  shrink(&position_, 3);
  shrink(&log_scale_, 3);
  shrink(&rotation_, 4);
  shrink(&opacity_, 1);
  shrink(&colour_, 3);
  compact(&steps_, remove, 1);
}

void GaussianAdam::reset() {
  position_ = log_scale_ = rotation_ = opacity_ = colour_ = Moments{};
  steps_.clear();
}

void GaussianAdam::step(const MapGradients& grad, const std::vector<uint8_t>& update,
                        GaussianMap* map) {
  resize_for(*map);
  const size_t n = map->size();
  const Params& p = params_;
  auto g_at = [](const std::vector<float>& g, size_t i, size_t width) -> const float* {
    return g.empty() ? nullptr : g.data() + i * width;
  };
  float* pos = map->positions().data();
  float* scl = map->log_scales().data();
  float* rot = map->rotations().data();
  float* opa = map->opacities().data();
  float* col = map->colours().data();
  for (size_t i = 0; i < n && i < update.size(); ++i) {
    if (!update[i]) continue;
    const uint32_t t = ++steps_[i];
    const double c1 = 1.0 - std::pow(static_cast<double>(p.beta1), t);
    const double c2 = 1.0 - std::pow(static_cast<double>(p.beta2), t);
    if (p.lr_position > 0.f) {
      adam_update(pos + 3 * i, &position_.m[3 * i], &position_.v[3 * i], g_at(grad.position, i, 3),
                  3, p.lr_position, p.beta1, p.beta2, p.epsilon, c1, c2);
    }
    if (p.lr_log_scale > 0.f) {
      adam_update(scl + 3 * i, &log_scale_.m[3 * i], &log_scale_.v[3 * i],
                  g_at(grad.log_scale, i, 3), 3, p.lr_log_scale, p.beta1, p.beta2, p.epsilon, c1,
                  c2);
    }
    if (p.lr_rotation > 0.f) {
      float* q = rot + 4 * i;
      adam_update(q, &rotation_.m[4 * i], &rotation_.v[4 * i], g_at(grad.rotation, i, 4), 4,
                  p.lr_rotation, p.beta1, p.beta2, p.epsilon, c1, c2);
      if (p.normalise_rotation) {
        const float norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
        if (norm > 1e-12f) {
          for (int k = 0; k < 4; ++k) q[k] /= norm;
        } else {
          q[0] = 1.f, q[1] = q[2] = q[3] = 0.f;
        }
      }
    }
    if (p.lr_colour > 0.f) {
      float* c = col + 3 * i;
      adam_update(c, &colour_.m[3 * i], &colour_.v[3 * i], g_at(grad.colour, i, 3), 3, p.lr_colour,
                  p.beta1, p.beta2, p.epsilon, c1, c2);
      if (p.clamp_colour) {
        for (int k = 0; k < 3; ++k) c[k] = std::clamp(c[k], 0.f, 1.f);
      }
    }
    if (p.lr_opacity > 0.f) {
      // Adam on the logit s of the opacity o = σ(s): dL/ds = dL/do · o (1 − o).
      constexpr float kMin = 1e-4f, kMax = 1.f - 1e-4f;
      const float o = std::clamp(opa[i], kMin, kMax);
      float s = std::log(o / (1.f - o));
      const float g = grad.opacity.empty() ? 0.f : grad.opacity[i] * o * (1.f - o);
      adam_update(&s, &opacity_.m[i], &opacity_.v[i], &g, 1, p.lr_opacity, p.beta1, p.beta2,
                  p.epsilon, c1, c2);
      opa[i] = std::clamp(1.f / (1.f + std::exp(-s)), kMin, kMax);
    }
  }
}

}  // namespace dqo::gs
