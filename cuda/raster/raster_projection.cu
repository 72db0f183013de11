// Stage 1 of the CUDA rasteriser: every Gaussian of the pass through project_footprint()
// (raster_cuda.h: project_gaussian() of math/, culled by the image bounds, with the tiles of its 3σ
// square that its α ≥ 1/255 box reaches, the CPU reference's rule) and how many of them its ellipse
// reaches (the pairs it will have; the binning's rule, raster_cuda.h's tile_reached()), and which
// (TileRect::reached) for the key emission.

#include "raster_cuda.h"

#include "dqo_map/gaussians/math/alpha.h"

namespace dqo::cuda::detail {

namespace {

__global__ void project_kernel(DeviceGaussians g, gs::CameraView<float> cam, uint32_t ins_object, bool ins_per_label,
                               DeviceSplat* splats, TileRect* rects, uint32_t* tile_count, Grad2D* zero_grad2d) {
  const size_t i = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= g.count) return;
  tile_count[i] = 0;
  const size_t e = entry_of(g, i);
  Footprint f;
  if (!project_footprint(g, e, cam, &f)) return;
  const int width = cam.K.width, height = cam.K.height;
  const gs::ProjectedGaussian<float>& p = f.p;
  TileRect t = f.rect;
  DeviceSplat s;
  s.mean2d = p.mean2d;
  s.conic = p.conic;
  s.opacity = f.opacity;
  s.colour = gs::load_vec3(g.colour + 3 * e);
  s.depth = p.depth;
  s.object_id = g.object_id[e];
  // Per-label instance opacity: every object's OG counts, on the pixels of its label.
  s.counts_for_ins = g.type[e] == kOpaqueType &&
                     (ins_per_label ? g.object_id[e] != 0 : ins_object != 0 && g.object_id[e] == ins_object);
  for (int c = 0; c < 4; ++c) s.box[c] = static_cast<uint16_t>(f.box[c]);
  splats[i] = s;
  // Only the tiles its α ≥ 1/255 ellipse reaches (as the CPU binning: math/alpha.h).
  uint32_t count = 0;
  int k = 0;
  for (int ty = t.y0; ty <= t.y1; ++ty)
    for (int tx = t.x0; tx <= t.x1; ++tx, ++k) {
      if (!tile_reached(s, tx, ty, width, height)) continue;
      ++count;
      if (k < kReachedBits) t.reached |= 1u << k;
    }
  rects[i] = t;
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
