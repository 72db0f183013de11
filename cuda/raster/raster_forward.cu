// Stage 3 of the CUDA rasteriser: one block per 16×16 tile, one thread per pixel; the tile's
// Gaussians, in depth order, composited front to back with early stop, by the same per-pixel steps
// as the CPU reference (math/alpha.h, math/composite.h): alpha, colour and depth, surface depth,
// instance opacity, dominant ID. Each warp (an 8×4 block of the tile, raster_cuda.h's
// tile_thread()) asks which 32 splats at a time reach its block (one ballot over their α boxes)
// and visits only those, in order: most of a tile's splats are small and miss most of its blocks.
//
// Two ways to walk a tile's list (WalkOrder in raster_cuda.h, chosen per pass by its density):
//   - staged: the block copies 256 splats at a time into shared memory, one global read per splat
//     for all eight warps, and waits at a barrier per batch. Best where lists are short or splats
//     large (every warp visits most of them).
//   - per warp: each warp reads the list on its own (ids and boxes 32 at a time, a visited
//     splat's 56 bytes broadcast from L1), with no barrier: a warp that finished its pixels stops
//     and one with little to do moves on. Best on long lists of small splats (the 2M comparison
//     map: 1 200 a tile), where the staged walk's warps wait for the busiest at every batch.

#include "raster_cuda.h"

#include "dqo_map/gaussians/math/alpha.h"

