// Adam: steps against a hand-computed update, frozen Gaussians untouched, state that follows the
// map through additions and removals, opacity trained through its logit.

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "dqo_map/gaussians/adam.h"

namespace dqo::gs {
namespace {

GaussianMap random_map(size_t n, std::mt19937* rng) {
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  GaussianMap map;
  for (size_t i = 0; i < n; ++i) {
    GaussianInit g;
    g.position = Eigen::Vector3f(u(*rng), u(*rng), 2.f + u(*rng));
    g.log_scale =
        Eigen::Vector3f::Constant(-3.f) + 0.2f * Eigen::Vector3f(u(*rng), u(*rng), u(*rng));
    g.rotation = Eigen::Vector4f(1.f, 0.1f * u(*rng), 0.1f * u(*rng), 0.1f * u(*rng)).normalized();
    g.colour = Eigen::Vector3f::Constant(0.5f) + 0.3f * Eigen::Vector3f(u(*rng), u(*rng), u(*rng));
    g.object_id = static_cast<uint32_t>(i % 3);
    map.add(g);
  }
  return map;
}

MapGradients random_gradients(const GaussianMap& map, std::mt19937* rng) {
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  MapGradients g;
  g.resize_for(map);
  for (auto* v : {&g.position, &g.log_scale, &g.rotation, &g.opacity, &g.colour}) {
    for (float& x : *v) x = 1e-3f * u(*rng);
  }
  return g;
}

// Adam by the book, for one scalar, in double.
struct ScalarAdam {
  double m = 0.0, v = 0.0;
  int t = 0;
  double step(double x, double g, double lr, double b1 = 0.9, double b2 = 0.999,
              double eps = 1e-15) {
    ++t;
    m = b1 * m + (1 - b1) * g;
    v = b2 * v + (1 - b2) * g * g;
    const double mh = m / (1 - std::pow(b1, t)), vh = v / (1 - std::pow(b2, t));
    return x - lr * mh / (std::sqrt(vh) + eps);
  }
};

TEST(Adam, MatchesHandComputedSteps) {
  std::mt19937 rng(1);
  GaussianMap map = random_map(4, &rng);
  GaussianAdam::Params params;
  params.normalise_rotation = false;
  params.clamp_colour = false;
  GaussianAdam adam(params);
  const GaussianMap start = map;

  std::vector<MapGradients> grads;
  for (int s = 0; s < 3; ++s) grads.push_back(random_gradients(map, &rng));
  for (const MapGradients& g : grads) adam.step(g, std::vector<uint8_t>(4, 1), &map);

  // The first step of Adam moves every value by exactly lr against the sign of its gradient.
  {
    GaussianMap one = start;
    GaussianAdam a(params);
    a.step(grads[0], std::vector<uint8_t>(4, 1), &one);
    for (size_t k = 0; k < one.positions().size(); ++k) {
      const float expected = start.positions()[k] - 1e-3f * (grads[0].position[k] > 0 ? 1 : -1);
      EXPECT_NEAR(one.positions()[k], expected, 1e-7);
    }
  }
  auto check = [&](const std::vector<float>& x0, const std::vector<float>& x,
                   std::vector<float> MapGradients::*field, double lr) {
    for (size_t k = 0; k < x.size(); ++k) {
      ScalarAdam ref;
      double value = x0[k];
      for (const MapGradients& g : grads) value = ref.step(value, (g.*field)[k], lr);
      EXPECT_NEAR(x[k], value, 1e-6 * std::max(1.0, std::abs(value))) << k;
    }
  };
  check(start.positions(), map.positions(), &MapGradients::position, 1e-3);
  check(start.log_scales(), map.log_scales(), &MapGradients::log_scale, 1.6e-2);
  check(start.rotations(), map.rotations(), &MapGradients::rotation, 4e-3);
  check(start.colours(), map.colours(), &MapGradients::colour, 2e-3);
  EXPECT_EQ(map.opacities(), start.opacities());  // lr 0: not trained
}

TEST(Adam, FrozenGaussiansUntouched) {
  std::mt19937 rng(2);
  GaussianMap map = random_map(6, &rng);
  const GaussianMap start = map;
  GaussianAdam adam;
  const std::vector<uint8_t> update = {1, 0, 1, 0, 0, 1};
  for (int s = 0; s < 4; ++s) adam.step(random_gradients(map, &rng), update, &map);
  for (size_t i = 0; i < 6; ++i) {
    for (int k = 0; k < 3; ++k) {
      const bool same = map.positions()[3 * i + k] == start.positions()[3 * i + k];
      EXPECT_EQ(same, !update[i]) << i;
      EXPECT_EQ(map.log_scales()[3 * i + k] == start.log_scales()[3 * i + k], !update[i]);
      EXPECT_EQ(map.colours()[3 * i + k] == start.colours()[3 * i + k], !update[i]);
    }
  }
}

TEST(Adam, RotationStaysUnitAndColourInRange) {
  std::mt19937 rng(3);
  GaussianMap map = random_map(5, &rng);
  GaussianAdam::Params params;
  params.lr_colour = 0.3f;  // large steps, to hit the range
  GaussianAdam adam(params);
  for (int s = 0; s < 10; ++s) {
    MapGradients g = random_gradients(map, &rng);
    for (float& c : g.colour) c = c > 0 ? 1.f : -1.f;
    adam.step(g, std::vector<uint8_t>(5, 1), &map);
  }
  for (size_t i = 0; i < 5; ++i) {
    const float* q = &map.rotations()[4 * i];
    EXPECT_NEAR(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3], 1.f, 1e-5f);
    for (int k = 0; k < 3; ++k) {
      EXPECT_GE(map.colours()[3 * i + k], 0.f);
      EXPECT_LE(map.colours()[3 * i + k], 1.f);
    }
  }
}

// Removing Gaussians with a keep-mask, and appending new ones, gives exactly what an optimiser
// that only ever saw the surviving Gaussians gives.
TEST(Adam, StateFollowsRemovalsAndAdditions) {
  std::mt19937 rng(4);
  GaussianMap map = random_map(5, &rng);
  GaussianAdam::Params params;
  params.normalise_rotation = false;
  GaussianAdam adam(params);
  std::vector<MapGradients> grads;
  for (int s = 0; s < 3; ++s) grads.push_back(random_gradients(map, &rng));
  // Gaussian 3 sits out the second step: its own step count stays behind.
  const std::vector<std::vector<uint8_t>> updates = {
      {1, 1, 1, 1, 1}, {1, 1, 1, 0, 1}, {1, 1, 1, 1, 1}};
  for (int s = 0; s < 3; ++s) adam.step(grads[s], updates[s], &map);

  const std::vector<uint8_t> remove = {0, 1, 0, 0, 1};
  map.remove_if(remove);
  adam.remove_if(remove);
  ASSERT_EQ(adam.size(), 3u);
  GaussianInit fresh;
  fresh.position = Eigen::Vector3f(0.1f, 0.2f, 3.f);
  map.add(fresh);  // index 3, zero moments
  const GaussianMap before = map;
  MapGradients next = random_gradients(map, &rng);
  adam.step(next, std::vector<uint8_t>(4, 1), &map);
  ASSERT_EQ(adam.size(), 4u);

  // Reference: per kept Gaussian, a scalar Adam fed the same gradients from its own history. The
  // removal filled the hole at 1 with Gaussian 3 (removal_plan.h): new order 0, 3, 2.
  const size_t kept[3] = {0, 3, 2};
  for (size_t j = 0; j < 3; ++j) {
    const size_t old = kept[j];
    for (int k = 0; k < 3; ++k) {
      ScalarAdam ref;
      double x = 0.0;  // only the displacement matters
      for (int s = 0; s < 3; ++s) {
        if (updates[s][old]) x = ref.step(x, grads[s].position[3 * old + k], 1e-3);
      }
      const double x_before = x;
      x = ref.step(x, next.position[3 * j + k], 1e-3);
      EXPECT_NEAR(map.positions()[3 * j + k] - before.positions()[3 * j + k], x - x_before, 1e-7)
          << "kept " << old << " k " << k;
    }
  }
  // The new Gaussian takes a first step: lr against the sign.
  for (int k = 0; k < 3; ++k) {
    const float d = map.positions()[9 + k] - before.positions()[9 + k];
    EXPECT_NEAR(d, next.position[9 + k] > 0 ? -1e-3f : 1e-3f, 1e-7);
  }
}

// With the moments left to an engine, the host keeps the step counts alone, in step with the map.
TEST(Adam, MomentsLeftToAnEngine) {
  std::mt19937 rng(5);
  GaussianMap map = random_map(6, &rng);
  GaussianAdam adam;
  adam.step(random_gradients(map, &rng), std::vector<uint8_t>{1, 0, 1, 1, 0, 1}, &map);
  ASSERT_EQ(adam.state().position.m.size(), 18u);
  adam.keep_moments_on_host(false);
  for (const auto* mo : {&adam.state().position, &adam.state().log_scale, &adam.state().rotation,
                         &adam.state().opacity, &adam.state().colour}) {
    EXPECT_TRUE(mo->m.empty() && mo->v.empty());
  }
  // Steps 1 0 1 1 0 1; the holes at 0 and 3 are filled by Gaussians 4 and 5: 0 0 1 1.
  const std::vector<uint8_t> remove = {1, 0, 0, 1, 0, 0};
  map.remove_if(remove);
  adam.remove_if(remove);
  EXPECT_EQ(adam.state().steps, (std::vector<uint32_t>{0, 0, 1, 1}));
  map.add(GaussianInit{});
  adam.resize_for(map);
  EXPECT_EQ(adam.state().steps, (std::vector<uint32_t>{0, 0, 1, 1, 0}));
  EXPECT_TRUE(adam.state().colour.v.empty());
  EXPECT_THROW(adam.step(random_gradients(map, &rng), std::vector<uint8_t>(5, 1), &map), std::logic_error);
  // Kept again: zero moments sized for the map, and steps run.
  adam.keep_moments_on_host(true);
  adam.step(random_gradients(map, &rng), std::vector<uint8_t>(5, 1), &map);
  EXPECT_EQ(adam.state().rotation.v.size(), 20u);
  EXPECT_EQ(adam.state().steps, (std::vector<uint32_t>{1, 1, 2, 2, 1}));
}

TEST(Adam, OpacityThroughLogitWhenTrainable) {
  std::mt19937 rng(5);
  GaussianMap map = random_map(2, &rng);
  GaussianAdam::Params params;
  params.lr_opacity = 0.05f;
  GaussianAdam adam(params);
  const float o0 = map.opacities()[0], o1 = map.opacities()[1];
  MapGradients g;
  g.resize_for(map);
  g.opacity = {1.f, -1.f};
  for (int s = 0; s < 200; ++s) adam.step(g, {1, 1}, &map);
  EXPECT_LT(map.opacities()[0], o0);  // against the gradient
  EXPECT_GT(map.opacities()[1], o1);
  EXPECT_GT(map.opacities()[0], 0.f);
  EXPECT_LT(map.opacities()[1], 1.f);
  // The first step moves the logit by lr.
  GaussianMap one = random_map(1, &rng);
  GaussianAdam a(params);
  MapGradients g1;
  g1.resize_for(one);
  g1.opacity = {0.3f};
  const float before = one.opacities()[0];
  a.step(g1, {1}, &one);
  const auto logit = [](float o) { return std::log(o / (1 - o)); };
  EXPECT_NEAR(logit(one.opacities()[0]), logit(before) - 0.05f, 1e-4);
}

}  // namespace
}  // namespace dqo::gs
