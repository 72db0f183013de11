#pragma once
// Stage: front-to-back alpha compositing of one pixel, one Gaussian at a time, and its reverse.
//
// Forward, Gaussians i = 0, 1, ... in depth order, T_0 = 1:
//   C = Σ T_i α_i c_i + T_N bg,  D = Σ T_i α_i z_i,  A = 1 − T_N,  T_{i+1} = T_i (1 − α_i),
// stopping (before Gaussian i contributes) once T_i (1 − α_i) < 1e-4, as 3DGS does.
// Backward, back to front from T_N: T_i = T_{i+1} / (1 − α_i) and, with the after-sums
// C_>i = Σ_{j>i} T_j α_j c_j and D_>i likewise,
//   ∂C/∂α_i = T_i c_i − (C_>i + T_N bg) / (1 − α_i),  ∂D/∂α_i = T_i z_i − D_>i / (1 − α_i),
//   ∂A/∂α_i = T_N / (1 − α_i),  ∂C/∂c_i = T_i α_i,  ∂D/∂z_i = T_i α_i.

#include "dqo_map/gaussians/math/types.h"

namespace dqo::gs {

constexpr float kTransmittanceMin = 1e-4f;

template <typename T>
struct PixelAccum {
  T transmittance;  // T before the next Gaussian
  Vec3<T> rgb;      // Σ T α c so far
  T depth;          // Σ T α z so far
};

template <typename T>
DQO_HD PixelAccum<T> pixel_accum_start() {
  return {T(1), {T(0), T(0), T(0)}, T(0)};
}

// Returns false (and leaves *acc alone) where this Gaussian would take T below 1e-4: the pixel is
// finished and neither this Gaussian nor any later one contributes.
template <typename T>
DQO_HD bool composite_step(T alpha,                // input
                           const Vec3<T>& colour,  // input
                           T z,                    // input, camera-frame depth of the mean
                           PixelAccum<T>* acc      // input and output
) {
  const T next = acc->transmittance * (T(1) - alpha);
  if (next < T(kTransmittanceMin)) return false;
  const T w = acc->transmittance * alpha;
  acc->rgb += w * colour;
  acc->depth += w * z;
  acc->transmittance = next;
  return true;
}

// The backward walk's state: T after the current Gaussian and the after-sums.
template <typename T>
struct PixelAccumBack {
  T transmittance;  // starts at T_N, ends at 1
  Vec3<T> rgb_after;
  T depth_after;
};

template <typename T>
DQO_HD PixelAccumBack<T> pixel_accum_back_start(T t_final) {
  return {t_final, {T(0), T(0), T(0)}, T(0)};
}

// One step back to front, for a Gaussian that contributed. Returns dL/dα_i; v_colour and v_z get
// dL/dc_i and dL/dz_i added.
template <typename T>
DQO_HD T composite_step_vjp(T alpha,                    // input
                            const Vec3<T>& colour,      // input
                            T z,                        // input
                            T t_final,                  // input: T_N
                            const Vec3<T>& background,  // input
                            const Vec3<T>& v_rgb,       // output gradient dL/dC
                            T v_depth,                  // output gradient dL/dD
                            T v_accum_alpha,            // output gradient dL/dA
                            PixelAccumBack<T>* back,    // input and output
                            Vec3<T>* v_colour,          // accumulated gradient
                            T* v_z                      // accumulated gradient
) {
  const T r = T(1) / (T(1) - alpha);
  const T t_i = back->transmittance * r;
  const T w = t_i * alpha;
  *v_colour += w * v_rgb;
  *v_z += w * v_depth;
  const Vec3<T> after = back->rgb_after + t_final * background;
  const T v_alpha = dot(v_rgb, t_i * colour - r * after) +
                    v_depth * (t_i * z - r * back->depth_after) + v_accum_alpha * t_final * r;
  back->rgb_after += w * colour;
  back->depth_after += w * z;
  back->transmittance = t_i;
  return v_alpha;
}

}  // namespace dqo::gs
