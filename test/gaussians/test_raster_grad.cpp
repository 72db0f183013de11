// The CPU rasteriser's backward pass against central finite differences, in double precision, for
// every parameter of every Gaussian and every output (rgb, depth raw, normalised and of the
// surface, accumulated alpha, ins). The Gaussians sit away from the cut-offs: transmittance stays
// far above the early stop, opacities below the 0.99 cap, and the 1/255 boundary moves by far less
// than a pixel spacing for the step used, so the rendered outputs are smooth in the parameters.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "raster_test_util.h"

namespace dqo::gs {
namespace {

using testing::DoubleGaussians;
using testing::Images;
using testing::render;
using testing::uniform;

enum class Output { kRgb, kDepth, kDepthNormalised, kDepthSurface, kAlpha, kIns };

struct Fixture {
  PinholeCamera camera = testing::make_camera(64, 48, 60.0);
  SE3 T_cw = testing::test_pose();
  RenderSettings settings;
  DoubleGaussians gaussians;
};

// For the surface depth, the Gaussians lie in two layers 0.6 m apart, 0.12 m deep each (two
// surfaces, fringes of the front one over the back one) rather than spread over 2 to 3 m.
Fixture make_fixture(uint64_t seed, Output output) {
  Fixture f;
  f.settings.normalise_depth = output == Output::kDepthNormalised;
  f.settings.surface_depth = output == Output::kDepthSurface;
  f.settings.ins_object = 3;
  f.settings.background[0] = 0.3f;
  f.settings.background[1] = 0.6f;
  f.settings.background[2] = 0.1f;
  std::mt19937_64 rng(seed);
  const uint32_t ids[] = {3, 3, 3, 5, 0, 3};
  const GaussianType types[] = {GaussianType::kOpaque,      GaussianType::kOpaque,
                                GaussianType::kTransparent, GaussianType::kOpaque,
                                GaussianType::kOpaque,      GaussianType::kOpaque};
  for (int i = 0; i < 6; ++i) {
    GaussianInit g = testing::gaussian_at(
        f.camera, f.T_cw, uniform(rng, 14, 50), uniform(rng, 12, 36),
        f.settings.surface_depth ? (i % 2 ? 2.0 : 2.6) + uniform(rng, 0.0, 0.12)
                                 : uniform(rng, 2.0, 3.0),
        rng, std::log(0.06), std::log(0.15));
    g.object_id = ids[i];
    g.type = types[i];
    // Front Gaussians opaque enough to be the surface near their centres.
    f.gaussians.add(g, uniform(rng, f.settings.surface_depth && i % 2 ? 0.7 : 0.3, 0.9));
  }
  return f;
}

// Fixed random weights per output value: L = Σ w · (output − base output). The base, a constant,
// changes no gradient; it makes the round-off of a difference L(x + ε) − L(x − ε) scale with the
// change of the outputs rather than with their size (the surface depth's gradients in scale,
// rotation and opacity are small: they go with the depth offsets within a surface).
struct Loss {
  Output output;
  std::vector<double> w;
  std::vector<double> base;

