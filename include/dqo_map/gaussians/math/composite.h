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

#include <cstdint>

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

// Stage: the depth of the surface a pixel sees (RenderSettings::surface_depth).
//
// The alpha-weighted depth, normalised or not, averages every surface on the pixel: at a
// silhouette the foreground's fringe and the background behind it give a depth in between, off
// both by a fraction of the jump (on `tabletop` the 2 % of pixels at depth edges gave a sixth of
// the depth L1). So the contributors, in depth order, are split into runs wherever the next one
// lies more than gap = max(gap_abs, gap_rel · z) behind the previous one (a surface's own
// Gaussians overlap in depth; a jump between surfaces leaves a gap). The surface is the run in which the pixel's
// accumulated alpha reaches ½, or the last run where it never does, and its depth is
//   D = Σ_{i∈run} t_i α_i z_i / Σ_{i∈run} t_i α_i,   t_i = Π_{j∈run, j<i} (1 − α_j).
// The transmittance in front of the run is a common factor of numerator and denominator and
// cancels: D depends on the run's members only, and on one surface it is the normalised depth.
// Backward, with W = Σ t_i α_i and the after-sum E_>i = Σ_{j∈run, j>i} t_j α_j (z_j − D):
//   ∂D/∂z_i = t_i α_i / W,   ∂D/∂α_i = (t_i (z_i − D) − E_>i / (1 − α_i)) / W.
// Which Gaussians form the run is piecewise constant in the parameters (like the 1/255 cut-off).
template <typename T>
struct SurfaceAccum {
  T weight;         // Σ t α over the run so far
  T depth;          // Σ t α z over the run so far
  T transmittance;  // t after the run's last member so far
  T last_z;         // depth of the previous contributor
  uint32_t first;   // list position (1-based) of the run's first member; 0: no run yet
  uint32_t last;    // list position of its last member
  bool reached;     // the accumulated alpha reached ½ within the run: it is the surface
  bool closed;      // a gap followed the surface: nothing more joins it
};

template <typename T>
DQO_HD SurfaceAccum<T> surface_accum_start() {
  return {T(0), T(0), T(1), T(0), 0u, 0u, false, false};
}

// For a Gaussian that contributed (composite_step returned true), in the same order.
template <typename T>
DQO_HD void surface_step(T alpha,                // input
                         T z,                    // input, camera-frame depth of the mean
                         T transmittance_after,  // input: the pixel's T after this Gaussian
                         T gap_abs, T gap_rel,   // input: the gap that separates surfaces
                         uint32_t position,      // input: 1-based position in the depth order
                         SurfaceAccum<T>* s      // input and output
) {
  if (s->closed) return;
  if (s->first != 0 && z - s->last_z > hd_max(gap_abs, gap_rel * s->last_z)) {
    if (s->reached) {
      s->closed = true;
      return;
    }
    *s = surface_accum_start<T>();  // the run in front was a fringe: a new surface starts
  }
  if (s->first == 0) s->first = position;
  const T w = s->transmittance * alpha;
  s->weight += w;
  s->depth += w * z;
  s->transmittance *= T(1) - alpha;
  s->last = position;
  s->last_z = z;
  if (transmittance_after <= T(0.5)) s->reached = true;
}

// D, or 0 where nothing contributed.
template <typename T>
DQO_HD T surface_depth(const SurfaceAccum<T>& s) {
  return s.weight > T(0) ? s.depth / s.weight : T(0);
}

// The backward walk over the run's members, back to front.
template <typename T>
struct SurfaceBack {
  T transmittance;  // t after the current member; starts at the run's final t
  T after;          // E_>i
};

template <typename T>
DQO_HD SurfaceBack<T> surface_back_start(const SurfaceAccum<T>& s) {
  return {s.transmittance, T(0)};
}

// One member, back to front. Returns dL/dα_i; v_z gets dL/dz_i added. d = D, v_depth = dL/dD,
// weight = W of the forward pass.
template <typename T>
DQO_HD T surface_step_vjp(T alpha,               // input
                          T z,                   // input
                          T d,                   // input: the surface depth D
                          T weight,              // input: W
                          T v_depth,             // output gradient dL/dD
                          SurfaceBack<T>* back,  // input and output
                          T* v_z                 // accumulated gradient
) {
  const T r = T(1) / (T(1) - alpha);
  const T t_i = back->transmittance * r;
  const T w = t_i * alpha;
  const T g = v_depth / weight;
  *v_z += w * g;
  const T v_alpha = g * (t_i * (z - d) - r * back->after);
  back->after += w * (z - d);
  back->transmittance = t_i;
  return v_alpha;
}

}  // namespace dqo::gs
