#pragma once
// Photometric, geometric and instance losses of the incremental update (METHOD.md §4):
//   L = L_rgb + λ_d L_depth + λ_ins L_ins  (+ an optional SSIM term),
// each a function of one RenderOutput and its target, returning the loss and *adding*
// `lambda` · dL/d(output) to an OutputGradients (sized on first use), so that terms combine by
// calling them one after another and the sum goes to Rasteriser::backward() once.
//
// Every loss takes per-pixel weights (width·height values ≥ 0, empty = 1 everywhere): a mask is a
// weight of 0 or 1. Means are weighted means: Σ w·term / Σ w, so a loss keeps its scale whatever
// the mask; a loss whose weights sum to 0 is 0 and adds no gradient.
//
// The derivative of |x| at 0 is taken as 0.

#include <vector>

#include "dqo_map/common/image.h"
#include "dqo_map/gaussians/rasteriser.h"

namespace dqo::gs {

using ImageF = Image<float>;
using PixelWeights = std::vector<float>;

// One 8-bit channel in [0, 1]: the float every colour of the map and the losses starts from.
inline float unit_colour(uint8_t v) { return v * (1.f / 255.f); }
// RGB8 to float RGB in [0, 1] (unit_colour), same layout.
ImageF to_float_rgb(const ImageRgb8& rgb);

// L1 over the colour channels: Σ_p w_p Σ_c |r̂_pc − r_pc| / (3 Σ_p w_p). `target` has 3 channels.
double l1_rgb_loss(const RenderOutput& out, const ImageF& target, const PixelWeights& weights,
                   double lambda, OutputGradients* grad);

// L1 on depth (metres) over pixels with a valid measurement (finite and > 0):
// Σ_valid w_p |d̂_p − d_p| / Σ_valid w_p.
double l1_depth_loss(const RenderOutput& out, const DepthImage& target, const PixelWeights& weights,
                     double lambda, OutputGradients* grad);

// L_ins: L1 between the rendered instance opacity `ins` of the object the render was made for
// (RenderSettings::ins_object) and that object's target mask (1 on its pixels, 0 elsewhere; one
// channel, values in [0, 1]): Σ_p w_p |min(îns_p, 1) − m_p| / Σ_p w_p. îns is a sum of alphas
// (METHOD.md §4), unbounded above; where it reaches 1 the pixel counts as covered, so the loss asks
// the object to cover its mask and to stay out of the rest, not to thin out where its Gaussians
// overlap.
double ins_loss(const RenderOutput& out, const ImageF& target_mask, const PixelWeights& weights,
                double lambda, OutputGradients* grad);

// 1 − SSIM over the colour channels, with the 11×11 Gaussian window (σ = 1.5) of 3DGS, zero padding
// at the border, C1 = 0.01², C2 = 0.03²: L = 1 − Σ_p w_p mean_c S_pc / Σ_p w_p.
double ssim_loss(const RenderOutput& out, const ImageF& target, const PixelWeights& weights,
                 double lambda, OutputGradients* grad);

}  // namespace dqo::gs
