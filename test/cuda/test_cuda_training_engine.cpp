// The CUDA training engine against the host trainer (skipped without a GPU): the same keyframes
// through two GaussianTrainers, one iterating on the host with the CPU rasteriser, one on the GPU
// engine. One step has the same gradients (1e-3) and steps the same Gaussians; a mapping step's
// loss curve stays within 1 %; whole runs (add, train, prune) render as well; several seeds.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "../gaussians/raster_test_util.h"
#include "keyframe_test_util.h"
#include "dqo_map/cuda/cuda_rasteriser.h"
#include "dqo_map/cuda/cuda_training_engine.h"
#include "dqo_map/cuda/device_info.h"
#include "dqo_map/gaussians/trainer.h"

namespace dqo::cuda {
namespace {

using gs::testing::uniform;

constexpr int kWidth = 160, kHeight = 120;

PinholeCamera camera() { return gs::testing::make_camera(kWidth, kHeight, 140.0); }

// The world the keyframes see: a wall at 3 m and three boxes of Gaussians (objects 1-3) in front.
gs::GaussianMap truth_map(uint64_t seed) {
  std::mt19937_64 rng(seed);
  gs::GaussianMap map;
  for (int i = 0; i < 6000; ++i) {
    gs::GaussianInit g;
    const int object = i < 3000 ? 0 : 1 + (i % 3);
    if (object == 0) {
      g.position = Eigen::Vector3f(uniform(rng, -2.5, 2.5), uniform(rng, -2, 2), uniform(rng, 2.9, 3.1));
      g.colour = Eigen::Vector3f(0.3f + 0.4f * (g.position.x() > 0), 0.5f, uniform(rng, 0.2, 0.8));
    } else {
      const Eigen::Vector3f centre(-0.8f + 0.8f * (object - 1), 0.3f * (object - 2), 1.6f + 0.2f * object);
      g.position = centre + Eigen::Vector3f(uniform(rng, -0.25, 0.25), uniform(rng, -0.25, 0.25), uniform(rng, -0.2, 0.2));
      g.colour = Eigen::Vector3f(object == 1, object == 2, object == 3) * 0.8f + Eigen::Vector3f::Constant(0.1f);
    }
    for (int k = 0; k < 3; ++k) g.log_scale[k] = static_cast<float>(uniform(rng, -3.6, -2.6));
    g.rotation = Eigen::Vector4f(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1)).normalized();
    g.object_id = static_cast<uint32_t>(object);
    map.add(g);
  }
  return map;
}

// Keyframe k: the truth rendered from a camera that moves sideways and turns a little.
gs::TrainingKeyframe keyframe(const gs::GaussianMap& truth, int k) {
  const SE3 T_wc(Eigen::Quaterniond(Eigen::AngleAxisd(0.04 * k, Eigen::Vector3d::UnitY())),
                 Eigen::Vector3d(0.08 * k, 0.02 * k, 0.0));
  return testing::rendered_keyframe(truth, camera(), T_wc, static_cast<uint32_t>(k + 1));
}

gs::GaussianTrainer::Params params(uint64_t seed, int iterations) {
  gs::GaussianTrainer::Params p;
  p.iterations = iterations;
  p.seed = seed;
  return p;
}

struct Pair {
  gs::GaussianTrainer host, gpu;
  Pair(const gs::GaussianTrainer::Params& p)
      : host(p, gs::make_cpu_rasteriser(0)), gpu(p, make_cuda_rasteriser(), make_cuda_training_engine()) {}
};

// ‖gpu − host‖ / ‖host‖.
double relative_l2(const std::vector<float>& gpu, const std::vector<float>& host) {
  EXPECT_EQ(gpu.size(), host.size());
  double diff = 0.0, norm = 0.0;
  for (size_t i = 0; i < std::min(gpu.size(), host.size()); ++i) {
    diff += (double(gpu[i]) - host[i]) * (double(gpu[i]) - host[i]);
    norm += double(host[i]) * host[i];
  }
  return norm > 0.0 ? std::sqrt(diff / norm) : std::sqrt(diff);
}

// Two trainers with the same map, window and random state: keyframes added without iterations
// (the renders that decide what is added are bit-identical on both rasterisers), then the same
// (fresh) optimiser state.
void build_alike(Pair* t, const gs::GaussianMap& truth, int keyframes) {
  for (int k = 0; k < keyframes; ++k) {
    t->host.add_keyframe(keyframe(truth, k));
    t->gpu.add_keyframe(keyframe(truth, k));
  }
  t->gpu.set_map(t->host.map());
  t->host.set_map(t->host.map());
}

TEST(CudaTrainingEngine, OneStepHasTheHostsGradientsAndUpdates) {
  if (!gpu_available()) GTEST_SKIP() << "no GPU";
  for (uint64_t seed : {1u, 2u, 3u}) {
    const gs::GaussianMap truth = truth_map(seed);
    Pair t(params(seed, 0));
    ASSERT_TRUE(t.gpu.uses_engine());
    build_alike(&t, truth, 3);
    ASSERT_GT(t.host.map().size(), 1000u) << "seed " << seed;
    const double loss_host = t.host.optimise(1), loss_gpu = t.gpu.optimise(1);
    EXPECT_NEAR(loss_gpu, loss_host, 1e-4 * loss_host) << "seed " << seed;
    const gs::GaussianMap& h = t.host.map();
    const gs::GaussianMap& g = t.gpu.map();
    size_t moved_host = 0, moved_gpu = 0;
    for (size_t i = 0; i < h.size(); ++i) {
      moved_host += h.confidences()[i] > 0.f;
      moved_gpu += g.confidences()[i] > 0.f;
    }
    EXPECT_GT(moved_host, h.size() / 4) << "seed " << seed << ": most Gaussians are in view";
    EXPECT_EQ(moved_gpu, moved_host) << "seed " << seed << ": the same Gaussians step";
    // After one step the first moment is (1 − β1) g: the gradients, to the 1e-3. The
    // values moved by ±lr (Adam's first step is the gradient's sign), so a component whose
    // gradient is nearly zero may move the other way on the GPU, where float atomics sum in
    // another order: positions and colours, whose gradients are rarely that small, are compared.
    const gs::GaussianAdam::State& sh = t.host.adam_state();
    const gs::GaussianAdam::State& sg = t.gpu.adam_state();
    EXPECT_LE(relative_l2(sg.position.m, sh.position.m), 1e-3) << "position gradients, seed " << seed;
    EXPECT_LE(relative_l2(sg.log_scale.m, sh.log_scale.m), 1e-3) << "log-scale gradients, seed " << seed;
    EXPECT_LE(relative_l2(sg.rotation.m, sh.rotation.m), 1e-3) << "rotation gradients, seed " << seed;
    EXPECT_LE(relative_l2(sg.colour.m, sh.colour.m), 1e-3) << "colour gradients, seed " << seed;
    EXPECT_EQ(sg.steps, sh.steps) << "seed " << seed;
    EXPECT_LE(relative_l2(g.positions(), h.positions()), 1e-5) << "seed " << seed;
    EXPECT_LE(relative_l2(g.colours(), h.colours()), 1e-3) << "seed " << seed;
    EXPECT_EQ(g.opacities(), h.opacities()) << "opacity is not trained";
  }
}

TEST(CudaTrainingEngine, AMappingStepsLossCurveIsTheHosts) {
  if (!gpu_available()) GTEST_SKIP() << "no GPU";
  for (uint64_t seed : {4u, 5u, 6u}) {
    const gs::GaussianMap truth = truth_map(seed);
    Pair t(params(seed, 0));
    build_alike(&t, truth, 4);
    // 50 iterations, one batch each on the GPU (the trained attributes come down every time).
    double worst = 0.0;
    for (int it = 0; it < 50; ++it) {
      const double h = t.host.optimise(1), g = t.gpu.optimise(1);
      worst = std::max(worst, std::abs(g - h) / h);
      EXPECT_NEAR(g, h, 0.01 * h) << "seed " << seed << ", iteration " << it;
    }
    std::printf("seed %llu: 50 iterations, largest relative loss difference %.2e\n",
                static_cast<unsigned long long>(seed), worst);
  }
}

TEST(CudaTrainingEngine, WholeMappingRunsReachTheHostsQuality) {
  if (!gpu_available()) GTEST_SKIP() << "no GPU";
  // Past the first keyframe the two runs draw differently (how many error pixels each samples
  // depends on its own render): compared as a whole, by the renders' error over every view.
  // The GPU's run also differs from one run to the next (float atomics sum in any order, and six
  // keyframes of adding and pruning carry that on): on an H100 (2026-11-27) one seed's error was
  // 0.95-1.05 of the host's over twelve runs, and the four seeds' summed error 0.984 and 1.029
  // in two. So the sum is held within 5 % and each seed within 10 %: beyond the runs' spread, a
  // GPU trainer that learns worse than the host's fails.
  double total_h = 0, total_g = 0;
  for (uint64_t seed : {7u, 8u, 9u, 10u}) {
    const gs::GaussianMap truth = truth_map(seed);
    Pair t(params(seed, 30));
    for (int k = 0; k < 6; ++k) {
      const gs::KeyframeReport h = t.host.add_keyframe(keyframe(truth, k));
      const gs::KeyframeReport g = t.gpu.add_keyframe(keyframe(truth, k));
      EXPECT_EQ(g.iterations, h.iterations);
      EXPECT_NEAR(double(g.num_gaussians), double(h.num_gaussians), 0.02 * h.num_gaussians) << "seed " << seed;
    }
    double eh = 0, eg = 0;
    for (int k = 0; k < 6; ++k) {
      const gs::TrainingKeyframe view = keyframe(truth, k);
      gs::RenderOutput rh, rg;
      t.host.render(view.camera, view.T_wc, &rh);
      t.gpu.render(view.camera, view.T_wc, &rg);
      for (size_t i = 0; i < rh.rgb.size(); ++i) {
        eh += std::abs(rh.rgb[i] - view.rgb.data[i] / 255.f);
        eg += std::abs(rg.rgb[i] - view.rgb.data[i] / 255.f);
      }
    }
    const double values = 6.0 * 3 * kWidth * kHeight;
    std::printf("seed %llu: mean colour error host %.5f, gpu %.5f (%.3f)\n", static_cast<unsigned long long>(seed),
                eh / values, eg / values, eg / eh);
    EXPECT_LE(eg, 1.10 * eh) << "seed " << seed;
    total_h += eh, total_g += eg;
  }
  std::printf("all seeds: gpu / host %.3f\n", total_g / total_h);
  EXPECT_LE(total_g, 1.05 * total_h);
}

TEST(CudaTrainingEngine, SettingsItDoesNotCoverStayOnTheHost) {
  if (!gpu_available()) GTEST_SKIP() << "no GPU";
  gs::GaussianTrainer::Params p = params(1, 2);
  p.lambda_ssim = 0.2f;
  gs::GaussianTrainer ssim(p, make_cuda_rasteriser(), make_cuda_training_engine());
  EXPECT_FALSE(ssim.uses_engine());
  p = params(1, 2);
  p.train_per_label = true;
  EXPECT_FALSE(gs::GaussianTrainer(p, make_cuda_rasteriser(), make_cuda_training_engine()).uses_engine());
  // The engine refuses a step that names no view, and leaves the map as it was.
  auto engine = make_cuda_training_engine();
  gs::GaussianMap map = truth_map(1);
  gs::GaussianAdam adam;
  const gs::GaussianMap before = map;
  EXPECT_THROW(engine->run({}, {gs::TrainingStep{0, 0}}, gs::TrainingLoss{}, &map, &adam), std::invalid_argument);
  EXPECT_EQ(map.positions(), before.positions());
}

}  // namespace
}  // namespace dqo::cuda
