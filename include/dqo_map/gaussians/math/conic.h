#pragma once
// Stage: the 2D covariance's inverse (the "conic" that the per-pixel alpha evaluates) and the
// screen-space radius (3σ along the major axis) that bins the Gaussian into tiles.

#include "dqo_map/gaussians/math/types.h"

namespace dqo::gs {

// Returns false (and leaves *conic alone) where Σ_2D is not positive definite.
template <typename T>
DQO_HD bool conic_from_covariance(const Sym2<T>& cov2d,  // input, low-pass included
                                  Sym2<T>* conic         // output
) {
  const T det = cov2d.xx * cov2d.yy - cov2d.xy * cov2d.xy;
  if (!(det > T(0)) || !(cov2d.xx > T(0))) return false;
  const T inv = T(1) / det;
  *conic = {cov2d.yy * inv, -cov2d.xy * inv, cov2d.xx * inv};
  return true;
}

// C = Σ⁻¹: dΣ = −C G_C C with G_C the full-matrix gradient of C (xy gradient split in halves), and
// back to Sym2 (xy gradient = both off-diagonal entries).
template <typename T>
DQO_HD void conic_from_covariance_vjp(const Sym2<T>& conic,    // input (the forward's output)
                                      const Sym2<T>& v_conic,  // output gradient
                                      Sym2<T>* v_cov2d         // accumulated gradient
) {
  const T a = conic.xx, b = conic.xy, c = conic.yy;
  const T ga = v_conic.xx, gb = T(0.5) * v_conic.xy, gc = v_conic.yy;
  // G_C C, then C (G_C C).
  const T m00 = ga * a + gb * b, m01 = ga * b + gb * c;
  const T m10 = gb * a + gc * b, m11 = gb * b + gc * c;
  const T r00 = a * m00 + b * m10, r01 = a * m01 + b * m11;
  const T r10 = b * m00 + c * m10, r11 = b * m01 + c * m11;
  v_cov2d->xx -= r00;
  v_cov2d->xy -= r01 + r10;
  v_cov2d->yy -= r11;
}

// ceil(3 sqrt(λ_max)) in pixels, λ_max the larger eigenvalue of Σ_2D (floored as 3DGS does, so
// that a degenerate splat still gets a radius).
template <typename T>
DQO_HD int radius_3sigma(const Sym2<T>& cov2d) {
  const T det = cov2d.xx * cov2d.yy - cov2d.xy * cov2d.xy;
  const T mid = T(0.5) * (cov2d.xx + cov2d.yy);
  const T lambda_max = mid + hd_sqrt(hd_max(T(0.1), mid * mid - det));
  return static_cast<int>(hd_ceil(T(3) * hd_sqrt(lambda_max)));
}

}  // namespace dqo::gs
