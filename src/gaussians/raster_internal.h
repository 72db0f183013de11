#pragma once
// Internals of the CPU rasteriser shared by its stage files: the per-Gaussian projection results,
// the tile bins, the state kept for the backward pass, and a small fork-join helper.
// Stages: raster_projection.cpp → raster_binning.cpp → raster_forward.cpp (→ raster_backward.cpp),
// sequenced by cpu_rasteriser.cpp.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "dqo_map/gaussians/detail/cpu_rasteriser.h"
#include "dqo_map/gaussians/math/alpha.h"
#include "dqo_map/gaussians/math/composite.h"
#include "dqo_map/gaussians/math/project_gaussian.h"
#include "parallel.h"

namespace dqo::gs::detail {

constexpr int kTileSize = 16;
constexpr int kTilePixels = kTileSize * kTileSize;
// Below this accumulated alpha the normalised depth is 0 (and passes no gradient).
constexpr double kNormaliseMinAlpha = 1e-6;
// Images up to this size (the splats store rows in 16 bits).
constexpr int kMaxImageSide = 32767;

struct PixelBox {
  int x0, y0, x1, y1;  // inclusive; empty when x0 > x1 or y0 > y1
};

// What the compositing loops read of one visible Gaussian, packed so that one lookup is one or
// two cache lines (the tiles visit Gaussians in depth order, i.e. at random in memory).
template <typename S>
struct alignas(8 * sizeof(S) <= 32 ? 64 : 128) Splat {
  Vec2<S> mean2d;
  Sym2<S> conic;
  S opacity;
  Vec3<S> colour;
  S depth;      // camera-frame z of the mean
  S min_power;  // powers below this give α < 1/255 for sure (skip the exp)
  uint32_t object_id;
  uint16_t counts_for_ins;  // OG of settings.ins_object
  int16_t y0, y1;           // rows (clipped to the image) where α ≥ 1/255 is possible
};

// Projection of every Gaussian, [N] each; visible[i] == 0 for culled ones (other fields undefined).
template <typename S>
struct ProjectedSet {
  std::vector<Splat<S>> splats;
  std::vector<PixelBox> tile_rect;  // tiles touched by the 3σ square, inclusive
  std::vector<uint8_t> visible;
  std::vector<uint32_t> visible_ids;  // indices with visible != 0, ascending
};

// Per tile, the Gaussians that touch it in depth order (ties by index): ids[offsets[t],
// offsets[t + 1]). And per visible Gaussian, where its pairs are, in ascending tile order: for the
// Gaussian projected.visible_ids[v], pairs j in [pair_first[v], pair_first[v + 1]) at
// ids[pair_position[j]] of tile pair_tile[j]. The backward pass adds each Gaussian's per-tile
// gradients in that order, so its result does not depend on how the tiles were split over threads.
struct TileBins {
  int tiles_x = 0, tiles_y = 0;
  std::vector<uint32_t> offsets;
  std::vector<uint32_t> ids;
  std::vector<uint32_t> pair_first;     // [visible Gaussians + 1]
  std::vector<uint32_t> pair_position;  // [ids.size()]
  std::vector<uint32_t> pair_tile;      // [ids.size()]
};

template <typename S>
class CpuRenderState final : public RenderState {
 public:
  size_t gaussian_count = 0;
  int width = 0, height = 0;
  ProjectedSet<S> projected;
  TileBins bins;
  std::vector<S> t_final;                // [P] transmittance after the last contributor
  std::vector<uint32_t> n_contrib;       // [P] list position of the last contributor + 1 (0: none)
  std::vector<S> depth_raw;              // [P] Σ T α z, before any normalisation
  std::vector<SurfaceAccum<S>> surface;  // [P] with settings.surface_depth only
};


// Stage entry points (explicitly instantiated for float and double in their files).
template <typename S>
void project_gaussians(const GaussianArrays<S>& g, const CameraView<S>& cam,
                       const RenderSettings& settings, int threads, ProjectedSet<S>* out);
template <typename S>
void bin_gaussians(const ProjectedSet<S>& projected, int width, int height, TileBins* bins);
template <typename S>
void composite_forward(const RenderSettings& settings, int threads, const ImageBuffers<S>& out,
                       CpuRenderState<S>* state);
template <typename S>
void composite_backward(const GaussianArrays<S>& g, const CameraView<S>& cam,
                        const RenderSettings& settings, int threads, const CpuRenderState<S>& state,
                        const ImageGradients<S>& grad_out, const AttributeGradients<S>& grad);

// ---------------------------------------------------------------- tile rows
// Pixels of a tile are visited through one 16-bit mask per row (bit c: column c of the tile).
static_assert(kTileSize == 16, "row masks are 16 bits wide");

// The columns [xa, xb] of row y that a splat can reach (α ≥ 1/255 needs power ≥ min_power), within
// the tile's columns [tx0, tx1], as a mask; 0 where none.
template <typename S>
inline uint32_t splat_row_mask(const Splat<S>& s, int y, int tx0, int tx1) {
  S lo, hi;
  if (!power_row_span(s.conic, s.mean2d.y - S(y), s.min_power, &lo, &hi)) return 0;
  // x = mean.x − dx; widened by a hair for round-off (the alpha test decides exactly).
  const S fxa = std::ceil(s.mean2d.x - hi - S(1e-3)), fxb = std::floor(s.mean2d.x - lo + S(1e-3));
  if (!(fxb >= S(tx0) && fxa <= S(tx1))) return 0;
  const int xa = static_cast<int>(std::max(S(tx0), fxa)) - tx0;
  const int xb = static_cast<int>(std::min(S(tx1), fxb)) - tx0;
  return ((2u << (xb - xa)) - 1u) << xa;
}

}  // namespace dqo::gs::detail
