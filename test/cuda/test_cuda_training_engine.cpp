// The CUDA training engine against the host trainer (skipped without a GPU): the same keyframes
// through two GaussianTrainers, one iterating on the host with the CPU rasteriser, one on the GPU
// engine. One step has the same gradients (1e-3) and steps the same Gaussians; a mapping step's
// loss curve stays within 1 %; whole runs (add, train, prune) render as well; several seeds; the
// keyframe review on the device keeps the host loop's counters and relabels.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <limits>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "../gaussians/raster_test_util.h"
#include "keyframe_test_util.h"
#include "dqo_map/cuda/cuda_backend.h"
#include "dqo_map/cuda/cuda_rasteriser.h"
#include "dqo_map/cuda/cuda_training_engine.h"
#include "dqo_map/cuda/device_info.h"
#include "dqo_map/gaussians/math/prune.h"
#include "dqo_map/gaussians/math/review.h"
#include "dqo_map/gaussians/removal_plan.h"
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

// A batch works on the Gaussians its views reach (the selection, train_select.cu), through an
// index list when some are out of every view: Gaussians behind the cameras and far to the side,
// scattered among the others (a removal's plan moves them into its holes), change nothing of what
// the in-view ones learn, and stay as they were.
TEST(CudaTrainingEngine, ABatchLeavesOutWhatNoViewReaches) {
  if (!gpu_available()) GTEST_SKIP() << "no GPU";
  for (uint64_t seed : {4u, 5u}) {
    const gs::GaussianMap truth = truth_map(seed);
    Pair t(params(seed, 0));
    build_alike(&t, truth, 3);
    gs::GaussianMap m = t.host.map();
    const size_t in_view = m.size();
    std::mt19937_64 rng(seed);
    for (int i = 0; i < 1500; ++i) {
      gs::GaussianInit g;
      g.position = i % 2 ? Eigen::Vector3f(uniform(rng, -2, 2), uniform(rng, -2, 2), uniform(rng, -3, -0.5))
                         : Eigen::Vector3f(uniform(rng, 30, 40), uniform(rng, -2, 2), uniform(rng, 2, 4));
      g.colour = Eigen::Vector3f(0.2f, 0.9f, 0.4f);
      g.log_scale = Eigen::Vector3f::Constant(-3.f);
      g.rotation = Eigen::Vector4f(1, 0, 0, 0);
      m.add(g);
    }
    std::vector<uint8_t> remove(m.size(), 0);
    for (size_t i = 0; i < in_view; i += 8) remove[i] = 1;
    m.remove_if(remove);
    const auto out_of_view = [&](size_t i) { return m.positions()[3 * i + 2] < 0.f || m.positions()[3 * i] > 20.f; };
    size_t scattered = 0;
    for (size_t i = 0; i + 1500 < m.size(); ++i) scattered += out_of_view(i);
    ASSERT_GT(scattered, 100u) << "seed " << seed << ": out-of-view Gaussians among the others";
    t.host.set_map(m);
    t.gpu.set_map(m);
    const double loss_host = t.host.optimise(1), loss_gpu = t.gpu.optimise(1);
    EXPECT_NEAR(loss_gpu, loss_host, 1e-4 * loss_host) << "seed " << seed;
    const gs::GaussianMap& h = t.host.map();
    const gs::GaussianMap& g = t.gpu.map();
    ASSERT_EQ(g.size(), m.size());
    size_t moved_host = 0, moved_gpu = 0, out_moved = 0;
    for (size_t i = 0; i < h.size(); ++i) {
      moved_host += h.confidences()[i] > 0.f;
      moved_gpu += g.confidences()[i] > 0.f;
      if (!out_of_view(i)) continue;
      for (int k = 0; k < 3; ++k) out_moved += g.positions()[3 * i + k] != m.positions()[3 * i + k];
    }
    EXPECT_GT(moved_host, h.size() / 4) << "seed " << seed;
    EXPECT_EQ(moved_gpu, moved_host) << "seed " << seed << ": the same Gaussians step";
    EXPECT_EQ(out_moved, 0u) << "seed " << seed;
    const gs::GaussianAdam::State& sh = t.host.adam_state();
    const gs::GaussianAdam::State& sg = t.gpu.adam_state();
    EXPECT_LE(relative_l2(sg.position.m, sh.position.m), 1e-3) << "position gradients, seed " << seed;
    EXPECT_LE(relative_l2(sg.colour.m, sh.colour.m), 1e-3) << "colour gradients, seed " << seed;
    EXPECT_EQ(sg.steps, sh.steps) << "seed " << seed;
    EXPECT_LE(relative_l2(g.positions(), h.positions()), 1e-5) << "seed " << seed;
    EXPECT_LE(relative_l2(g.colours(), h.colours()), 1e-3) << "seed " << seed;
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

// The keyframe review on the device (TrainingEngine::review) against the host's loop over
// math/review.h with the CPU rasteriser's colour sums: the same counters and relabels, but for the
// few Gaussians whose sums (added in another order) sit on a threshold. A third of object 1's
// Gaussians start labelled background and the views show them on its pixels: relabels happen.
// Two engines: a lone one, which takes the host's counters and gives them back each review, and
// the backend's with deferred attributes, which keeps its own from review to review — through a
// removal and appends between keyframes — until fetched at the end; its pruning flags
// (flag_prune: size and invisibility) are then the host's too.
TEST(CudaTrainingEngine, ReviewOnTheDeviceMatchesTheHostLoop) {
  if (!gpu_available()) GTEST_SKIP() << "no GPU";
  const gs::GaussianMap truth = truth_map(3);
  gs::GaussianMap map = truth;
  std::vector<uint32_t> truth_ids = truth.object_ids_per_gaussian();  // in step with map's indices
  std::vector<std::pair<uint32_t, uint32_t>> wrong;
  for (uint32_t i : map.indices_of(1))
    if (i % 3 == 0) wrong.emplace_back(i, 0u);
  ASSERT_GT(map.relabel_each(wrong), 100u);
  gs::GaussianAdam adam;
  auto engine = make_cuda_training_engine();
  CudaBackend backend = make_cuda_backend();
  ASSERT_TRUE(backend.engine->defer_attributes(true));
  auto cpu = gs::make_cpu_rasteriser(0);
  const gs::GaussianTrainer::Params p;
  const gs::ReviewSettings rs = p.review_settings();
  gs::RenderSettings settings;
  settings.normalise_depth = p.normalise_depth;
  const float inf = std::numeric_limits<float>::infinity();
  std::vector<float> use_h(map.size(), inf), use_k = use_h;
  std::vector<uint16_t> inv_h(map.size(), 0), inv_k = inv_h;
  std::vector<uint8_t> votes_h(map.size(), 0), votes_k = votes_h;
  // Counters alike: the same but for Gaussians whose sums sit on a threshold (rare).
  auto count_differing = [](const std::vector<float>& ua, const std::vector<uint16_t>& ia,
                            const std::vector<uint8_t>& va, const std::vector<float>& ub,
                            const std::vector<uint16_t>& ib, const std::vector<uint8_t>& vb) {
    size_t off = 0;
    for (size_t i = 0; i < ua.size(); ++i) {
      const bool same = ia[i] == ib[i] && va[i] == vb[i] &&
                        (ua[i] == ub[i] || std::abs(ua[i] - ub[i]) <= 1e-4f * std::abs(ub[i]) + 1e-6f);
      off += same ? 0 : 1;
    }
    return off;
  };
  size_t relabelled = 0, fixed = 0;
  for (int k = 0; k < 5; ++k) {
    const std::string where = "keyframe " + std::to_string(k);
    if (k == 3) {
      // Between keyframes: every seventh Gaussian removed (by one plan everywhere: the map, the
      // host's counters, the backend's kept ones), then 40 appended (counters start afresh).
      std::vector<uint8_t> remove(map.size(), 0);
      for (size_t i = 0; i < remove.size(); i += 7) remove[i] = 1;
      const gs::RemovalPlan plan = gs::plan_removal(remove);
      map.remove_if(remove);
      adam.remove_if(remove);
      backend.engine->map_removed(gs::plan_removal(remove));
      gs::apply_removal(&truth_ids, 1, plan);
      gs::apply_removal(&use_h, 1, plan);
      gs::apply_removal(&inv_h, 1, plan);
      gs::apply_removal(&votes_h, 1, plan);
      for (int a = 0; a < 40; ++a) {
        gs::GaussianInit g = truth.gaussian(static_cast<size_t>(a) * 11);
        g.position += Eigen::Vector3f(0.01f, 0.f, 0.f);
        map.add(g);
        truth_ids.push_back(g.object_id);
        use_h.push_back(inf), inv_h.push_back(0), votes_h.push_back(0);
      }
      use_k.resize(map.size(), inf), inv_k.resize(map.size(), 0), votes_k.resize(map.size(), 0);
    }
    const size_t n = map.size();
    adam.resize_for(map);
    const gs::TrainingKeyframe kf = keyframe(truth, k % 4);
    const SE3 T_cw = kf.T_wc.inverse();
    const gs::ReviewView view = gs::review_view_of(kf.camera, T_cw, kf.depth, kf.labels);
    // Host: the probe's colour sums from the CPU rasteriser, then the loop (a relabelled
    // Gaussian's votes start over, as the trainer's relabelling does).
    gs::RenderOutput out;
    std::unique_ptr<gs::RenderState> state;
    cpu->forward(map, kf.camera, T_cw, settings, &out, &state);
    gs::OutputGradients probe;
    probe.rgb.resize(3 * kf.labels.data.size());
    for (size_t q = 0; q < kf.labels.data.size(); ++q) {
      probe.rgb[3 * q] = 1.f;
      probe.rgb[3 * q + 1] = kf.labels.data[q] == 0 ? 1.f : 0.f;
      probe.rgb[3 * q + 2] = kf.labels.data[q] != 0 ? 1.f : 0.f;
    }
    gs::MapGradients g;
    cpu->backward(map, kf.camera, T_cw, settings, *state, probe, &g);
    std::vector<float> use_d = use_h;  // the lone engine starts from the host's counters
    std::vector<uint16_t> inv_d = inv_h;
    std::vector<uint8_t> votes_d = votes_h;
    std::vector<std::pair<uint32_t, uint32_t>> relabels_h, relabels_d, relabels_k;
    for (size_t i = 0; i < n; ++i) {
      uint32_t id = 0;
      if (gs::review_gaussian(view, rs, map.positions().data() + 3 * i, map.object_ids_per_gaussian()[i],
                              g.colour.data() + 3 * i, &use_h[i], &inv_h[i], &votes_h[i], &id)) {
        relabels_h.emplace_back(static_cast<uint32_t>(i), id);
        votes_h[i] = 0;
      }
    }
    // Devices.
    const gs::TrainingView tv{kf.id, &kf.camera, T_cw, &kf.rgb, &kf.depth, &kf.labels};
    engine->sync(map, adam);
    ASSERT_TRUE(engine->review(map, tv, settings, view, rs, use_d.data(), inv_d.data(), votes_d.data(), &relabels_d))
        << where;
    EXPECT_FALSE(engine->holds_review_counters()) << where;
    backend.engine->sync(map, adam);
    ASSERT_TRUE(backend.engine->review(map, tv, settings, view, rs, use_k.data(), inv_k.data(), votes_k.data(),
                                       &relabels_k))
        << where;
    EXPECT_TRUE(backend.engine->holds_review_counters()) << where;
    const size_t off = count_differing(use_d, inv_d, votes_d, use_h, inv_h, votes_h);
    std::vector<std::pair<uint32_t, uint32_t>> only, only_k;
    std::set_symmetric_difference(relabels_h.begin(), relabels_h.end(), relabels_d.begin(), relabels_d.end(),
                                  std::back_inserter(only));
    std::set_symmetric_difference(relabels_h.begin(), relabels_h.end(), relabels_k.begin(), relabels_k.end(),
                                  std::back_inserter(only_k));
    std::printf("%s: %zu of %zu Gaussians' counters differ, relabels host %zu device %zu kept %zu (%zu, %zu not "
                "shared)\n",
                where.c_str(), off, n, relabels_h.size(), relabels_d.size(), relabels_k.size(), only.size(),
                only_k.size());
    EXPECT_LE(off, n / 500) << where;
    EXPECT_LE(only.size(), relabels_h.size() / 50 + 2) << where;
    EXPECT_LE(only_k.size(), relabels_h.size() / 50 + 2) << where;
    // On from the host's result, as the trainer goes on.
    for (const auto& [i, id] : relabels_h) fixed += id == 1 && truth_ids[i] == 1 ? 1 : 0;
    map.relabel_each(relabels_h);
    relabelled += relabels_h.size();
  }
  // Relabels happened (a Gaussian needs relabel_keyframes views in a row voting for the same
  // label: those the first keyframes see), and most put a mislabelled Gaussian back.
  std::printf("relabelled %zu, of which %zu of the %zu mislabelled back to object 1\n", relabelled, fixed,
              wrong.size());
  EXPECT_GE(fixed, 50u) << "the mislabelled Gaussians were to follow the views";
  EXPECT_GE(fixed, relabelled * 9 / 10);
  // The backend's pruning flags on its kept counters, then the counters themselves, handed back.
  const float max_log_scale = std::log(0.045f);
  const int max_invisible = 2;
  std::vector<uint8_t> flags;
  backend.engine->sync(map, adam);  // the last relabelling changed the map
  ASSERT_TRUE(backend.engine->flag_prune(map, max_log_scale, max_invisible, use_k.data(), inv_k.data(),
                                         votes_k.data(), &flags));
  ASSERT_EQ(flags.size(), map.size());
  size_t flag_off = 0, unseen = 0;
  for (size_t i = 0; i < map.size(); ++i) {
    const uint8_t want = (gs::oversized(map.log_scales().data() + 3 * i, max_log_scale) ? 1 : 0) |
                         (inv_h[i] >= max_invisible ? 2 : 0);
    flag_off += flags[i] != want ? 1 : 0;
    unseen += (flags[i] & 2) ? 1 : 0;
  }
  std::printf("pruning flags: %zu invisible for %d keyframes, %zu differ from the host's\n", unseen, max_invisible,
              flag_off);
  EXPECT_LE(flag_off, map.size() / 500);
  EXPECT_GT(unseen, 0u);
  backend.engine->fetch_review_counters(use_k.data(), inv_k.data(), votes_k.data());
  EXPECT_FALSE(backend.engine->holds_review_counters());
  const size_t off_k = count_differing(use_k, inv_k, votes_k, use_h, inv_h, votes_h);
  std::printf("kept counters after %d keyframes: %zu of %zu differ from the host's\n", 5, off_k, map.size());
  EXPECT_LE(off_k, map.size() / 500);
  const size_t fresh = static_cast<size_t>(std::count(use_k.end() - 40, use_k.end(), inf));
  EXPECT_LT(fresh, 40u) << "the appended Gaussians were reviewed too";
}

// The backend's engine keeps what it trains on the device (TrainingEngine::defer_attributes) until
// fetched: a batch leaves the host map as it was; a removal and appends between batches keep what
// was trained (the device removes by the host's plan); fetch_attributes() then gives what an
// engine that writes back after every batch gives (to the order of float atomics), the Gaussians
// appended since the last batch keep the host's values, and the pruning's size test on the device
// is the host's on the fetched values, to the bit. A lone engine does not defer.
TEST(CudaTrainingEngine, DeferredAttributesComeDownWhenFetched) {
  if (!gpu_available()) GTEST_SKIP() << "no GPU";
  const gs::GaussianMap truth = truth_map(11);
  gs::GaussianMap start = truth;
  std::mt19937_64 rng(12);
  for (float& x : start.positions()) x += static_cast<float>(uniform(rng, -0.02, 0.02));
  for (float& c : start.colours()) c = std::clamp(c + static_cast<float>(uniform(rng, -0.1, 0.1)), 0.f, 1.f);
  CudaBackend backend = make_cuda_backend();
  auto eager = make_cuda_training_engine();
  EXPECT_FALSE(eager->defer_attributes(true)) << "a lone engine: renders of its map do not show its copy";
  ASSERT_TRUE(backend.engine->defer_attributes(true));
  const gs::GaussianTrainer::Params p;
  std::vector<gs::TrainingKeyframe> kfs;
  for (int k = 0; k < 3; ++k) kfs.push_back(keyframe(truth, k));
  std::vector<gs::TrainingView> views;
  for (const auto& kf : kfs)
    views.push_back(gs::TrainingView{kf.id, &kf.camera, kf.T_wc.inverse(), &kf.rgb, &kf.depth, &kf.labels});
  std::vector<gs::TrainingStep> steps;
  for (uint32_t k = 0; k < 12; ++k) steps.push_back(gs::TrainingStep{k % 3, k % 4});
  gs::TrainingLoss loss;
  loss.settings.normalise_depth = p.normalise_depth;
  loss.lambda_depth = p.lambda_depth;
  loss.lambda_ins = p.lambda_ins;
  gs::GaussianMap md = start, me = start;
  gs::GaussianAdam ad(p.adam), ae(p.adam);
  backend.engine->run(views, steps, loss, &md, &ad);
  eager->run(views, steps, loss, &me, &ae);
  EXPECT_EQ(md.positions(), start.positions()) << "the batch left the host map as it was";
  EXPECT_NE(me.positions(), start.positions()) << "the eager engine wrote back";
  // Between batches: every fifth Gaussian removed, 50 appended; a second batch; 20 more appended.
  std::vector<uint8_t> remove(md.size(), 0);
  for (size_t i = 0; i < remove.size(); i += 5) remove[i] = 1;
  auto append = [&](int count, uint64_t seed) {
    std::mt19937_64 r(seed);
    for (int i = 0; i < count; ++i) {
      gs::GaussianInit g;
      g.position = Eigen::Vector3f(uniform(r, -1, 1), uniform(r, -1, 1), uniform(r, 2, 3));
      g.colour = Eigen::Vector3f(0.5f, 0.4f, 0.3f);
      g.log_scale = Eigen::Vector3f::Constant(-3.f);
      g.rotation = Eigen::Vector4f(1, 0, 0, 0);
      md.add(g);
      me.add(g);
    }
  };
  md.remove_if(remove);
  backend.engine->map_removed(gs::plan_removal(remove));
  me.remove_if(remove);
  eager->map_removed(gs::plan_removal(remove));
  append(50, 13);
  backend.engine->run(views, steps, loss, &md, &ad);
  eager->run(views, steps, loss, &me, &ae);
  append(20, 14);
  const gs::GaussianMap before_fetch = md;
  backend.engine->fetch_attributes(&md);
  const size_t n = md.size();
  ASSERT_EQ(n, me.size());
  const double e_pos = relative_l2(md.positions(), me.positions()), e_col = relative_l2(md.colours(), me.colours());
  const double e_scale = relative_l2(md.log_scales(), me.log_scales()), e_rot = relative_l2(md.rotations(), me.rotations());
  std::printf("deferred against eager: relative L2 positions %.2e, colours %.2e, log-scales %.2e, rotations %.2e\n",
              e_pos, e_col, e_scale, e_rot);
  EXPECT_LE(e_pos, 1e-5);
  EXPECT_LE(e_col, 1e-3);
  EXPECT_LE(e_scale, 1e-3);
  EXPECT_LE(e_rot, 1e-3);
  EXPECT_EQ(md.confidences(), me.confidences()) << "the same Gaussians stepped as often";
  EXPECT_GT(relative_l2(before_fetch.positions(), me.positions()), 10 * e_pos) << "the fetch brought the training";
  for (size_t i = n - 20; i < n; ++i) {
    for (int k = 0; k < 3; ++k) EXPECT_EQ(md.positions()[3 * i + k], before_fetch.positions()[3 * i + k]) << i;
  }
  // The size test on the device, on the held values (the last 20 sent first).
  ad.resize_for(md);
  backend.engine->sync(md, ad);
  ASSERT_TRUE(backend.engine->holds(md));
  const float max_log_scale = std::log(0.045f);
  std::vector<uint8_t> flags;
  ASSERT_TRUE(backend.engine->flag_prune(md, max_log_scale, 0, nullptr, nullptr, nullptr, &flags));
  ASSERT_EQ(flags.size(), n);
  size_t flagged = 0, differ = 0;
  for (size_t i = 0; i < n; ++i) {
    flagged += flags[i];
    differ += flags[i] != (gs::oversized(md.log_scales().data() + 3 * i, max_log_scale) ? 1 : 0);
  }
  EXPECT_EQ(differ, 0u);
  EXPECT_GT(flagged, 0u);
  EXPECT_LT(flagged, n);
  EXPECT_FALSE(eager->flag_prune(md, max_log_scale, 0, nullptr, nullptr, nullptr, &flags))
      << "it does not hold this map";
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