  double operator()(const Images<double>& im) const {
    const std::vector<double>& v = values(im);
    double sum = 0.0;
    for (size_t i = 0; i < v.size(); ++i) sum += w[i] * (v[i] - base[i]);
    return sum;
  }
  const std::vector<double>& values(const Images<double>& im) const {
    switch (output) {
      case Output::kRgb:
        return im.rgb;
      case Output::kDepth:
      case Output::kDepthNormalised:
      case Output::kDepthSurface:
        return im.depth;
      case Output::kAlpha:
        return im.alpha;
      case Output::kIns:
        return im.ins;
    }
    return im.rgb;
  }
  detail::ImageGradients<double> gradients() const {
    detail::ImageGradients<double> g;
    switch (output) {
      case Output::kRgb:
        g.rgb = w.data();
        break;
      case Output::kDepth:
      case Output::kDepthNormalised:
      case Output::kDepthSurface:
        g.depth = w.data();
        break;
      case Output::kAlpha:
        g.alpha = w.data();
        break;
      case Output::kIns:
        g.ins = w.data();
        break;
    }
    return g;
  }
};

void check_gradients(Output output, uint64_t seed) {
  Fixture f = make_fixture(seed, output);
  const Images<double> base =
      render(f.gaussians.arrays(), f.camera, f.T_cw, f.settings, 2, /*keep_state=*/true);
  // Away from the early stop; every Gaussian visible.
  EXPECT_GT(*std::min_element(base.alpha.begin(), base.alpha.end()), -1e-12);
  EXPECT_LT(*std::max_element(base.alpha.begin(), base.alpha.end()), 0.999);

  if (output == Output::kDepthSurface) {
    // The fixture must exercise both choices against the normalised depth, which mixes the two
    // surfaces: pixels where the front one's fringe is skipped, and pixels where the front one
    // is kept while the back one still adds to the mix.
    RenderSettings mixed = f.settings;
    mixed.surface_depth = false;
    mixed.normalise_depth = true;
    const Images<double> m = render(f.gaussians.arrays(), f.camera, f.T_cw, mixed, 2);
    int back_kept = 0, front_kept = 0;
    for (size_t p = 0; p < m.depth.size(); ++p) {
      back_kept += base.depth[p] > 2.4 && base.depth[p] - m.depth[p] > 0.02;
      front_kept += base.depth[p] < 2.4 && m.depth[p] - base.depth[p] > 0.02;
    }
    EXPECT_GT(back_kept, 10);
    EXPECT_GT(front_kept, 10);
  }

  std::mt19937_64 rng(seed + 100);
  Loss loss{output, {}, {}};
  loss.w.resize(loss.values(base).size());
  for (double& w : loss.w) w = uniform(rng, -1, 1);
  loss.base = loss.values(base);
  double weighted = 0.0;  // Σ w · output: the outputs carry something for the weights to probe
  for (size_t i = 0; i < loss.w.size(); ++i) weighted += loss.w[i] * loss.base[i];
  ASSERT_GT(std::abs(weighted), 0.0);

  const size_t n = f.gaussians.size();
  std::vector<double> g_pos(3 * n, 0), g_ls(3 * n, 0), g_rot(4 * n, 0), g_op(n, 0), g_col(3 * n, 0);
  detail::AttributeGradients<double> grad;
  grad.position = g_pos.data();
  grad.log_scale = g_ls.data();
  grad.rotation = g_rot.data();
  grad.opacity = g_op.data();
  grad.colour = g_col.data();
  detail::cpu_backward(f.gaussians.arrays(), f.camera, f.T_cw, f.settings, 2, *base.state,
                       loss.gradients(), grad);

  const char* names[] = {"position", "log_scale", "rotation", "opacity", "colour"};
  const std::vector<double>* analytic[] = {&g_pos, &g_ls, &g_rot, &g_op, &g_col};
  const double eps = 1e-6;
  int checked = 0;
  for (int b = 0; b < 5; ++b) {
    std::vector<double>& param = *f.gaussians.blocks()[b];
    std::vector<double> numeric(param.size());
    for (size_t i = 0; i < param.size(); ++i) {
      const double x = param[i];
      param[i] = x + eps;
      const double lp = loss(render(f.gaussians.arrays(), f.camera, f.T_cw, f.settings, 2));
      param[i] = x - eps;
      const double lm = loss(render(f.gaussians.arrays(), f.camera, f.T_cw, f.settings, 2));
      param[i] = x;
      numeric[i] = (lp - lm) / (2 * eps);
    }
    double block_max = 0.0;
    for (double d : numeric) block_max = std::max(block_max, std::abs(d));
    for (size_t i = 0; i < param.size(); ++i) {
      const double a = (*analytic[b])[i], d = numeric[i];
      // Relative to the entry itself, or to the block's largest where the entry is ~0 (the
      // quaternion's radial direction, the colour of a depth loss).
      const double denom = std::max({std::abs(d), std::abs(a), 1e-3 * block_max, 1e-12});
      EXPECT_LT(std::abs(a - d) / denom, 1e-4)
          << names[b] << "[" << i << "] analytic " << a << " numeric " << d;
      ++checked;
    }
  }
  EXPECT_EQ(checked, static_cast<int>(14 * n));
}

TEST(RasteriserGradients, Rgb) { check_gradients(Output::kRgb, 11); }
TEST(RasteriserGradients, Depth) { check_gradients(Output::kDepth, 12); }
TEST(RasteriserGradients, NormalisedDepth) { check_gradients(Output::kDepthNormalised, 13); }
TEST(RasteriserGradients, SurfaceDepth) { check_gradients(Output::kDepthSurface, 16); }
TEST(RasteriserGradients, AccumulatedAlpha) { check_gradients(Output::kAlpha, 14); }
TEST(RasteriserGradients, Ins) { check_gradients(Output::kIns, 15); }

// Where the early stop cuts pixels off, the gradient is still that of the rendered image (the cut
// moves only when some pixel's transmittance crosses 1e-4 exactly, which a 1e-6 step does not
// cause): a dense, opaque cluster, a sample of parameters, the rgb and depth outputs.
TEST(RasteriserGradients, ThroughTheEarlyStop) {
  const PinholeCamera camera = testing::make_camera(48, 40, 45.0);
  const SE3 T_cw = testing::test_pose();
  std::mt19937_64 rng(31);
  DoubleGaussians d;
  for (int i = 0; i < 30; ++i) {
    GaussianInit g =
        testing::gaussian_at(camera, T_cw, uniform(rng, 16, 32), uniform(rng, 14, 26),
                             uniform(rng, 2.0, 3.0), rng, std::log(0.12), std::log(0.25));
    d.add(g, uniform(rng, 0.6, 0.9));
  }
  RenderSettings settings;
  settings.background[1] = 0.5f;
  const Images<double> base = render(d.arrays(), camera, T_cw, settings, 2, true);
  int stopped = 0;
  for (double a : base.alpha) stopped += a > 1 - 1e-3;
  ASSERT_GT(stopped, 50);

  std::vector<double> w_rgb(base.rgb.size()), w_depth(base.depth.size());
  for (double& w : w_rgb) w = uniform(rng, -1, 1);
  for (double& w : w_depth) w = uniform(rng, -1, 1);
  auto loss = [&](const Images<double>& im) {
    double s = 0;
    for (size_t i = 0; i < w_rgb.size(); ++i) s += w_rgb[i] * im.rgb[i];
    for (size_t i = 0; i < w_depth.size(); ++i) s += w_depth[i] * im.depth[i];
    return s;
  };
  const size_t n = d.size();
  std::vector<double> g_pos(3 * n, 0), g_ls(3 * n, 0), g_rot(4 * n, 0), g_op(n, 0), g_col(3 * n, 0);
  detail::AttributeGradients<double> grad{g_pos.data(), g_ls.data(), g_rot.data(), g_op.data(),
                                          g_col.data()};
  detail::ImageGradients<double> og;
  og.rgb = w_rgb.data();
  og.depth = w_depth.data();
  detail::cpu_backward(d.arrays(), camera, T_cw, settings, 2, *base.state, og, grad);
  std::vector<double>* params[] = {&d.position, &d.log_scale, &d.rotation, &d.opacity, &d.colour};
  const std::vector<double>* analytic[] = {&g_pos, &g_ls, &g_rot, &g_op, &g_col};
  for (int b = 0; b < 5; ++b) {
    double block_max = 0;
    for (double v : *analytic[b]) block_max = std::max(block_max, std::abs(v));
    for (int trial = 0; trial < 8; ++trial) {
      const size_t i = std::uniform_int_distribution<size_t>(0, params[b]->size() - 1)(rng);
      std::vector<double>& p = *params[b];
      const double x = p[i], eps = 1e-6;
      p[i] = x + eps;
      const double lp = loss(render(d.arrays(), camera, T_cw, settings, 2));
      p[i] = x - eps;
      const double lm = loss(render(d.arrays(), camera, T_cw, settings, 2));
      p[i] = x;
      const double numeric = (lp - lm) / (2 * eps), a = (*analytic[b])[i];
      EXPECT_LT(std::abs(a - numeric) / std::max({std::abs(numeric), 1e-3 * block_max, 1e-12}),
                1e-4)
          << "block " << b << " [" << i << "] analytic " << a << " numeric " << numeric;
    }
  }
}

// The float backend (make_cpu_rasteriser) agrees with the double core it is instantiated from.
TEST(RasteriserGradients, FloatMatchesDouble) {
  Fixture f = make_fixture(21, Output::kRgb);
  GaussianMap map;
  std::mt19937_64 rng(22);
  for (size_t i = 0; i < f.gaussians.size(); ++i) {
    GaussianInit g;
    for (int k = 0; k < 3; ++k) {
      g.position[k] = static_cast<float>(f.gaussians.position[3 * i + k]);
      g.log_scale[k] = static_cast<float>(f.gaussians.log_scale[3 * i + k]);
      g.colour[k] = static_cast<float>(f.gaussians.colour[3 * i + k]);
    }
    for (int k = 0; k < 4; ++k) g.rotation[k] = static_cast<float>(f.gaussians.rotation[4 * i + k]);
    g.opacity = static_cast<float>(f.gaussians.opacity[i]);
    g.object_id = f.gaussians.object_id[i];
    g.type = static_cast<GaussianType>(f.gaussians.type[i]);
    map.add(g);
  }
  // The double run on the float values, exactly.
  DoubleGaussians d;
  for (size_t i = 0; i < map.size(); ++i) {
    GaussianInit g;
    g.position = Eigen::Map<const Eigen::Vector3f>(map.positions().data() + 3 * i);
    g.log_scale = Eigen::Map<const Eigen::Vector3f>(map.log_scales().data() + 3 * i);
    g.rotation = Eigen::Map<const Eigen::Vector4f>(map.rotations().data() + 4 * i);
    g.colour = Eigen::Map<const Eigen::Vector3f>(map.colours().data() + 3 * i);
    g.object_id = map.object_ids_per_gaussian()[i];
    g.type = static_cast<GaussianType>(map.types()[i]);
    d.add(g, map.opacities()[i]);
  }
  auto rasteriser = make_cpu_rasteriser(2);
  RenderOutput out;
  std::unique_ptr<RenderState> state;
  rasteriser->forward(map, f.camera, f.T_cw, f.settings, &out, &state);
  const Images<double> ref = render(d.arrays(), f.camera, f.T_cw, f.settings, 1, true);
  for (size_t i = 0; i < out.rgb.size(); ++i) ASSERT_NEAR(out.rgb[i], ref.rgb[i], 2e-5);
  for (size_t i = 0; i < out.depth.size(); ++i) {
    ASSERT_NEAR(out.depth[i], ref.depth[i], 5e-5);
    ASSERT_NEAR(out.alpha[i], ref.alpha[i], 2e-5);
    ASSERT_NEAR(out.ins[i], ref.ins[i], 2e-5);
  }
  EXPECT_EQ(out.dominant_id, ref.dominant_id);

  OutputGradients og;
  og.rgb.resize(out.rgb.size());
  og.depth.resize(out.depth.size());
  og.ins.resize(out.ins.size());
  for (float& v : og.rgb) v = static_cast<float>(uniform(rng, -1, 1));
  for (float& v : og.depth) v = static_cast<float>(uniform(rng, -1, 1));
  for (float& v : og.ins) v = static_cast<float>(uniform(rng, -1, 1));
  MapGradients gm;
  rasteriser->backward(map, f.camera, f.T_cw, f.settings, *state, og, &gm);
  const std::vector<double> w_rgb(og.rgb.begin(), og.rgb.end()),
      w_depth(og.depth.begin(), og.depth.end()), w_ins(og.ins.begin(), og.ins.end());
  detail::ImageGradients<double> dg;
  dg.rgb = w_rgb.data();
  dg.depth = w_depth.data();
  dg.ins = w_ins.data();
  const size_t n = map.size();
  std::vector<double> g_pos(3 * n, 0), g_ls(3 * n, 0), g_rot(4 * n, 0), g_op(n, 0), g_col(3 * n, 0);
  detail::AttributeGradients<double> grad{g_pos.data(), g_ls.data(), g_rot.data(), g_op.data(),
                                          g_col.data()};
  detail::cpu_backward(d.arrays(), f.camera, f.T_cw, f.settings, 1, *ref.state, dg, grad);
  auto compare = [](const std::vector<float>& a, const std::vector<double>& b, const char* name) {
    double scale = 0.0;
    for (double v : b) scale = std::max(scale, std::abs(v));
    for (size_t i = 0; i < a.size(); ++i)
      EXPECT_NEAR(a[i], b[i], 1e-3 * scale) << name << "[" << i << "]";
  };
  compare(gm.position, g_pos, "position");
  compare(gm.log_scale, g_ls, "log_scale");
  compare(gm.rotation, g_rot, "rotation");
  compare(gm.opacity, g_op, "opacity");
  compare(gm.colour, g_col, "colour");
}

}  // namespace
}  // namespace dqo::gs
