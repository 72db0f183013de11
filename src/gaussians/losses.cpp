#include "dqo_map/gaussians/losses.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>

namespace dqo::gs {
namespace {

float sign_of(float x) { return x > 0.f ? 1.f : (x < 0.f ? -1.f : 0.f); }

float weight_at(const PixelWeights& w, size_t p) { return w.empty() ? 1.f : w[p]; }

void ensure_size(std::vector<float>* v, size_t n) {
  if (v->size() != n) v->assign(n, 0.f);
}

// The 11-tap Gaussian of 3DGS's SSIM (σ = 1.5), normalised to sum 1.
constexpr int kRadius = 5;
std::array<double, 2 * kRadius + 1> gaussian_taps() {
  std::array<double, 2 * kRadius + 1> t{};
  double sum = 0.0;
  for (int i = -kRadius; i <= kRadius; ++i) {
    t[i + kRadius] = std::exp(-(i * i) / (2.0 * 1.5 * 1.5));
    sum += t[i + kRadius];
  }
  for (double& v : t) v /= sum;
  return t;
}

// Separable correlation with the symmetric window, zero outside the image. The window being
// symmetric, this operator is its own transpose: the backward pass reuses it.
void blur(const std::vector<double>& in, int w, int h, std::vector<double>* out) {
  static const auto taps = gaussian_taps();
  std::vector<double> tmp(in.size(), 0.0);
  for (int y = 0; y < h; ++y) {
    const double* row = in.data() + static_cast<size_t>(y) * w;
    double* dst = tmp.data() + static_cast<size_t>(y) * w;
    for (int x = 0; x < w; ++x) {
      double s = 0.0;
      for (int k = -kRadius; k <= kRadius; ++k) {
        const int xx = x + k;
        if (xx >= 0 && xx < w) s += taps[k + kRadius] * row[xx];
      }
      dst[x] = s;
    }
  }
  out->assign(in.size(), 0.0);
  for (int y = 0; y < h; ++y) {
    double* dst = out->data() + static_cast<size_t>(y) * w;
    for (int k = -kRadius; k <= kRadius; ++k) {
      const int yy = y + k;
      if (yy < 0 || yy >= h) continue;
      const double t = taps[k + kRadius];
      const double* src = tmp.data() + static_cast<size_t>(yy) * w;
      for (int x = 0; x < w; ++x) dst[x] += t * src[x];
    }
  }
}

}  // namespace

ImageF to_float_rgb(const ImageRgb8& rgb) {
  ImageF out(rgb.width, rgb.height, rgb.channels);
  for (size_t i = 0; i < rgb.data.size(); ++i) out.data[i] = unit_colour(rgb.data[i]);
  return out;
}

double l1_rgb_loss(const RenderOutput& out, const ImageF& target, const PixelWeights& weights,
                   double lambda, OutputGradients* grad) {
  const size_t n = static_cast<size_t>(out.width) * out.height;
  double wsum = 0.0;
  for (size_t p = 0; p < n; ++p) wsum += weight_at(weights, p);
  if (wsum <= 0.0) return 0.0;
  double loss = 0.0;
  const double norm = 1.0 / (3.0 * wsum);
  if (grad) ensure_size(&grad->rgb, 3 * n);
  for (size_t p = 0; p < n; ++p) {
    const float w = weight_at(weights, p);
    if (w == 0.f) continue;
    for (int c = 0; c < 3; ++c) {
      const float d = out.rgb[3 * p + c] - target.data[3 * p + c];
      loss += w * std::abs(d);
      if (grad) grad->rgb[3 * p + c] += static_cast<float>(lambda * norm * w) * sign_of(d);
    }
  }
  return loss * norm;
}

double l1_depth_loss(const RenderOutput& out, const DepthImage& target, const PixelWeights& weights,
                     double lambda, OutputGradients* grad) {
  const size_t n = static_cast<size_t>(out.width) * out.height;
  double wsum = 0.0;
  for (size_t p = 0; p < n; ++p) {
    const float d = target.data[p];
    if (std::isfinite(d) && d > 0.f) wsum += weight_at(weights, p);
  }
  if (wsum <= 0.0) return 0.0;
  if (grad) ensure_size(&grad->depth, n);
  double loss = 0.0;
  const double norm = 1.0 / wsum;
  for (size_t p = 0; p < n; ++p) {
    const float d = target.data[p];
    const float w = weight_at(weights, p);
    if (!(std::isfinite(d) && d > 0.f) || w == 0.f) continue;
    const float e = out.depth[p] - d;
    loss += w * std::abs(e);
    if (grad) grad->depth[p] += static_cast<float>(lambda * norm * w) * sign_of(e);
  }
  return loss * norm;
}

double ins_loss(const RenderOutput& out, const ImageF& target_mask, const PixelWeights& weights,
                double lambda, OutputGradients* grad) {
  const size_t n = static_cast<size_t>(out.width) * out.height;
  double wsum = 0.0;
  for (size_t p = 0; p < n; ++p) wsum += weight_at(weights, p);
  if (wsum <= 0.0) return 0.0;
  if (grad) ensure_size(&grad->ins, n);
  double loss = 0.0;
  const double norm = 1.0 / wsum;
  for (size_t p = 0; p < n; ++p) {
    const float w = weight_at(weights, p);
    if (w == 0.f) continue;
    // ins is a sum of alphas, unbounded above: a pixel with ins >= 1 is fully covered.
    const float ins = std::min(out.ins[p], 1.f);
    const float e = ins - target_mask.data[p];
    loss += w * std::abs(e);
    if (grad && out.ins[p] < 1.f)
      grad->ins[p] += static_cast<float>(lambda * norm * w) * sign_of(e);
  }
  return loss * norm;
}

// SSIM per pixel and channel, from local means μ, second moments E and the cross moment of the
// render x and the target y (σ² = E[x²] − μ², σ_xy = E[xy] − μ_x μ_y):
//   S = A B / (C D),  A = 2 μx μy + C1, B = 2 σxy + C2, C = μx² + μy² + C1, D = σx² + σy² + C2.
// With the target fixed, S depends on x through μx, E[x²] and E[xy]:
//   ∂S/∂μx   = S (2μy/A − 2μy/B − 2μx/C + 2μx/D),  ∂S/∂E[x²] = −S/D,  ∂S/∂E[xy] = 2S/B,
// and each of those is a blur G of x, x², x·y, so with g_p = dL/dS_p
//   dL/dx_q = (Gᵀ a)_q + 2 x_q (Gᵀ b)_q + y_q (Gᵀ c)_q,  a = g ∂S/∂μx, b = g ∂S/∂E[x²], c = g
//   ∂S/∂E[xy].
double ssim_loss(const RenderOutput& out, const ImageF& target, const PixelWeights& weights,
                 double lambda, OutputGradients* grad) {
  constexpr double kC1 = 0.01 * 0.01;
  constexpr double kC2 = 0.03 * 0.03;
  const int w = out.width, h = out.height;
  const size_t n = static_cast<size_t>(w) * h;
  double wsum = 0.0;
  for (size_t p = 0; p < n; ++p) wsum += weight_at(weights, p);
  if (wsum <= 0.0) return 0.0;
  if (grad) ensure_size(&grad->rgb, 3 * n);

  std::vector<double> x(n), y(n), xx(n), yy(n), xy(n);
  std::vector<double> mx, my, exx, eyy, exy;
  std::vector<double> a(n), b(n), c(n), ga, gb, gc;
  double total = 0.0;
  for (int ch = 0; ch < 3; ++ch) {
    for (size_t p = 0; p < n; ++p) {
      x[p] = out.rgb[3 * p + ch];
      y[p] = target.data[3 * p + ch];
      xx[p] = x[p] * x[p];
      yy[p] = y[p] * y[p];
      xy[p] = x[p] * y[p];
    }
    blur(x, w, h, &mx);
    blur(y, w, h, &my);
    blur(xx, w, h, &exx);
    blur(yy, w, h, &eyy);
    blur(xy, w, h, &exy);
    for (size_t p = 0; p < n; ++p) {
      const double A = 2.0 * mx[p] * my[p] + kC1;
      const double B = 2.0 * (exy[p] - mx[p] * my[p]) + kC2;
      const double C = mx[p] * mx[p] + my[p] * my[p] + kC1;
      const double D = (exx[p] - mx[p] * mx[p]) + (eyy[p] - my[p] * my[p]) + kC2;
      const double S = A * B / (C * D);
      const double wp = weight_at(weights, p);
      total += wp * S;
      const double g = -lambda * wp / (3.0 * wsum);
      a[p] = g * S * (2.0 * my[p] / A - 2.0 * my[p] / B - 2.0 * mx[p] / C + 2.0 * mx[p] / D);
      b[p] = g * (-S / D);
      c[p] = g * (2.0 * S / B);
    }
    if (!grad) continue;
    blur(a, w, h, &ga);
    blur(b, w, h, &gb);
    blur(c, w, h, &gc);
    for (size_t p = 0; p < n; ++p) {
      grad->rgb[3 * p + ch] += static_cast<float>(ga[p] + 2.0 * x[p] * gb[p] + y[p] * gc[p]);
    }
  }
  return 1.0 - total / (3.0 * wsum);
}

}  // namespace dqo::gs
