// The GPU backend's rasteriser and engine sharing the engine's copy of the map (cuda_backend.h;
// skipped without a GPU): after training batches the rasteriser renders the trained map from that
// copy, bit-identical to a rasteriser that uploads the host's map; a map changed since (relabelled,
// pruned, another map) is uploaded instead, and renders right. The review's colour-only backward
// brings back the same colour gradients as a full one.

#include <gtest/gtest.h>

#include <random>

#include "../gaussians/raster_test_util.h"
#include "keyframe_test_util.h"
#include "dqo_map/cuda/cuda_backend.h"
#include "dqo_map/cuda/cuda_rasteriser.h"
#include "dqo_map/cuda/device_info.h"
#include "dqo_map/gaussians/trainer.h"

namespace dqo::cuda {
namespace {

using gs::testing::uniform;

constexpr int kWidth = 128, kHeight = 96;

// Keyframe k of a scene of random Gaussians (objects 1 and 2 in front of a background wall).
gs::TrainingKeyframe keyframe(const gs::GaussianMap& truth, int k) {
  const SE3 T_wc(Eigen::Quaterniond(Eigen::AngleAxisd(0.05 * k, Eigen::Vector3d::UnitY())),
                 Eigen::Vector3d(0.1 * k, 0.0, 0.0));
  return testing::rendered_keyframe(truth, gs::testing::make_camera(kWidth, kHeight, 110.0), T_wc,
                                    static_cast<uint32_t>(k + 1));
}

gs::GaussianMap scene(uint64_t seed) {
  std::mt19937_64 rng(seed);
  gs::GaussianMap map;
  for (int i = 0; i < 3000; ++i) {
    gs::GaussianInit g;
    const int object = i < 2000 ? 0 : 1 + i % 2;
    const double z = object == 0 ? uniform(rng, 2.9, 3.1) : uniform(rng, 1.6, 2.0);
    g.position = Eigen::Vector3f(uniform(rng, -2, 2) * (object ? 0.2 : 1.0) + 0.5 * object, uniform(rng, -1.5, 1.5) * (object ? 0.2 : 1.0), z);
    g.colour = Eigen::Vector3f(uniform(rng, 0, 1), uniform(rng, 0, 1), uniform(rng, 0, 1));
    for (int k = 0; k < 3; ++k) g.log_scale[k] = static_cast<float>(uniform(rng, -3.6, -2.6));
    g.rotation = Eigen::Vector4f(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1)).normalized();
    g.object_id = static_cast<uint32_t>(object);
    map.add(g);
  }
  return map;
}

void expect_same_render(const gs::RenderOutput& a, const gs::RenderOutput& b, const std::string& where) {
  EXPECT_EQ(a.rgb, b.rgb) << where;
  EXPECT_EQ(a.depth, b.depth) << where;
  EXPECT_EQ(a.alpha, b.alpha) << where;
  EXPECT_EQ(a.ins, b.ins) << where;
  EXPECT_EQ(a.dominant_id, b.dominant_id) << where;
}

TEST(CudaBackend, RendersTheEnginesCopyAsTheHostMapAndUploadsAChangedOne) {
  if (!gpu_available()) GTEST_SKIP() << "no GPU";
  for (uint64_t seed : {1u, 2u}) {
    const std::string where = "seed " + std::to_string(seed);
    const gs::GaussianMap truth = scene(seed);
    gs::GaussianTrainer::Params p;
    p.iterations = 20;
    p.seed = seed;
    CudaBackend backend = make_cuda_backend();
    gs::Rasteriser* shared = backend.rasteriser.get();
    gs::GaussianTrainer trainer(p, std::move(backend.rasteriser), std::move(backend.engine));
    ASSERT_TRUE(trainer.uses_engine());
    for (int k = 0; k < 4; ++k) trainer.add_keyframe(keyframe(truth, k));
    ASSERT_GT(trainer.map().size(), 1000u);
    auto alone = make_cuda_rasteriser();
    const gs::TrainingKeyframe view = keyframe(truth, 2);
    const SE3 T_cw = view.T_wc.inverse();
    gs::RenderSettings s;
    s.normalise_depth = true;
    s.ins_object = 1;
    gs::RenderOutput from_copy, uploaded;
    // The trainer's render syncs the engine's copy; then the shared rasteriser renders from it.
    trainer.render(view.camera, view.T_wc, &from_copy);
    shared->forward(trainer.map(), view.camera, T_cw, s, &from_copy, nullptr);
    ASSERT_TRUE(last_forward_timings(*shared)->resident) << where << ": the engine's copy is rendered";
    alone->forward(trainer.map(), view.camera, T_cw, s, &uploaded, nullptr);
    ASSERT_FALSE(last_forward_timings(*alone)->resident);
    expect_same_render(from_copy, uploaded, where + ", trained map");
    // Relabelled on the host (an object merge): no longer the copy's map until the next sync.
    ASSERT_GT(trainer.relabel(1, 2), 0u);
    shared->forward(trainer.map(), view.camera, T_cw, s, &from_copy, nullptr);
    EXPECT_FALSE(last_forward_timings(*shared)->resident) << where;
    alone->forward(trainer.map(), view.camera, T_cw, s, &uploaded, nullptr);
    expect_same_render(from_copy, uploaded, where + ", relabelled");
    // Another map (a copy of the same): uploaded.
    const gs::GaussianMap copy = trainer.map();
    shared->forward(copy, view.camera, T_cw, s, &from_copy, nullptr);
    EXPECT_FALSE(last_forward_timings(*shared)->resident) << where;
    expect_same_render(from_copy, uploaded, where + ", a copy");
    // More keyframes (appends, pruning, the relabelled IDs synced), then the copy again.
    for (int k = 4; k < 6; ++k) trainer.add_keyframe(keyframe(truth, k));
    trainer.render(view.camera, view.T_wc, &from_copy);
    shared->forward(trainer.map(), view.camera, T_cw, s, &from_copy, nullptr);
    EXPECT_TRUE(last_forward_timings(*shared)->resident) << where;
    alone->forward(trainer.map(), view.camera, T_cw, s, &uploaded, nullptr);
    expect_same_render(from_copy, uploaded, where + ", after more keyframes");
  }
}

TEST(CudaBackend, ColourOnlyBackwardBringsTheSameColourGradients) {
  if (!gpu_available()) GTEST_SKIP() << "no GPU";
  const gs::GaussianMap map = scene(3);
  const gs::TrainingKeyframe view = keyframe(map, 1);
  const SE3 T_cw = view.T_wc.inverse();
  auto r = make_cuda_rasteriser();
  gs::RenderSettings s;
  gs::RenderOutput out;
  std::unique_ptr<gs::RenderState> state;
  r->forward(map, view.camera, T_cw, s, &out, &state);
  gs::OutputGradients go;
  std::mt19937_64 rng(3);
  go.rgb.resize(out.rgb.size());
  for (float& v : go.rgb) v = static_cast<float>(uniform(rng, -1, 1));
  gs::MapGradients full, colour;
  colour.colour_only = true;
  r->backward(map, view.camera, T_cw, s, *state, go, &full);
  r->backward(map, view.camera, T_cw, s, *state, go, &colour);
  ASSERT_EQ(colour.colour.size(), full.colour.size());
  double diff = 0, norm = 0;
  for (size_t k = 0; k < full.colour.size(); ++k) {
    diff += std::abs(double(colour.colour[k]) - full.colour[k]);
    norm += std::abs(double(full.colour[k]));
  }
  EXPECT_GT(norm, 0.0);
  EXPECT_LE(diff, 1e-5 * norm) << "float atomics may sum in another order, nothing more";
  EXPECT_TRUE(colour.position.empty()) << "the geometry's gradients are not brought back";
}

}  // namespace
}  // namespace dqo::cuda
