// Losses: values against a direct computation, gradients against central finite differences
// (L1 terms away from their kinks, SSIM everywhere), masks.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>

#include "dqo_map/gaussians/losses.h"

namespace dqo::gs {
namespace {

RenderOutput random_output(int w, int h, std::mt19937* rng) {
  std::uniform_real_distribution<float> u(0.05f, 0.95f);
  RenderOutput out;
  out.width = w;
  out.height = h;
  const size_t n = static_cast<size_t>(w) * h;
  out.rgb.resize(3 * n);
  out.depth.resize(n);
  out.alpha.resize(n);
  out.ins.resize(n);
  out.dominant_id.assign(n, 0);
  for (float& v : out.rgb) v = u(*rng);
  for (float& v : out.depth) v = 0.5f + 2.f * u(*rng);
  for (float& v : out.alpha) v = u(*rng);
  for (float& v : out.ins) v = 1.4f * u(*rng);
  return out;
}

ImageF random_image(int w, int h, int c, std::mt19937* rng) {
  std::uniform_real_distribution<float> u(0.05f, 0.95f);
  ImageF img(w, h, c);
  for (float& v : img.data) v = u(*rng);
  return img;
}

PixelWeights random_weights(int w, int h, std::mt19937* rng) {
  std::uniform_real_distribution<float> u(0.f, 2.f);
  PixelWeights wt(static_cast<size_t>(w) * h);
  for (size_t p = 0; p < wt.size(); ++p) wt[p] = (p % 5 == 0) ? 0.f : u(*rng);  // a mask too
  return wt;
}

// Central differences of loss(out) with respect to every value of out.*field, compared with the
// analytic gradient in `analytic`. The step actually taken (after float rounding) divides the
// difference, so the check is not limited by float spacing.
void check_gradient(RenderOutput out, std::vector<float> RenderOutput::*field,
                    const std::vector<float>& analytic,
                    const std::function<double(const RenderOutput&)>& loss, double h,
                    double tolerance) {
  std::vector<float>& values = out.*field;
  ASSERT_EQ(values.size(), analytic.size());
  double max_abs = 0.0;
  for (const float g : analytic) max_abs = std::max(max_abs, std::abs(static_cast<double>(g)));
  for (size_t k = 0; k < values.size(); ++k) {
    const float x = values[k];
    const float xp = x + static_cast<float>(h), xm = x - static_cast<float>(h);
    values[k] = xp;
    const double lp = loss(out);
    values[k] = xm;
    const double lm = loss(out);
    values[k] = x;
    const double fd = (lp - lm) / (static_cast<double>(xp) - xm);
    EXPECT_NEAR(analytic[k], fd, tolerance * max_abs) << "element " << k;
  }
}

TEST(Losses, L1RgbValueAndGradient) {
  std::mt19937 rng(1);
  const int w = 9, h = 7;
  const RenderOutput out = random_output(w, h, &rng);
  const ImageF target = random_image(w, h, 3, &rng);
  const PixelWeights wt = random_weights(w, h, &rng);

  double num = 0.0, den = 0.0;
  for (size_t p = 0; p < wt.size(); ++p) {
    for (int c = 0; c < 3; ++c)
      num += wt[p] * std::abs(out.rgb[3 * p + c] - target.data[3 * p + c]);
    den += 3.0 * wt[p];
  }
  OutputGradients g;
  const double loss = l1_rgb_loss(out, target, wt, 2.0, &g);
  EXPECT_NEAR(loss, num / den, 1e-6);
  ASSERT_EQ(g.rgb.size(), out.rgb.size());
  EXPECT_TRUE(g.depth.empty());
  for (size_t p = 0; p < wt.size(); ++p) {
    if (wt[p] == 0.f) {
      EXPECT_EQ(g.rgb[3 * p], 0.f);
    }
  }
  check_gradient(
      out, &RenderOutput::rgb, g.rgb,
      [&](const RenderOutput& o) { return 2.0 * l1_rgb_loss(o, target, wt, 1.0, nullptr); }, 1e-3,
      1e-3);
}

TEST(Losses, GradientsAccumulate) {
  std::mt19937 rng(2);
  const RenderOutput out = random_output(6, 5, &rng);
  const ImageF target = random_image(6, 5, 3, &rng);
  OutputGradients once, twice;
  l1_rgb_loss(out, target, {}, 1.0, &once);
  l1_rgb_loss(out, target, {}, 0.5, &twice);
  l1_rgb_loss(out, target, {}, 0.5, &twice);
  for (size_t k = 0; k < once.rgb.size(); ++k) EXPECT_NEAR(once.rgb[k], twice.rgb[k], 1e-7);
}

TEST(Losses, L1DepthOnlyOnValidPixels) {
  std::mt19937 rng(3);
  const int w = 8, h = 6;
  const RenderOutput out = random_output(w, h, &rng);
  DepthImage target(w, h, 1);
  std::uniform_real_distribution<float> u(0.5f, 2.5f);
  for (size_t p = 0; p < target.data.size(); ++p) {
    target.data[p] = p % 7 == 0 ? 0.f : (p % 11 == 0 ? NAN : u(rng));
  }
  const PixelWeights wt = random_weights(w, h, &rng);
  double num = 0.0, den = 0.0;
  for (size_t p = 0; p < wt.size(); ++p) {
    if (!(target.data[p] > 0.f)) continue;
    num += wt[p] * std::abs(out.depth[p] - target.data[p]);
    den += wt[p];
  }
  OutputGradients g;
  const double loss = l1_depth_loss(out, target, wt, 1.0, &g);
  EXPECT_NEAR(loss, num / den, 1e-6);
  for (size_t p = 0; p < wt.size(); ++p) {
    if (!(target.data[p] > 0.f)) {
      EXPECT_EQ(g.depth[p], 0.f) << p;
    }
  }
  check_gradient(
      out, &RenderOutput::depth, g.depth,
      [&](const RenderOutput& o) { return l1_depth_loss(o, target, wt, 1.0, nullptr); }, 1e-3,
      1e-3);
}

TEST(Losses, InsAgainstObjectMask) {
  std::mt19937 rng(4);
  const int w = 8, h = 6;
  const RenderOutput out = random_output(w, h, &rng);
  ImageF mask(w, h, 1, 0.f);
  for (int y = 1; y < 4; ++y) {
    for (int x = 2; x < 6; ++x) mask.at(x, y) = 1.f;
  }
  double num = 0.0;
  for (size_t p = 0; p < mask.data.size(); ++p) {
    num += std::abs(std::min(out.ins[p], 1.f) - mask.data[p]);
  }
  OutputGradients g;
  const double loss = ins_loss(out, mask, {}, 0.3, &g);
  EXPECT_NEAR(loss, num / mask.data.size(), 1e-6);
  check_gradient(
      out, &RenderOutput::ins, g.ins,
      [&](const RenderOutput& o) { return 0.3 * ins_loss(o, mask, {}, 1.0, nullptr); }, 1e-3, 1e-3);
  // Zero weights everywhere: no loss and no gradient.
  OutputGradients none;
  EXPECT_EQ(ins_loss(out, mask, PixelWeights(mask.data.size(), 0.f), 1.0, &none), 0.0);
  EXPECT_TRUE(none.ins.empty());
}

// SSIM straight from its definition: every window sum written out, zero outside the image.
double ssim_reference(const RenderOutput& out, const ImageF& target, const PixelWeights& wt) {
  const int w = out.width, h = out.height;
  double g1[11], sum = 0.0;
  for (int i = -5; i <= 5; ++i) sum += g1[i + 5] = std::exp(-i * i / 4.5);
  for (double& v : g1) v /= sum;
  double total = 0.0, wsum = 0.0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double wp = wt.empty() ? 1.0 : wt[static_cast<size_t>(y) * w + x];
      wsum += wp;
      for (int c = 0; c < 3; ++c) {
        double mx = 0, my = 0, exx = 0, eyy = 0, exy = 0;
        for (int dy = -5; dy <= 5; ++dy) {
          for (int dx = -5; dx <= 5; ++dx) {
            const int xx = x + dx, yy = y + dy;
            if (xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
            const double k = g1[dx + 5] * g1[dy + 5];
            const size_t q = 3 * (static_cast<size_t>(yy) * w + xx) + c;
            const double a = out.rgb[q], b = target.data[q];
            mx += k * a, my += k * b, exx += k * a * a, eyy += k * b * b, exy += k * a * b;
          }
        }
        const double C1 = 1e-4, C2 = 9e-4;
        const double s = (2 * mx * my + C1) * (2 * (exy - mx * my) + C2) /
                         ((mx * mx + my * my + C1) * (exx - mx * mx + eyy - my * my + C2));
        total += wp * s;
      }
    }
  }
  return 1.0 - total / (3.0 * wsum);
}

TEST(Losses, SsimValueAndGradient) {
  std::mt19937 rng(5);
  const int w = 14, h = 12;  // larger than the window, so interior and border pixels both occur
  RenderOutput out = random_output(w, h, &rng);
  const ImageF target = random_image(w, h, 3, &rng);
  // Correlate the render with the target a little, as a real render is.
  for (size_t k = 0; k < out.rgb.size(); ++k)
    out.rgb[k] = 0.5f * out.rgb[k] + 0.5f * target.data[k];
  const PixelWeights wt = random_weights(w, h, &rng);

  OutputGradients g;
  const double loss = ssim_loss(out, target, wt, 1.0, &g);
  EXPECT_NEAR(loss, ssim_reference(out, target, wt), 1e-9);
  EXPECT_GT(loss, 0.0);
  check_gradient(
      out, &RenderOutput::rgb, g.rgb,
      [&](const RenderOutput& o) { return ssim_loss(o, target, wt, 1.0, nullptr); }, 1e-3, 2e-3);

  // Identical images: SSIM 1, loss 0.
  RenderOutput same = out;
  same.rgb = target.data;
  EXPECT_NEAR(ssim_loss(same, target, {}, 1.0, nullptr), 0.0, 1e-9);
}

TEST(Losses, FloatRgb) {
  ImageRgb8 rgb(2, 1, 3);
  rgb.data = {0, 51, 255, 255, 0, 102};
  const ImageF f = to_float_rgb(rgb);
  EXPECT_FLOAT_EQ(f.data[1], 0.2f);
  EXPECT_FLOAT_EQ(f.data[2], 1.f);
  EXPECT_FLOAT_EQ(f.data[5], 0.4f);
}

}  // namespace
}  // namespace dqo::gs
