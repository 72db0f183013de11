#include "dqo_map/gaussians/adam.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "compaction.h"
#include "dqo_map/gaussians/math/adam_step.h"

namespace dqo::gs {

void GaussianAdam::keep_moments_on_host(bool keep) {
  keep_moments_ = keep;
  if (!keep) drop_moments();
}

void GaussianAdam::drop_moments() {
  for (Moments* mo : {&s_.position, &s_.log_scale, &s_.rotation, &s_.opacity, &s_.colour}) {
    mo->m.clear();
    mo->v.clear();
  }
}

void GaussianAdam::resize_for(const GaussianMap& map) {
  const size_t n = map.size();
  if (!keep_moments_) {
    if (s_.steps.size() != n) drop_moments();  // a fetched copy is stale once the map changed
    s_.steps.resize(n, 0);
    return;
  }
  auto grow = [n](Moments* mo, size_t width) {
    mo->m.resize(n * width, 0.f);
    mo->v.resize(n * width, 0.f);
  };
  grow(&s_.position, 3);
  grow(&s_.log_scale, 3);
  grow(&s_.rotation, 4);
  grow(&s_.opacity, 1);
  grow(&s_.colour, 3);
  s_.steps.resize(n, 0);
}

void GaussianAdam::remove_if(const std::vector<uint8_t>& remove) { this->remove(plan_removal(remove)); }

void GaussianAdam::remove(const RemovalPlan& plan) {
  detail::Compaction c(plan);
  if (!keep_moments_) {
    drop_moments();
    c.add(&s_.steps, 1);
    c.run();
    return;
  }
  auto shrink = [&c](Moments* mo, size_t width) {
    c.add(&mo->m, width);
    c.add(&mo->v, width);
  };
  shrink(&s_.position, 3);
  shrink(&s_.log_scale, 3);
  shrink(&s_.rotation, 4);
  shrink(&s_.opacity, 1);
  shrink(&s_.colour, 3);
  c.add(&s_.steps, 1);
  c.run();
}

void GaussianAdam::reset() {
  s_.position = s_.log_scale = s_.rotation = s_.opacity = s_.colour = Moments{};
  s_.steps.clear();
}

void GaussianAdam::step(const MapGradients& grad, const std::vector<uint8_t>& update,
                        GaussianMap* map) {
  if (!keep_moments_) throw std::logic_error("GaussianAdam::step: the moments are kept by an engine");
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
    const uint32_t t = ++s_.steps[i];
    const AdamCorrection c = adam_correction(p.beta1, p.beta2, t);
    if (p.lr_position > 0.f) {
      adam_update(pos + 3 * i, &s_.position.m[3 * i], &s_.position.v[3 * i], g_at(grad.position, i, 3),
                  3, p.lr_position, p.beta1, p.beta2, p.epsilon, c);
    }
    if (p.lr_log_scale > 0.f) {
      adam_update(scl + 3 * i, &s_.log_scale.m[3 * i], &s_.log_scale.v[3 * i],
                  g_at(grad.log_scale, i, 3), 3, p.lr_log_scale, p.beta1, p.beta2, p.epsilon, c);
    }
    if (p.lr_rotation > 0.f) {
      float* q = rot + 4 * i;
      adam_update(q, &s_.rotation.m[4 * i], &s_.rotation.v[4 * i], g_at(grad.rotation, i, 4), 4,
                  p.lr_rotation, p.beta1, p.beta2, p.epsilon, c);
      if (p.normalise_rotation) normalise_quaternion(q);
    }
    if (p.lr_colour > 0.f) {
      float* rgb = col + 3 * i;
      adam_update(rgb, &s_.colour.m[3 * i], &s_.colour.v[3 * i], g_at(grad.colour, i, 3), 3, p.lr_colour,
                  p.beta1, p.beta2, p.epsilon, c);
      if (p.clamp_colour) clamp_unit(rgb, 3);
    }
    if (p.lr_opacity > 0.f) {
      // Adam on the logit s of the opacity o = σ(s): dL/ds = dL/do · o (1 − o).
      constexpr float kMin = 1e-4f, kMax = 1.f - 1e-4f;
      const float o = std::clamp(opa[i], kMin, kMax);
      float s = std::log(o / (1.f - o));
      const float g = grad.opacity.empty() ? 0.f : grad.opacity[i] * o * (1.f - o);
      adam_update(&s, &s_.opacity.m[i], &s_.opacity.v[i], &g, 1, p.lr_opacity, p.beta1, p.beta2,
                  p.epsilon, c);
      opa[i] = std::clamp(1.f / (1.f + std::exp(-s)), kMin, kMax);
    }
  }
}

}  // namespace dqo::gs
