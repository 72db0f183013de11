// Stage 3 of the CUDA rasteriser: one block per 16×16 tile, one thread per pixel; the tile's
// Gaussians, in depth order, are staged through shared memory in batches and composited front to
// back with early stop, by the same per-pixel steps as the CPU reference (math/alpha.h,
// math/composite.h): alpha, colour and depth, surface depth, instance opacity, dominant ID.
// Each warp (an 8×4 block of the tile, raster_cuda.h's tile_thread()) first asks which 32 of the
// batch's splats reach its block (one ballot over their α boxes) and visits only those, in order:
// most of a tile's splats are small and miss most of its blocks.

#include "raster_cuda.h"

#include "dqo_map/gaussians/math/alpha.h"

namespace dqo::cuda::detail {

namespace {

constexpr int kThreads = kTileSize * kTileSize;
constexpr float kNormaliseMinAlpha = 1e-6f;  // as the CPU's: below it the normalised depth is 0
constexpr unsigned kFull = 0xffffffffu;

__global__ void __launch_bounds__(kThreads)
    forward_kernel(int width, int height, int tiles_x, const uint32_t* tile_order, const uint2* ranges,
                   const uint32_t* sorted_ids, const DeviceSplat* splats, ForwardSettings settings, ForwardImages out,
                   ForwardState state) {
  const int tile = static_cast<int>(tile_order[blockIdx.x]);
  const TileThread th = tile_thread(tile, tiles_x, width, height);
  const int x = th.x, y = th.y;
  const bool inside = x < width && y < height;
  const int lane = static_cast<int>(threadIdx.x % 32);

  __shared__ DeviceSplat batch[kThreads];
  gs::PixelAccum<float> acc = gs::pixel_accum_start<float>();
  gs::SurfaceAccum<float> surface = gs::surface_accum_start<float>();
  float ins = 0.f, best_weight = 0.f;
  const uint32_t ins_label = inside && settings.ins_labels ? settings.ins_labels[y * width + x] : 0u;
  uint32_t best_id = 0;
  bool done = !inside;
  uint32_t n_contrib = 0;

  const uint2 range = ranges[tile];
  const int count = static_cast<int>(range.y - range.x);
  for (int start = 0; start < count; start += kThreads) {
    // Everyone in the tile finished: the rest of the list cannot change a pixel.
    if (__syncthreads_count(done ? 0 : 1) == 0) break;
    const int k = start + static_cast<int>(threadIdx.x);
    if (k < count) batch[threadIdx.x] = splats[sorted_ids[range.x + k]];
    __syncthreads();
    const int n = min(kThreads, count - start);
    // 32 splats at a time, front to back: the warp's lanes test one each against the block.
    for (int r = 0; r < n; r += 32) {
      if (__all_sync(kFull, done)) break;
      uint32_t hits = __ballot_sync(kFull, r + lane < n && box_meets_block(batch[r + lane], th));
      for (; hits != 0; hits &= hits - 1) {
        const int j = r + __ffs(hits) - 1;
        if (done) continue;
        const DeviceSplat& s = batch[j];
        float alpha, vis;
        if (!gs::evaluate_alpha(s.conic, s.mean2d, s.opacity, float(x), float(y), &alpha, &vis)) continue;
        const float weight = acc.transmittance * alpha;
        if (!gs::composite_step(alpha, s.colour, s.depth, &acc)) {
          done = true;
          continue;
        }
        const uint32_t position = static_cast<uint32_t>(start + j + 1);
        if (settings.surface_depth)
          gs::surface_step(alpha, s.depth, acc.transmittance, settings.gap_abs, settings.gap_rel, position, &surface);
        if (s.counts_for_ins && (!settings.ins_labels || s.object_id == ins_label)) ins += alpha;
        if (weight > best_weight) {
          best_weight = weight;
          best_id = s.object_id;
        }
        n_contrib = position;
      }
    }
  }
  if (!inside) return;
  const size_t pix = static_cast<size_t>(y) * width + x;
  const float t = acc.transmittance;
  out.rgb[3 * pix + 0] = acc.rgb.x + t * settings.background[0];
  out.rgb[3 * pix + 1] = acc.rgb.y + t * settings.background[1];
  out.rgb[3 * pix + 2] = acc.rgb.z + t * settings.background[2];
  const float accumulated = 1.f - t;
  out.alpha[pix] = accumulated;
  if (settings.surface_depth)
    out.depth[pix] = gs::surface_depth(surface);
  else if (settings.normalise_depth)
    out.depth[pix] = accumulated > kNormaliseMinAlpha ? acc.depth / accumulated : 0.f;
  else
    out.depth[pix] = acc.depth;
  out.ins[pix] = ins;
  out.dominant_id[pix] = best_id;
  if (state.t_final) {
    state.t_final[pix] = t;
    state.n_contrib[pix] = n_contrib;
    state.depth_raw[pix] = acc.depth;
    if (settings.surface_depth) state.surface[pix] = surface;
  }
}

}  // namespace

void launch_forward(int width, int height, const uint32_t* tile_order, const uint2* ranges,
                    const uint32_t* sorted_ids, const DeviceSplat* splats, const ForwardSettings& settings,
                    const ForwardImages& out, const ForwardState& state, cudaStream_t stream) {
  const int tiles_x = (width + kTileSize - 1) / kTileSize, tiles_y = (height + kTileSize - 1) / kTileSize;
  if (tiles_x * tiles_y == 0) return;
  forward_kernel<<<tiles_x * tiles_y, kThreads, 0, stream>>>(width, height, tiles_x, tile_order, ranges, sorted_ids,
                                                              splats, settings, out, state);
}

}  // namespace dqo::cuda::detail
