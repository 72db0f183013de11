#pragma once
// Stage: a Gaussian's alpha at one pixel, α = min(0.99, o · exp(−½ dᵀ Σ⁻¹ d)), d = mean − pixel,
// skipped (contributes nothing) below 1/255, as in 3DGS. The 0.99 cap keeps 1 − α invertible for
// the backward pass; where it is active, α does not depend on the Gaussian and the gradient is
// zero.

#include "dqo_map/gaussians/math/types.h"

namespace dqo::gs {

constexpr float kAlphaMax = 0.99f;
constexpr float kAlphaMin = 1.0f / 255.0f;

// −½ dᵀ C d with C = conic.
template <typename T>
DQO_HD T gaussian_power(const Sym2<T>& conic, const Vec2<T>& mean2d, T px, T py) {
  const T dx = mean2d.x - px, dy = mean2d.y - py;
  return T(-0.5) * (conic.xx * dx * dx + conic.yy * dy * dy) - conic.xy * dx * dy;
}

// Returns false where the Gaussian is skipped at this pixel (power > 0 from round-off, or
// α < 1/255); *alpha and *vis are set only when true.
template <typename T>
DQO_HD bool evaluate_alpha(const Sym2<T>& conic,   // input
                           const Vec2<T>& mean2d,  // input, pixels
                           T opacity,              // input
                           T px, T py,             // input: pixel centre
                           T* alpha,               // output
                           T* vis                  // output: exp(power), for the VJP
) {
  const T power = gaussian_power(conic, mean2d, px, py);
  if (power > T(0)) return false;
  const T g = hd_exp(power);
  const T a = hd_min(T(kAlphaMax), opacity * g);
  if (a < T(kAlphaMin)) return false;
  *alpha = a;
  *vis = g;
  return true;
}

// For a pixel where evaluate_alpha returned true; `vis` is its output.
template <typename T>
DQO_HD void evaluate_alpha_vjp(const Sym2<T>& conic,   // input
                               const Vec2<T>& mean2d,  // input
                               T opacity,              // input
                               T px, T py,             // input
                               T vis,                  // input: exp(power) from the forward
                               T v_alpha,              // output gradient
                               Sym2<T>* v_conic,       // accumulated gradient
                               Vec2<T>* v_mean2d,      // accumulated gradient
                               T* v_opacity            // accumulated gradient
) {
  if (opacity * vis > T(kAlphaMax)) return;  // capped: flat
  const T dx = mean2d.x - px, dy = mean2d.y - py;
  *v_opacity += vis * v_alpha;
  const T v_power = opacity * vis * v_alpha;
  v_conic->xx += T(-0.5) * dx * dx * v_power;
  v_conic->xy += -dx * dy * v_power;
  v_conic->yy += T(-0.5) * dy * dy * v_power;
  v_mean2d->x += -(conic.xx * dx + conic.xy * dy) * v_power;
  v_mean2d->y += -(conic.yy * dy + conic.xy * dx) * v_power;
}

// Half-extents (pixels) of the ellipse outside which α < 1/255 for sure: dᵀ C d ≤ k with
// k = 2 ln(255 o) has |dx| ≤ sqrt(k Σxx), |dy| ≤ sqrt(k Σyy). Lets a CPU loop skip pixels without
// evaluating exp; it changes no result (the 1/255 test still decides). Returns false when the
// Gaussian can never reach 1/255.
template <typename T>
DQO_HD bool alpha_extent(const Sym2<T>& cov2d,  // input, low-pass included
                         T opacity,             // input
                         Vec2<T>* half_extent   // output
) {
  if (!(opacity * T(255) > T(1))) return false;
  const T k = T(2) * hd_log(opacity * T(255));
  // A relative margin and a small absolute one cover the round-off of the conic's inversion.
  half_extent->x = hd_sqrt(k * cov2d.xx) * T(1.001) + T(0.01);
  half_extent->y = hd_sqrt(k * cov2d.yy) * T(1.001) + T(0.01);
  return true;
}

// The least of q(a, b) = caa a² + 2 cab a b + cbb b² over b in [b0, b1] at a fixed a (cbb > 0),
// and the sum of its terms' magnitudes there (for a round-off margin).
template <typename T>
DQO_HD T quadratic_min_on_segment(T caa, T cab, T cbb, T a, T b0, T b1, T* magnitude) {
  const T b = hd_min(hd_max(-cab * a / cbb, b0), b1);
  *magnitude = hd_abs(caa) * a * a + T(2) * hd_abs(cab * a * b) + hd_abs(cbb) * b * b;
  return caa * a * a + T(2) * cab * a * b + cbb * b * b;
}

// Whether α can reach 1/255 anywhere in the rectangle [x0, x1] × [y0, y1] of pixel centres (a
// tile's): the least of dᵀ C d over it (a convex quadratic: zero where the rectangle holds the
// mean, else on one of its edges) against k = 2 ln(255 o), with margins wider than the round-off
// of both. Conservative: where it says no, no pixel centre of the rectangle passes
// evaluate_alpha(), so binning a Gaussian only into the tiles its ellipse reaches (rather than
// every tile of its square) changes no pixel and saves the visits (issue 12: exact ellipse–tile
// overlap).
template <typename T>
DQO_HD bool ellipse_reaches_rect(const Sym2<T>& conic, const Vec2<T>& mean2d, T opacity, T x0, T y0, T x1, T y1) {
  if (!(opacity * T(255) > T(1))) return false;
  if (!(conic.xx > T(0)) || !(conic.yy > T(0))) return true;  // not an ellipse: keep (never here)
  const T dx0 = x0 - mean2d.x, dx1 = x1 - mean2d.x, dy0 = y0 - mean2d.y, dy1 = y1 - mean2d.y;
  if (dx0 <= T(0) && dx1 >= T(0) && dy0 <= T(0) && dy1 >= T(0)) return true;
  T m0, m1, m2, m3;
  const T q0 = quadratic_min_on_segment(conic.xx, conic.xy, conic.yy, dx0, dy0, dy1, &m0);
  const T q1 = quadratic_min_on_segment(conic.xx, conic.xy, conic.yy, dx1, dy0, dy1, &m1);
  const T q2 = quadratic_min_on_segment(conic.yy, conic.xy, conic.xx, dy0, dx0, dx1, &m2);
  const T q3 = quadratic_min_on_segment(conic.yy, conic.xy, conic.xx, dy1, dx0, dx1, &m3);
  const T k = T(2) * hd_log(opacity * T(255));
  const T margin = k * T(1e-3) + T(1e-4) * hd_max(hd_max(m0, m1), hd_max(m2, m3)) + T(0.01);
  return hd_min(hd_min(q0, q1), hd_min(q2, q3)) <= k + margin;
}

// The x-interval [*dx_lo, *dx_hi] of offsets d.x = mean.x − px where the power at offset d.y
// reaches min_power (< 0): a dx² + 2 b dy dx + c dy² ≤ −2 min_power. Returns false where the row
// misses the ellipse. A CPU loop uses it to visit only the pixels of a row that can pass.
template <typename T>
DQO_HD bool power_row_span(const Sym2<T>& conic, T dy, T min_power, T* dx_lo, T* dx_hi) {
  const T bdy = conic.xy * dy;
  const T disc = bdy * bdy - conic.xx * (conic.yy * dy * dy + T(2) * min_power);
  if (disc < T(0)) return false;
  const T root = hd_sqrt(disc);
  *dx_lo = (-bdy - root) / conic.xx;
  *dx_hi = (-bdy + root) / conic.xx;
  return true;
}

}  // namespace dqo::gs
