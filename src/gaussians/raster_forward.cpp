// Stage 3 of the CPU rasteriser: per tile, front-to-back compositing with early stop.
//
// The GPU composites pixel by pixel over the tile's list; here the loops are swapped: each Gaussian
// of the depth-ordered list visits, row by row, only the still-open pixels of the tile that its
// ellipse (α ≥ 1/255) can reach (a 16-bit mask per row). Every pixel still sees its Gaussians in
// the same order, so its result is the same, while most (pixel, Gaussian) pairs are never touched.
// Tiles are independent: threads take them one at a time.

#include "dqo_map/gaussians/math/composite.h"
#include "raster_internal.h"

namespace dqo::gs::detail {

namespace {

template <typename S>
struct TileForward {
  PixelAccum<S> acc[kTilePixels];
  S ins[kTilePixels];
  uint32_t ins_label[kTilePixels];  // settings.ins_labels of the tile's pixels
  S best_weight[kTilePixels];
  uint32_t best_id[kTilePixels];
  uint32_t n_contrib[kTilePixels];
  SurfaceAccum<S> surface[kTilePixels];
};

template <typename S>
void composite_tile(const RenderSettings& settings, size_t tile, const ImageBuffers<S>& out,
                    CpuRenderState<S>* state, TileForward<S>* tf) {
  const std::vector<Splat<S>>& splats = state->projected.splats;
  const TileBins& bins = state->bins;
  const int width = state->width, height = state->height;
  const int tx0 = static_cast<int>(tile % bins.tiles_x) * kTileSize;
  const int ty0 = static_cast<int>(tile / bins.tiles_x) * kTileSize;
  const int tx1 = std::min(tx0 + kTileSize, width) - 1;
  const int ty1 = std::min(ty0 + kTileSize, height) - 1;

  for (int p = 0; p < kTilePixels; ++p) {
    tf->acc[p] = pixel_accum_start<S>();
    tf->ins[p] = S(0);
    tf->best_weight[p] = S(0);
    tf->best_id[p] = 0;
    tf->n_contrib[p] = 0;
    tf->surface[p] = surface_accum_start<S>();
  }
  const uint32_t* labels = settings.ins_labels;
  if (labels)
    for (int y = ty0; y <= ty1; ++y)
      for (int x = tx0; x <= tx1; ++x)
        tf->ins_label[(y - ty0) * kTileSize + (x - tx0)] = labels[static_cast<size_t>(y) * width + x];
  const bool surface = settings.surface_depth;
  const S gap_abs = S(settings.surface_gap), gap_rel = S(settings.surface_gap_relative);
  uint32_t open[kTileSize];  // pixels not finished by the early stop
  for (int r = 0; r < kTileSize; ++r) open[r] = ty0 + r <= ty1 ? (2u << (tx1 - tx0)) - 1u : 0u;
  int n_open = (tx1 - tx0 + 1) * (ty1 - ty0 + 1);

  const uint32_t begin = bins.offsets[tile], end = bins.offsets[tile + 1];
  for (uint32_t k = begin; k < end && n_open > 0; ++k) {
    const Splat<S>& s = splats[bins.ids[k]];
    const int y0 = std::max<int>(s.y0, ty0), y1 = std::min<int>(s.y1, ty1);
    const uint32_t position = k - begin + 1;
    for (int y = y0; y <= y1; ++y) {
      const int row = y - ty0;
      if (!open[row]) continue;
      uint32_t mask = open[row] & splat_row_mask(s, y, tx0, tx1);
      while (mask) {
        const int c = __builtin_ctz(mask);
        mask &= mask - 1;
        const int p = row * kTileSize + c;
        S alpha, vis;
        if (!evaluate_alpha(s.conic, s.mean2d, s.opacity, S(tx0 + c), S(y), &alpha, &vis)) continue;
        const S weight = tf->acc[p].transmittance * alpha;
        if (!composite_step(alpha, s.colour, s.depth, &tf->acc[p])) {
          open[row] &= ~(1u << c);
          --n_open;
          continue;
        }
        if (surface)
          surface_step(alpha, s.depth, tf->acc[p].transmittance, gap_abs, gap_rel, position,
                       &tf->surface[p]);
        if (s.counts_for_ins && (!labels || s.object_id == tf->ins_label[p])) tf->ins[p] += alpha;
        if (weight > tf->best_weight[p]) {
          tf->best_weight[p] = weight;
          tf->best_id[p] = s.object_id;
        }
        tf->n_contrib[p] = position;
      }
    }
  }

  const S bg[3] = {S(settings.background[0]), S(settings.background[1]), S(settings.background[2])};
  for (int y = ty0; y <= ty1; ++y) {
    for (int x = tx0; x <= tx1; ++x) {
      const int p = (y - ty0) * kTileSize + (x - tx0);
      const size_t pix = static_cast<size_t>(y) * width + x;
      const PixelAccum<S>& a = tf->acc[p];
      const S t = a.transmittance;
      out.rgb[3 * pix + 0] = a.rgb.x + t * bg[0];
      out.rgb[3 * pix + 1] = a.rgb.y + t * bg[1];
      out.rgb[3 * pix + 2] = a.rgb.z + t * bg[2];
      const S accumulated = S(1) - t;
      out.alpha[pix] = accumulated;
      if (surface)
        out.depth[pix] = surface_depth(tf->surface[p]);
      else if (settings.normalise_depth)
        out.depth[pix] = accumulated > S(kNormaliseMinAlpha) ? a.depth / accumulated : S(0);
      else
        out.depth[pix] = a.depth;
      out.ins[pix] = tf->ins[p];
      out.dominant_id[pix] = tf->best_id[p];
      state->t_final[pix] = t;
      state->n_contrib[pix] = tf->n_contrib[p];
      state->depth_raw[pix] = a.depth;
      if (surface) state->surface[pix] = tf->surface[p];
    }
  }
}

}  // namespace

template <typename S>
void composite_forward(const RenderSettings& settings, int threads, const ImageBuffers<S>& out,
                       CpuRenderState<S>* state) {
  const size_t pixels = static_cast<size_t>(state->width) * state->height;
  state->t_final.resize(pixels);
  state->n_contrib.resize(pixels);
  state->depth_raw.resize(pixels);
  if (settings.surface_depth) state->surface.resize(pixels);
  const size_t tiles = static_cast<size_t>(state->bins.tiles_x) * state->bins.tiles_y;
  const int n_threads = std::max(1, std::min<int>(threads, static_cast<int>(tiles)));
  std::vector<TileForward<S>> scratch(n_threads);
  std::atomic<size_t> next{0};
  run_on_threads(n_threads, [&](int t) {
    for (size_t tile = next.fetch_add(1); tile < tiles; tile = next.fetch_add(1))
      composite_tile(settings, tile, out, state, &scratch[t]);
  });
}

template void composite_forward<float>(const RenderSettings&, int, const ImageBuffers<float>&,
                                       CpuRenderState<float>*);
template void composite_forward<double>(const RenderSettings&, int, const ImageBuffers<double>&,
                                        CpuRenderState<double>*);

}  // namespace dqo::gs::detail