namespace dqo::cuda::detail {

namespace {

constexpr int kThreads = kTileSize * kTileSize;
constexpr float kNormaliseMinAlpha = 1e-6f;  // as the CPU's: below it the normalised depth is 0
constexpr unsigned kFull = 0xffffffffu;

// One pixel's compositing state.
struct PixelForward {
  gs::PixelAccum<float> acc = gs::pixel_accum_start<float>();
  gs::SurfaceAccum<float> surface = gs::surface_accum_start<float>();
  float ins = 0.f, best_weight = 0.f;
  uint32_t ins_label = 0, best_id = 0, n_contrib = 0;
  bool done = false;
};

// The splat at 1-based list position `position` composited into the pixel (a no-op where its α
// is below 1/255; `done` once the transmittance is spent).
__device__ __forceinline__ void composite_splat(const DeviceSplat& s, uint32_t position, float x, float y,
                                                const ForwardSettings& settings, PixelForward* p) {
  float alpha, vis;
  if (!gs::evaluate_alpha(s.conic, s.mean2d, s.opacity, x, y, &alpha, &vis)) return;
  const float weight = p->acc.transmittance * alpha;
  if (!gs::composite_step(alpha, s.colour, s.depth, &p->acc)) {
    p->done = true;
    return;
  }
  if (settings.surface_depth)
    gs::surface_step(alpha, s.depth, p->acc.transmittance, settings.gap_abs, settings.gap_rel, position, &p->surface);
  if (s.counts_for_ins && (!settings.ins_labels || s.object_id == p->ins_label)) p->ins += alpha;
  if (weight > p->best_weight) {
    p->best_weight = weight;
    p->best_id = s.object_id;
  }
  p->n_contrib = position;
}

__device__ __forceinline__ void write_pixel(const PixelForward& p, size_t pix, const ForwardSettings& settings,
                                            const ForwardImages& out, const ForwardState& state) {
  const float t = p.acc.transmittance;
  out.rgb[3 * pix + 0] = p.acc.rgb.x + t * settings.background[0];
  out.rgb[3 * pix + 1] = p.acc.rgb.y + t * settings.background[1];
  out.rgb[3 * pix + 2] = p.acc.rgb.z + t * settings.background[2];
  const float accumulated = 1.f - t;
  out.alpha[pix] = accumulated;
  if (settings.surface_depth)
    out.depth[pix] = gs::surface_depth(p.surface);
  else if (settings.normalise_depth)
    out.depth[pix] = accumulated > kNormaliseMinAlpha ? p.acc.depth / accumulated : 0.f;
  else
    out.depth[pix] = p.acc.depth;
  out.ins[pix] = p.ins;
  out.dominant_id[pix] = p.best_id;
  if (state.t_final) {
    state.t_final[pix] = t;
    state.n_contrib[pix] = p.n_contrib;
    state.depth_raw[pix] = p.acc.depth;
    if (settings.surface_depth) state.surface[pix] = p.surface;
  }
}

template <WalkOrder kWalk>
__global__ void __launch_bounds__(kThreads)
    forward_kernel(int width, int height, int tiles_x, const uint32_t* tile_order, const uint2* ranges,
                   const uint32_t* sorted_ids, const DeviceSplat* splats, ForwardSettings settings, ForwardImages out,
                   ForwardState state) {
  const int tile = static_cast<int>(tile_order[blockIdx.x]);
  const TileThread th = tile_thread(tile, tiles_x, width, height);
  const bool inside = th.x < width && th.y < height;
  const float x = float(th.x), y = float(th.y);
  const int lane = static_cast<int>(threadIdx.x % 32);

  PixelForward p;
  p.ins_label = inside && settings.ins_labels ? settings.ins_labels[th.y * width + th.x] : 0u;
  p.done = !inside;
  const uint2 range = ranges[tile];
  const int count = static_cast<int>(range.y - range.x);

  if constexpr (kWalk == WalkOrder::kStaged) {
    __shared__ DeviceSplat batch[kThreads];
    for (int start = 0; start < count; start += kThreads) {
      // Everyone in the tile finished: the rest of the list cannot change a pixel.
      if (__syncthreads_count(p.done ? 0 : 1) == 0) break;
      const int k = start + static_cast<int>(threadIdx.x);
      if (k < count) batch[threadIdx.x] = splats[sorted_ids[range.x + k]];
      __syncthreads();
      const int n = min(kThreads, count - start);
      // 32 splats at a time, front to back: the warp's lanes test one each against the block.
      for (int r = 0; r < n; r += 32) {
        if (__all_sync(kFull, p.done)) break;
        for (uint32_t hits = __ballot_sync(kFull, r + lane < n && box_meets_block(batch[r + lane], th)); hits != 0;
             hits &= hits - 1) {
          const int j = r + __ffs(hits) - 1;
          if (!p.done) composite_splat(batch[j], static_cast<uint32_t>(start + j + 1), x, y, settings, &p);
        }
      }
    }
  } else {
    for (int start = 0; start < count; start += 32) {
      if (__all_sync(kFull, p.done)) break;
      const int k = start + lane;
      uint32_t id = 0;
      bool meets = false;
      if (k < count) {
        id = sorted_ids[range.x + k];
        meets = box_meets_block(splats[id], th);
      }
      for (uint32_t hits = __ballot_sync(kFull, meets); hits != 0; hits &= hits - 1) {
        const int b = __ffs(hits) - 1;
        const uint32_t sid = __shfl_sync(kFull, id, b);
        if (p.done) continue;
        const DeviceSplat s = splats[sid];  // the same for every lane: one load, broadcast
        composite_splat(s, static_cast<uint32_t>(start + b + 1), x, y, settings, &p);
      }
    }
  }
  if (inside) write_pixel(p, static_cast<size_t>(th.y) * width + th.x, settings, out, state);
}

}  // namespace

void launch_forward(int width, int height, const uint32_t* tile_order, const uint2* ranges,
                    const uint32_t* sorted_ids, const DeviceSplat* splats, const ForwardSettings& settings,
                    const ForwardImages& out, const ForwardState& state, WalkOrder walk, cudaStream_t stream) {
  const int tiles_x = (width + kTileSize - 1) / kTileSize, tiles_y = (height + kTileSize - 1) / kTileSize;
  if (tiles_x * tiles_y == 0) return;
  if (walk == WalkOrder::kStaged)
    forward_kernel<WalkOrder::kStaged><<<tiles_x * tiles_y, kThreads, 0, stream>>>(
        width, height, tiles_x, tile_order, ranges, sorted_ids, splats, settings, out, state);
  else
    forward_kernel<WalkOrder::kPerWarp><<<tiles_x * tiles_y, kThreads, 0, stream>>>(
        width, height, tiles_x, tile_order, ranges, sorted_ids, splats, settings, out, state);
}

}  // namespace dqo::cuda::detail
