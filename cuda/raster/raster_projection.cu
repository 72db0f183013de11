// Stage 1 of the CUDA rasteriser: every Gaussian through project_gaussian() (math/), culled by the
// image bounds, with the tiles of its 3σ square that its α ≥ 1/255 box reaches — the CPU
// reference's rule (src/gaussians/raster_projection.cpp) — and how many of them its ellipse
// reaches (the pairs it will have; the binning's rule, raster_cuda.h's tile_reached()).

#include "raster_cuda.h"

#include "dqo_map/gaussians/math/alpha.h"

namespace dqo::cuda::detail {

namespace {

__global__ void project_kernel(DeviceGaussians g, gs::CameraView<float> cam, uint32_t ins_object, bool ins_per_label,
                               DeviceSplat* splats, TileRect* rects, uint32_t* tile_count, Grad2D* zero_grad2d) {
  const size_t i = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= g.count) return;
  tile_count[i] = 0;
  gs::ProjectedGaussian<float> p;
  if (!gs::project_gaussian(g.position + 3 * i, g.log_scale + 3 * i, g.rotation + 4 * i, cam, &p)) return;
  const float opacity = g.opacity[i];
  gs::Vec2<float> half;
  if (!gs::alpha_extent(p.cov2d, opacity, &half)) return;
  const int width = cam.K.width, height = cam.K.height;
  const float r = static_cast<float>(p.radius);
  const float fx0 = ceilf(p.mean2d.x - r), fx1 = floorf(p.mean2d.x + r);
  const float fy0 = ceilf(p.mean2d.y - r), fy1 = floorf(p.mean2d.y + r);
  if (!(fx1 >= 0 && fy1 >= 0 && fx0 <= float(width - 1) && fy0 <= float(height - 1))) return;
  const int px0 = static_cast<int>(fmaxf(0.f, fx0)), px1 = static_cast<int>(fminf(float(width - 1), fx1));
  const int py0 = static_cast<int>(fmaxf(0.f, fy0)), py1 = static_cast<int>(fminf(float(height - 1), fy1));
  const float ax0 = ceilf(p.mean2d.x - half.x), ax1 = floorf(p.mean2d.x + half.x);
  const float ay0 = ceilf(p.mean2d.y - half.y), ay1 = floorf(p.mean2d.y + half.y);
  if (!(ax1 >= 0 && ay1 >= 0 && ax0 <= float(width - 1) && ay0 <= float(height - 1))) return;
  const int bx0 = static_cast<int>(fmaxf(0.f, ax0)), bx1 = static_cast<int>(fminf(float(width - 1), ax1));
  const int by0 = static_cast<int>(fmaxf(0.f, ay0)), by1 = static_cast<int>(fminf(float(height - 1), ay1));
  const TileRect t{max(px0, bx0) / kTileSize, max(py0, by0) / kTileSize, min(px1, bx1) / kTileSize,
                   min(py1, by1) / kTileSize};
  if (t.x0 > t.x1 || t.y0 > t.y1) return;
  DeviceSplat s;
  s.mean2d = p.mean2d;
  s.conic = p.conic;
  s.opacity = opacity;
  s.colour = gs::load_vec3(g.colour + 3 * i);
  s.depth = p.depth;
  s.object_id = g.object_id[i];
  // Per-label instance opacity: every object's OG counts, on the pixels of its label.
  s.counts_for_ins = g.type[i] == kOpaqueType &&
                     (ins_per_label ? g.object_id[i] != 0 : ins_object != 0 && g.object_id[i] == ins_object);
  s.box[0] = static_cast<uint16_t>(bx0), s.box[1] = static_cast<uint16_t>(by0);
  s.box[2] = static_cast<uint16_t>(bx1), s.box[3] = static_cast<uint16_t>(by1);
  splats[i] = s;
  rects[i] = t;
  // Only the tiles its α ≥ 1/255 ellipse reaches (as the CPU binning: math/alpha.h).
  uint32_t count = 0;
  for (int ty = t.y0; ty <= t.y1; ++ty)
    for (int tx = t.x0; tx <= t.x1; ++tx)
      count += tile_reached(s, tx, ty, width, height) ? 1u : 0u;
  tile_count[i] = count;
  if (zero_grad2d && count > 0) zero_grad2d[i] = Grad2D{};
}

}  // namespace

void launch_project(const DeviceGaussians& g, const gs::CameraView<float>& cam, uint32_t ins_object, bool ins_per_label,
                    DeviceSplat* splats, TileRect* rects, uint32_t* tile_count, Grad2D* zero_grad2d,
                    cudaStream_t stream) {
  if (g.count == 0) return;
  constexpr int kBlock = 256;
  const unsigned blocks = static_cast<unsigned>((g.count + kBlock - 1) / kBlock);
  project_kernel<<<blocks, kBlock, 0, stream>>>(g, cam, ins_object, ins_per_label, splats, rects, tile_count,
                                                zero_grad2d);
}

}  // namespace dqo::cuda::detail
