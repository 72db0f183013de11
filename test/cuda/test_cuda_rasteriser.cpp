// The CUDA rasteriser against the CPU reference on random Gaussians (skipped without a GPU):
// every output per pixel within 1e-4 + 1e-4·|cpu| (the bound), for several seeds and every
// depth mode, and the object ID image equal everywhere: both run the same maths by the same float
// operations (no FMA in the kernels, one exp: gaussians/math/types.h) in the same per-pixel order,
// so a pixel cannot fall on different sides of a cut-off. Outputs are poisoned with NaN
// beforehand, so that a pixel the GPU does not write fails.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

#include "../../cuda/raster/raster_cuda.h"
#include "../gaussians/raster_test_util.h"
#include "dqo_map/cuda/cuda_rasteriser.h"
#include "dqo_map/cuda/device_info.h"

namespace dqo::cuda {
namespace {

using gs::testing::gaussian_at;
using gs::testing::uniform;

gs::GaussianMap random_map(const PinholeCamera& cam, const SE3& T_cw, uint64_t seed, int n) {
  std::mt19937_64 rng(seed);
  gs::GaussianMap map;
  for (int i = 0; i < n; ++i) {
    // Means across and a little beyond the image, at overlapping depths; sizes from sub-pixel to
    // tens of pixels; some object IDs and types.
    gs::GaussianInit g = gaussian_at(cam, T_cw, uniform(rng, -20, cam.width + 20), uniform(rng, -20, cam.height + 20),
                                     uniform(rng, 0.5, 4.0), rng, -6.0, -2.5);
    g.opacity = static_cast<float>(uniform(rng, 0.05, 0.99));
    g.object_id = static_cast<uint32_t>(rng() % 4);
    g.type = rng() % 3 == 0 ? gs::GaussianType::kTransparent : gs::GaussianType::kOpaque;
    map.add(g);
  }
  return map;
}

void poison(gs::RenderOutput* out, size_t pixels) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  out->rgb.assign(3 * pixels, nan);
  out->depth.assign(pixels, nan);
  out->alpha.assign(pixels, nan);
  out->ins.assign(pixels, nan);
  out->dominant_id.assign(pixels, 0xdeadbeefu);
}

void expect_close(const std::vector<float>& gpu, const std::vector<float>& cpu, const char* what, uint64_t seed) {
  ASSERT_EQ(gpu.size(), cpu.size()) << what;
  size_t bad = 0, first = 0, not_identical = 0;
  for (size_t i = 0; i < cpu.size(); ++i) {
    not_identical += gpu[i] != cpu[i];
    const bool ok = std::isfinite(gpu[i]) && std::abs(gpu[i] - cpu[i]) <= 1e-4f + 1e-4f * std::abs(cpu[i]);
    if (!ok && bad++ == 0) first = i;
  }
  EXPECT_EQ(bad, 0u) << what << " (seed " << seed << "): first at " << first << ": gpu " << gpu[first] << ", cpu "
                     << cpu[first];
  if (not_identical) std::printf("%s (seed %llu): %zu of %zu values not bit-identical\n", what,
                                 static_cast<unsigned long long>(seed), not_identical, cpu.size());
}

// The tile lists' mean length of the latest forward pass, and whether the compositing kernels
// walked them per warp there (detail::walk_for: the maps of 3000 Gaussians stay below, those of
// 40 000 go above, so both walks are checked against the CPU).
double pairs_per_tile(const gs::Rasteriser& r, const PinholeCamera& cam) {
  const auto t = last_forward_timings(r);
  const double tiles = std::ceil(cam.width / 16.0) * std::ceil(cam.height / 16.0);
  return t ? static_cast<double>(t->pairs) / tiles : 0.0;
}

TEST(CudaRasteriser, ForwardMatchesTheCpuReference) {
  if (!gpu_available()) GTEST_SKIP() << "no GPU";
  auto gpu = make_cuda_rasteriser();
  auto cpu = gs::make_cpu_rasteriser(2);
  const PinholeCamera cam = gs::testing::make_camera(173, 131, 150.0);  // not a whole number of tiles
  const SE3 T_cw = gs::testing::test_pose();
  const size_t pixels = static_cast<size_t>(cam.width) * cam.height;
  for (uint64_t seed : {1u, 2u, 3u, 4u}) {
    const bool dense = seed == 4;  // lists long enough for the per-warp walk
    const gs::GaussianMap map = random_map(cam, T_cw, seed, dense ? 40000 : 3000);
    for (int mode = 0; mode < 3; ++mode) {
      gs::RenderSettings settings;
      settings.normalise_depth = mode == 1;
      settings.surface_depth = mode == 2;
      settings.ins_object = 2;
      settings.background[0] = 0.2f, settings.background[2] = 0.7f;
      gs::RenderOutput a, b;
      poison(&a, pixels);
      gpu->forward(map, cam, T_cw, settings, &a, nullptr);
      cpu->forward(map, cam, T_cw, settings, &b, nullptr);
      ASSERT_EQ(a.width, cam.width);
      ASSERT_EQ(a.height, cam.height);
      SCOPED_TRACE("depth mode " + std::to_string(mode));
      if (dense)
        EXPECT_GE(pairs_per_tile(*gpu, cam), detail::kPerWarpFromPairsPerTile);
      else
        EXPECT_LT(pairs_per_tile(*gpu, cam), detail::kPerWarpFromPairsPerTile);
      expect_close(a.rgb, b.rgb, "rgb", seed);
      expect_close(a.depth, b.depth, "depth", seed);
      expect_close(a.alpha, b.alpha, "alpha", seed);
      expect_close(a.ins, b.ins, "ins", seed);
      size_t differ = 0;
      for (size_t p = 0; p < pixels; ++p) differ += a.dominant_id[p] != b.dominant_id[p];
      EXPECT_EQ(differ, 0u) << "dominant IDs (seed " << seed << ")";
      size_t covered = 0;
      for (float v : b.alpha) covered += v > 0.5f;
      EXPECT_GT(covered, pixels / 4) << "the scene covers the image";
    }
    // The masks' per-label instance opacity (each pixel's own object's).
    std::vector<uint32_t> labels(pixels);
    for (size_t p = 0; p < pixels; ++p) labels[p] = static_cast<uint32_t>((p % cam.width) / 40 + p / (40 * cam.width)) % 4;
    gs::RenderSettings per_label;
    per_label.ins_labels = labels.data();
    gs::RenderOutput a, b;
    poison(&a, pixels);
    gpu->forward(map, cam, T_cw, per_label, &a, nullptr);
    cpu->forward(map, cam, T_cw, per_label, &b, nullptr);
    expect_close(a.ins, b.ins, "per-label ins", seed);
    double total = 0.0;
    for (float v : b.ins) total += v;
    EXPECT_GT(total, 10.0) << "seed " << seed;
    // Only the images asked for come back, the same as in a full render; the others are empty
    // (the poison is gone too: nothing stale is handed out).
    gs::RenderSettings some = per_label;
    some.outputs = gs::kRenderIns | gs::kRenderDepth;
    gs::RenderOutput c;
    poison(&c, pixels);
    gpu->forward(map, cam, T_cw, some, &c, nullptr);
    expect_close(c.ins, b.ins, "ins alone", seed);
    expect_close(c.depth, b.depth, "depth alone", seed);
    EXPECT_TRUE(c.rgb.empty() && c.alpha.empty() && c.dominant_id.empty()) << "seed " << seed;
  }
}

TEST(CudaRasteriser, EmptyMapAndReuse) {
  if (!gpu_available()) GTEST_SKIP() << "no GPU";
  auto gpu = make_cuda_rasteriser();
  const PinholeCamera cam = gs::testing::make_camera(64, 48, 60.0);
  gs::RenderSettings settings;
  settings.background[1] = 0.5f;
  gs::RenderOutput out;
  poison(&out, 64 * 48);
  gpu->forward(gs::GaussianMap(), cam, SE3(), settings, &out, nullptr);
  for (size_t p = 0; p < out.alpha.size(); ++p) {
    ASSERT_EQ(out.alpha[p], 0.f);
    ASSERT_EQ(out.rgb[3 * p + 1], 0.5f) << "background";
    ASSERT_EQ(out.dominant_id[p], 0u);
  }
  // A larger map, then a smaller one: buffers grow and are reused.
  auto cpu = gs::make_cpu_rasteriser(1);
  for (int n : {500, 50}) {
    const gs::GaussianMap map = random_map(cam, gs::testing::test_pose(), 7 + n, n);
    gs::RenderOutput a, b;
    gpu->forward(map, cam, gs::testing::test_pose(), settings, &a, nullptr);
    cpu->forward(map, cam, gs::testing::test_pose(), settings, &b, nullptr);
    expect_close(a.rgb, b.rgb, "rgb", n);
  }
  gs::MapGradients grad;
  EXPECT_THROW(gpu->backward(gs::GaussianMap(), cam, SE3(), settings, gs::RenderState(), {}, &grad),
               std::invalid_argument)
      << "a state that is not the latest forward's";
}

// ‖gpu − cpu‖ / ‖cpu‖ over one attribute's gradient.
double relative_l2(const std::vector<float>& gpu, const std::vector<float>& cpu) {
  double num = 0, den = 0;
  for (size_t i = 0; i < cpu.size(); ++i) {
    num += (double(gpu[i]) - cpu[i]) * (double(gpu[i]) - cpu[i]);
    den += double(cpu[i]) * cpu[i];
  }
  return den > 0 ? std::sqrt(num / den) : std::sqrt(num);
}

TEST(CudaRasteriser, BackwardMatchesTheCpuReference) {
  if (!gpu_available()) GTEST_SKIP() << "no GPU";
  auto gpu = make_cuda_rasteriser();
  auto cpu = gs::make_cpu_rasteriser(2);
  const PinholeCamera cam = gs::testing::make_camera(173, 131, 150.0);
  const SE3 T_cw = gs::testing::test_pose();
  const size_t pixels = static_cast<size_t>(cam.width) * cam.height;
  for (uint64_t seed : {11u, 12u, 13u, 14u}) {
    const bool dense = seed == 14;  // lists long enough for the per-warp walk
    const gs::GaussianMap map = random_map(cam, T_cw, seed, dense ? 40000 : 2000);
    std::mt19937_64 rng(seed);
    gs::OutputGradients go;  // random dL/d(outputs), as a loss would give
    go.rgb.resize(3 * pixels), go.depth.resize(pixels), go.alpha.resize(pixels), go.ins.resize(pixels);
    for (auto* v : {&go.rgb, &go.depth, &go.alpha, &go.ins})
      for (float& x : *v) x = static_cast<float>(uniform(rng, -1, 1));
    for (int mode = 0; mode < 3; ++mode) {
      SCOPED_TRACE("seed " + std::to_string(seed) + ", depth mode " + std::to_string(mode));
      gs::RenderSettings settings;
      settings.normalise_depth = mode == 1;
      settings.surface_depth = mode == 2;
      settings.ins_object = 2;
      settings.background[1] = 0.3f;
      gs::RenderOutput a, b;
      std::unique_ptr<gs::RenderState> sa, sb;
      gpu->forward(map, cam, T_cw, settings, &a, &sa);
      cpu->forward(map, cam, T_cw, settings, &b, &sb);
      EXPECT_EQ(pairs_per_tile(*gpu, cam) >= detail::kPerWarpFromPairsPerTile, dense);
      gs::MapGradients ga, gb;
      gpu->backward(map, cam, T_cw, settings, *sa, go, &ga);
      cpu->backward(map, cam, T_cw, settings, *sb, go, &gb);
      EXPECT_LE(relative_l2(ga.position, gb.position), 1e-3);
      EXPECT_LE(relative_l2(ga.log_scale, gb.log_scale), 1e-3);
      EXPECT_LE(relative_l2(ga.rotation, gb.rotation), 1e-3);
      EXPECT_LE(relative_l2(ga.opacity, gb.opacity), 1e-3);
      EXPECT_LE(relative_l2(ga.colour, gb.colour), 1e-3);
      double norm = 0;
      for (float v : gb.position) norm += double(v) * v;
      EXPECT_GT(norm, 0.0) << "the gradients are not all zero";
      // A second backward adds to the first (the first came down straight into the empty arrays);
      // the float atomics' order differs between the two, hence a relative L2 bound.
      gs::MapGradients twice = ga;
      gpu->backward(map, cam, T_cw, settings, *sa, go, &twice);
      std::vector<float> doubled_position = ga.position, doubled_colour = ga.colour;
      for (float& v : doubled_position) v *= 2.f;
      for (float& v : doubled_colour) v *= 2.f;
      EXPECT_LE(relative_l2(twice.position, doubled_position), 1e-5);
      EXPECT_LE(relative_l2(twice.colour, doubled_colour), 1e-5);
      std::printf("seed %llu mode %d: relative L2 position %.2e log-scale %.2e rotation %.2e opacity %.2e colour %.2e\n",
                  static_cast<unsigned long long>(seed), mode, relative_l2(ga.position, gb.position),
                  relative_l2(ga.log_scale, gb.log_scale), relative_l2(ga.rotation, gb.rotation),
                  relative_l2(ga.opacity, gb.opacity), relative_l2(ga.colour, gb.colour));
    }
  }
}

}  // namespace
}  // namespace dqo::cuda
