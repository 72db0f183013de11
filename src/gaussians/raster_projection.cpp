// Stage 1 of the CPU rasteriser: every Gaussian through project_gaussian() (math/), then culled by
// the image bounds, with its tile rectangle (from the 3σ radius, as 3DGS bins) and the rows outside
// which its alpha is below 1/255 for sure (a CPU shortcut that changes no result).

#include <cmath>

#include "dqo_map/gaussians/math/alpha.h"
#include "raster_internal.h"

namespace dqo::gs::detail {

namespace {

template <typename S>
bool project_one(const GaussianArrays<S>& g, size_t i, const CameraView<S>& cam,
                 const RenderSettings& settings, ProjectedSet<S>* out) {
  ProjectedGaussian<S> p;
  if (!project_gaussian(g.position + 3 * i, g.log_scale + 3 * i, g.rotation + 4 * i, cam, &p))
    return false;
  const S opacity = g.opacity[i];
  Vec2<S> half;
  if (!alpha_extent(p.cov2d, opacity, &half)) return false;
  const int width = cam.K.width, height = cam.K.height;
  // Pixels (centres at integers) within the 3σ square, then the tiles holding them. Clamped before
  // the conversion: a mean far off-screen must not overflow an int.
  const S r = S(p.radius);
  const S fx0 = std::ceil(p.mean2d.x - r), fx1 = std::floor(p.mean2d.x + r);
  const S fy0 = std::ceil(p.mean2d.y - r), fy1 = std::floor(p.mean2d.y + r);
  if (!(fx1 >= 0 && fy1 >= 0 && fx0 <= S(width - 1) && fy0 <= S(height - 1))) return false;
  const int px0 = static_cast<int>(std::max(S(0), fx0));
  const int px1 = static_cast<int>(std::min(S(width - 1), fx1));
  const int py0 = static_cast<int>(std::max(S(0), fy0));
  const int py1 = static_cast<int>(std::min(S(height - 1), fy1));
  // The rows and columns where α can reach 1/255, clipped to the image.
  const S ax0 = std::ceil(p.mean2d.x - half.x), ax1 = std::floor(p.mean2d.x + half.x);
  const S ay0 = std::ceil(p.mean2d.y - half.y), ay1 = std::floor(p.mean2d.y + half.y);
  if (!(ax1 >= 0 && ay1 >= 0 && ax0 <= S(width - 1) && ay0 <= S(height - 1))) return false;
  // Tiles of the 3σ square that the alpha box reaches (the others would visit no pixel).
  const int bx0 = static_cast<int>(std::max(S(0), ax0));
  const int bx1 = static_cast<int>(std::min(S(width - 1), ax1));
  const int by0 = static_cast<int>(std::max(S(0), ay0));
  const int by1 = static_cast<int>(std::min(S(height - 1), ay1));
  const PixelBox tiles{std::max(px0, bx0) / kTileSize, std::max(py0, by0) / kTileSize,
                       std::min(px1, bx1) / kTileSize, std::min(py1, by1) / kTileSize};
  if (tiles.x0 > tiles.x1 || tiles.y0 > tiles.y1) return false;

  Splat<S>& s = out->splats[i];
  s.mean2d = p.mean2d;
  s.conic = p.conic;
  s.opacity = opacity;
  s.colour = load_vec3(g.colour + 3 * i);
  s.depth = p.depth;
  s.min_power = -std::log(S(255) * opacity) - S(1e-3);
  s.object_id = g.object_id[i];
  // Per-label instance opacity: every object's OG counts, on the pixels of its label.
  s.counts_for_ins = g.type[i] == static_cast<uint8_t>(GaussianType::kOpaque) &&
                     (settings.ins_labels ? g.object_id[i] != 0
                                          : settings.ins_object != 0 && g.object_id[i] == settings.ins_object);
  s.y0 = static_cast<int16_t>(by0);
  s.y1 = static_cast<int16_t>(by1);
  out->tile_rect[i] = tiles;
  return true;
}

}  // namespace

template <typename S>
void project_gaussians(const GaussianArrays<S>& g, const CameraView<S>& cam,
                       const RenderSettings& settings, int threads, ProjectedSet<S>* out) {
  const size_t n = g.count;
  out->splats.resize(n);
  out->tile_rect.resize(n);
  out->visible.assign(n, 0);
  parallel_for_chunks(threads, n, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i)
      out->visible[i] = project_one(g, i, cam, settings, out) ? 1 : 0;
  });
  out->visible_ids.clear();
  for (size_t i = 0; i < n; ++i)
    if (out->visible[i]) out->visible_ids.push_back(static_cast<uint32_t>(i));
}

template void project_gaussians<float>(const GaussianArrays<float>&, const CameraView<float>&,
                                       const RenderSettings&, int, ProjectedSet<float>*);
template void project_gaussians<double>(const GaussianArrays<double>&, const CameraView<double>&,
                                        const RenderSettings&, int, ProjectedSet<double>*);

}  // namespace dqo::gs::detail
