// Stage 4 of the CPU rasteriser: the backward pass.
//
// Per tile, the depth-ordered list is walked back to front from the last contributor of any of its
// pixels. Each Gaussian visits, row by row (16-bit masks as in the forward pass), the pixels of its
// ellipse where it is at or before the pixel's last contributor, reconstructs the transmittance in
// front of it from the saved final one (composite_step_vjp) and sums over those pixels the
// gradients of its 2D quantities (mean, conic, opacity, colour, depth). Each (tile, Gaussian)
// pair's sum is written beside the pair in the tile's list; each Gaussian's are then added in
// ascending tile order (TileBins::pair_position) and its 2D gradients go through
// project_gaussian_vjp() to its attributes.
//
// Independent of the thread count, bit for bit: the threads take contiguous runs of tiles
// (balanced by list length) but no sum crosses a run, so a robot's 16 cores and a CI machine's 2
// train the same map. Per-thread buffers of the whole map, added in thread order, did not: their
// rounding changed with the split, and a trained map with it.

#include <memory>

#include "dqo_map/gaussians/math/composite.h"
#include "raster_internal.h"

namespace dqo::gs::detail {

namespace {

// Gradients of one Gaussian's screen-space quantities.
template <typename S>
struct Grad2D {
  Vec2<S> mean2d;
  Sym2<S> conic;
  S opacity;
  Vec3<S> colour;
  S depth;
};

template <typename S>
Grad2D<S> grad2d_zero() {
  return {{S(0), S(0)}, {S(0), S(0), S(0)}, S(0), {S(0), S(0), S(0)}, S(0)};
}

template <typename S>
void add_to(Grad2D<S>* a, const Grad2D<S>& b) {
  a->mean2d.x += b.mean2d.x;
  a->mean2d.y += b.mean2d.y;
  a->conic.xx += b.conic.xx;
  a->conic.xy += b.conic.xy;
  a->conic.yy += b.conic.yy;
  a->opacity += b.opacity;
  a->colour += b.colour;
  a->depth += b.depth;
}

template <typename S>
struct TileBackward {
  PixelAccumBack<S> back[kTilePixels];
  Vec3<S> v_rgb[kTilePixels];
  S v_depth[kTilePixels];    // of the raw Σ T α z
  S v_surface[kTilePixels];  // of the surface depth (settings.surface_depth)
  SurfaceBack<S> surface_back[kTilePixels];
  S v_alpha[kTilePixels];  // of the accumulated alpha 1 − T_N
  S v_ins[kTilePixels];
  S t_final[kTilePixels];
  uint32_t order[kTilePixels];  // (n_contrib << 8 | pixel), descending
};

// Writes the gradient sum over the tile of every pair the walk reaches (from the tile's deepest
// last contributor to its front) and returns the end of those pairs in the tile's list: the pairs
// behind it are not written (most of a dense map's: zeroing them cost more than the walk).
template <typename S>
uint32_t backward_tile(const RenderSettings& settings, const CpuRenderState<S>& state,
                       const ImageGradients<S>& grad_out, size_t tile, TileBackward<S>* tb,
                       Grad2D<S>* pair_sums) {
  const std::vector<Splat<S>>& splats = state.projected.splats;
  const TileBins& bins = state.bins;
  const int width = state.width, height = state.height;
  const int tx0 = static_cast<int>(tile % bins.tiles_x) * kTileSize;
  const int ty0 = static_cast<int>(tile / bins.tiles_x) * kTileSize;
  const int tx1 = std::min(tx0 + kTileSize, width) - 1;
  const int ty1 = std::min(ty0 + kTileSize, height) - 1;

  int n_order = 0;
  for (int y = ty0; y <= ty1; ++y) {
    for (int x = tx0; x <= tx1; ++x) {
      const int p = (y - ty0) * kTileSize + (x - tx0);
      const size_t pix = static_cast<size_t>(y) * width + x;
      const S t_final = state.t_final[pix];
      tb->t_final[p] = t_final;
      tb->back[p] = pixel_accum_back_start(t_final);
      if (state.n_contrib[pix] > 0) tb->order[n_order++] = state.n_contrib[pix] << 8 | p;
      tb->v_rgb[p] = grad_out.rgb ? Vec3<S>{grad_out.rgb[3 * pix], grad_out.rgb[3 * pix + 1],
                                            grad_out.rgb[3 * pix + 2]}
                                  : Vec3<S>{S(0), S(0), S(0)};
      S v_depth = grad_out.depth ? grad_out.depth[pix] : S(0);
      S v_alpha = grad_out.alpha ? grad_out.alpha[pix] : S(0);
      tb->v_surface[p] = S(0);
      if (settings.surface_depth) {
        // The output depth is the surface's alone: the raw Σ T α z gets no gradient.
        if (state.surface[pix].weight > S(0)) {
          tb->v_surface[p] = v_depth;
          tb->surface_back[p] = surface_back_start(state.surface[pix]);
        }
        v_depth = S(0);
      } else if (settings.normalise_depth) {
        // d = D / A: dD = g / A, dA = −g D / A².
        const S accumulated = S(1) - t_final;
        if (accumulated > S(kNormaliseMinAlpha)) {
          v_alpha -= v_depth * state.depth_raw[pix] / (accumulated * accumulated);
          v_depth /= accumulated;
        } else {
          v_depth = S(0);
        }
      }
      tb->v_depth[p] = v_depth;
      tb->v_alpha[p] = v_alpha;
      tb->v_ins[p] = grad_out.ins ? grad_out.ins[pix] : S(0);
    }
  }
  const uint32_t begin = bins.offsets[tile];
  if (n_order == 0) return begin;
  std::sort(tb->order, tb->order + n_order, [](uint32_t a, uint32_t b) { return a > b; });

  // A pixel opens when the walk reaches its last contributor: at list position pos, the pixels
  // with n_contrib > pos.
  uint32_t open[kTileSize] = {0};
  int next_open = 0;
  const Vec3<S> bg = {S(settings.background[0]), S(settings.background[1]),
                      S(settings.background[2])};
  const uint32_t walked = tb->order[0] >> 8;
  for (uint32_t pos = walked; pos-- > 0;) {
    while (next_open < n_order && (tb->order[next_open] >> 8) > pos) {
      const int p = tb->order[next_open++] & 0xff;
      open[p / kTileSize] |= 1u << (p % kTileSize);
    }
    const uint32_t id = bins.ids[begin + pos];
    const Splat<S>& s = splats[id];
    const int y0 = std::max<int>(s.y0, ty0), y1 = std::min<int>(s.y1, ty1);
    Grad2D<S> acc = grad2d_zero<S>();
    for (int y = y0; y <= y1; ++y) {
      const int row = y - ty0;
      if (!open[row]) continue;
      uint32_t mask = open[row] & splat_row_mask(s, y, tx0, tx1);
      while (mask) {
        const int c = __builtin_ctz(mask);
        mask &= mask - 1;
        const int p = row * kTileSize + c;
        const S px = S(tx0 + c), py = S(y);
        S alpha, vis;
        if (!evaluate_alpha(s.conic, s.mean2d, s.opacity, px, py, &alpha, &vis)) continue;
        S v_alpha = composite_step_vjp(alpha, s.colour, s.depth, tb->t_final[p], bg, tb->v_rgb[p],
                                       tb->v_depth[p], tb->v_alpha[p], &tb->back[p], &acc.colour,
                                       &acc.depth);
        if (s.counts_for_ins) v_alpha += tb->v_ins[p];
        if (tb->v_surface[p] != S(0)) {
          const SurfaceAccum<S>& sa = state.surface[static_cast<size_t>(y) * width + tx0 + c];
          const uint32_t position = pos + 1;
          if (position >= sa.first && position <= sa.last)
            v_alpha += surface_step_vjp(alpha, s.depth, surface_depth(sa), sa.weight,
                                        tb->v_surface[p], &tb->surface_back[p], &acc.depth);
        }
        evaluate_alpha_vjp(s.conic, s.mean2d, s.opacity, px, py, vis, v_alpha, &acc.conic,
                           &acc.mean2d, &acc.opacity);
      }
    }
    pair_sums[begin + pos] = acc;
  }
  return begin + walked;
}

// One contiguous run of tiles per thread, balanced by the tiles' list lengths.
std::vector<size_t> split_tiles(const TileBins& bins, int threads) {
  const size_t tiles = bins.offsets.size() - 1;
  std::vector<double> cost(tiles + 1, 0.0);
  for (size_t t = 0; t < tiles; ++t)
    cost[t + 1] = cost[t] + 1.0 + (bins.offsets[t + 1] - bins.offsets[t]);
  std::vector<size_t> bounds(threads + 1, tiles);
  bounds[0] = 0;
  size_t t = 0;
  for (int k = 1; k < threads; ++k) {
    const double target = cost[tiles] * k / threads;
    while (t < tiles && cost[t] < target) ++t;
    bounds[k] = t;
  }
  return bounds;
}

}  // namespace

template <typename S>
void composite_backward(const GaussianArrays<S>& g, const CameraView<S>& cam,
                        const RenderSettings& settings, int threads, const CpuRenderState<S>& state,
                        const ImageGradients<S>& grad_out, const AttributeGradients<S>& grad) {
  const size_t tiles = static_cast<size_t>(state.bins.tiles_x) * state.bins.tiles_y;
  const int n_threads = std::max(1, std::min<int>(threads, static_cast<int>(tiles)));
  const std::vector<size_t> bounds = split_tiles(state.bins, n_threads);

  // A pair's sum is read only where its tile's walk wrote it (default-initialised: no pass zeroes
  // them); walk_end[t] is the end of tile t's written pairs.
  const TileBins& bins = state.bins;
  const std::unique_ptr<Grad2D<S>[]> pair_sums(new Grad2D<S>[bins.ids.size()]);
  std::vector<uint32_t> walk_end(tiles);
  run_on_threads(n_threads, [&](int t) {
    auto scratch = std::make_unique<TileBackward<S>>();
    Grad2D<S>* sums = pair_sums.get();
    for (size_t tile = bounds[t]; tile < bounds[t + 1]; ++tile)
      walk_end[tile] = backward_tile(settings, state, grad_out, tile, scratch.get(), sums);
  });

  // In index order: the attributes and their gradients are read and written in memory order.
  const std::vector<uint32_t>& visible = state.projected.visible_ids;
  parallel_for_chunks(threads, visible.size(), [&](size_t begin, size_t end) {
    for (size_t v = begin; v < end; ++v) {
      const uint32_t i = visible[v];
      Grad2D<S> total = grad2d_zero<S>();
      for (uint32_t j = bins.pair_first[v]; j < bins.pair_first[v + 1]; ++j) {
        const uint32_t position = bins.pair_position[j];
        if (position < walk_end[bins.pair_tile[j]]) add_to(&total, pair_sums[position]);
      }
      grad.opacity[i] += total.opacity;
      grad.colour[3 * i + 0] += total.colour.x;
      grad.colour[3 * i + 1] += total.colour.y;
      grad.colour[3 * i + 2] += total.colour.z;
      project_gaussian_vjp(g.position + 3 * i, g.log_scale + 3 * i, g.rotation + 4 * i, cam,
                           total.mean2d, total.conic, total.depth, grad.position + 3 * i,
                           grad.log_scale + 3 * i, grad.rotation + 4 * i,
                           static_cast<Mat3<S>*>(nullptr), static_cast<Vec3<S>*>(nullptr));
    }
  });
}

template void composite_backward<float>(const GaussianArrays<float>&, const CameraView<float>&,
                                        const RenderSettings&, int, const CpuRenderState<float>&,
                                        const ImageGradients<float>&,
                                        const AttributeGradients<float>&);
template void composite_backward<double>(const GaussianArrays<double>&, const CameraView<double>&,
                                         const RenderSettings&, int, const CpuRenderState<double>&,
                                         const ImageGradients<double>&,
                                         const AttributeGradients<double>&);

}  // namespace dqo::gs::detail
