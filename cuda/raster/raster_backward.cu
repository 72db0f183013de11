// Stage 4 of the CUDA rasteriser: the backward pass, the CPU reference's (src/gaussians/
// raster_backward.cpp) by the same per-pixel steps (math/composite.h, math/alpha.h). One block per
// tile, one thread per pixel: the tile's list is walked back to front from the last contributor of
// its pixels, staged through shared memory or by each warp on its own as in the forward pass
// (raster_forward.cu, WalkOrder); a pixel takes part from its own last contributor on,
// reconstructs the transmittance in front of each Gaussian from its final one and adds that
// Gaussian's share of the 2D gradients. As in the forward pass, a warp (an 8×4 block) visits only
// the splats whose α box meets its block, found 32 at a time by one ballot. A warp sums its
// pixels' shares (a reduce-scatter) before ten of its lanes add them to the Gaussian's total
// (float atomics: the sum's order, and so its last bits, vary from run to run). Then every visible
// Gaussian's 2D gradients go through project_gaussian_vjp().

#include "raster_cuda.h"

#include "dqo_map/gaussians/math/alpha.h"

namespace dqo::cuda::detail {

namespace {

constexpr int kThreads = kTileSize * kTileSize;
constexpr float kNormaliseMinAlpha = 1e-6f;

constexpr unsigned kFull = 0xffffffffu;

// One step of a warp's reduce-scatter: each lane keeps half of its `2 half` partial sums (the upper
// half where `bit` of its lane is set) and adds its partner's of the same half.
template <int kHalf>
__device__ __forceinline__ void reduce_scatter_step(float* v, int lane, int bit) {
  const bool upper = (lane & bit) != 0;
#pragma unroll
  for (int k = 0; k < kHalf; ++k) {
    const float send = upper ? v[k] : v[k + kHalf];
    const float keep = upper ? v[k + kHalf] : v[k];
    v[k] = keep + __shfl_xor_sync(kFull, send, bit);
  }
}

// The warp's sums of the ten Grad2D values into `dst` (one Gaussian's): a reduce-scatter that
// halves the values a lane holds at each step (10 → 5 → 3 → 2 → 1, an odd count padded with a
// zero), 12 shuffles against 50 for ten separate tree sums (and 16 when padded to 16 at the
// start). Lane pair (2k, 2k + 1) ends with the total of component
// 5·b16 + 3·b8 + 2·b4 + b2 (its lane bits), a padding slot for 6 of the 16 pairs; ten lanes add
// their component at once instead of one lane adding ten in turn.
__device__ __forceinline__ void warp_add_grad2d(const Grad2D& g, float* dst) {
  static_assert(sizeof(Grad2D) == 10 * sizeof(float), "Grad2D is ten floats");
  const int lane = static_cast<int>(threadIdx.x % 32);
  float v[10];
  const float* gf = reinterpret_cast<const float*>(&g);
#pragma unroll
  for (int c = 0; c < 10; ++c) v[c] = gf[c];
  reduce_scatter_step<5>(v, lane, 16);  // components 0-4 or 5-9
  v[5] = 0.f;
  reduce_scatter_step<3>(v, lane, 8);  // 0-2 or 3-4 (and padding)
  v[3] = 0.f;
  reduce_scatter_step<2>(v, lane, 4);
  reduce_scatter_step<1>(v, lane, 2);
  v[0] += __shfl_xor_sync(kFull, v[0], 1);
  const int b16 = (lane >> 4) & 1, b8 = (lane >> 3) & 1, b4 = (lane >> 2) & 1, b2 = (lane >> 1) & 1;
  const int within = 2 * b4 + b2;  // of the three (b8 = 0) or two (b8 = 1) kept at the second step
  const bool real = within < (b8 ? 2 : 3);
  const int c = 5 * b16 + 3 * b8 + within;
  if ((lane & 1) == 0 && real && v[0] != 0.f) atomicAdd(dst + c, v[0]);
}

// One pixel's state walking back: its output gradients (as the CPU sets them up) and what the
// steps carry from one Gaussian to the one in front.
struct PixelBackward {
  float t_final = 1.f;
  uint32_t n_contrib = 0;
  gs::Vec3<float> v_rgb{0.f, 0.f, 0.f};
  float v_depth = 0.f, v_alpha_px = 0.f, v_ins = 0.f, v_surface = 0.f;
  gs::SurfaceAccum<float> sa = gs::surface_accum_start<float>();
  gs::SurfaceBack<float> surface_back{0.f, 0.f};
  gs::PixelAccumBack<float> back;
};

__device__ __forceinline__ PixelBackward start_pixel(bool inside, size_t pix, const ForwardSettings& settings,
                                                     const ForwardState& state, const ImageGradientsDevice& grad_out) {
  PixelBackward p;
  if (inside) {
    p.t_final = state.t_final[pix];
    p.n_contrib = state.n_contrib[pix];
    if (grad_out.rgb) p.v_rgb = {grad_out.rgb[3 * pix], grad_out.rgb[3 * pix + 1], grad_out.rgb[3 * pix + 2]};
    p.v_depth = grad_out.depth ? grad_out.depth[pix] : 0.f;
    p.v_alpha_px = grad_out.alpha ? grad_out.alpha[pix] : 0.f;
    p.v_ins = grad_out.ins ? grad_out.ins[pix] : 0.f;
    if (settings.surface_depth) {
      p.sa = state.surface[pix];
      if (p.sa.weight > 0.f) {
        p.v_surface = p.v_depth;
        p.surface_back = gs::surface_back_start(p.sa);
      }
      p.v_depth = 0.f;
    } else if (settings.normalise_depth) {
      const float accumulated = 1.f - p.t_final;
      if (accumulated > kNormaliseMinAlpha) {
        p.v_alpha_px -= p.v_depth * state.depth_raw[pix] / (accumulated * accumulated);
        p.v_depth /= accumulated;
      } else {
        p.v_depth = 0.f;
      }
    }
  }
  p.back = gs::pixel_accum_back_start(p.t_final);
  return p;
}

// The pixel's share of the 2D gradients of the splat at 0-based list position `pos`, into *g;
// false where the pixel takes no part (behind its last contributor, or α below 1/255).
__device__ __forceinline__ bool splat_gradient(const DeviceSplat& s, int pos, float x, float y,
                                               const gs::Vec3<float>& bg, PixelBackward* p, Grad2D* g) {
  if (static_cast<uint32_t>(pos) >= p->n_contrib) return false;
  float alpha, vis;
  if (!gs::evaluate_alpha(s.conic, s.mean2d, s.opacity, x, y, &alpha, &vis)) return false;
  gs::Vec3<float> v_colour{0.f, 0.f, 0.f};
  float v_z = 0.f;
  float v_alpha = gs::composite_step_vjp(alpha, s.colour, s.depth, p->t_final, bg, p->v_rgb, p->v_depth, p->v_alpha_px,
                                         &p->back, &v_colour, &v_z);
  if (s.counts_for_ins) v_alpha += p->v_ins;
  if (p->v_surface != 0.f) {
    const uint32_t position = static_cast<uint32_t>(pos) + 1;
    if (position >= p->sa.first && position <= p->sa.last)
      v_alpha += gs::surface_step_vjp(alpha, s.depth, gs::surface_depth(p->sa), p->sa.weight, p->v_surface,
                                      &p->surface_back, &v_z);
  }
  gs::Sym2<float> v_conic{0.f, 0.f, 0.f};
  gs::Vec2<float> v_mean{0.f, 0.f};
  float v_opacity = 0.f;
  gs::evaluate_alpha_vjp(s.conic, s.mean2d, s.opacity, x, y, vis, v_alpha, &v_conic, &v_mean, &v_opacity);
  *g = Grad2D{{v_mean.x, v_mean.y}, {v_conic.xx, v_conic.xy, v_conic.yy}, v_opacity,
              {v_colour.x, v_colour.y, v_colour.z}, v_z};
  return true;
}

template <WalkOrder kWalk>
__global__ void __launch_bounds__(kThreads)
    backward_kernel(int width, int height, int tiles_x, const uint32_t* tile_order, const uint2* ranges,
                    const uint32_t* sorted_ids, const DeviceSplat* splats, ForwardSettings settings,
                    ForwardState state, ImageGradientsDevice grad_out, Grad2D* grad2d) {
  const int tile = static_cast<int>(tile_order[blockIdx.x]);
  const TileThread th = tile_thread(tile, tiles_x, width, height);
  const int lane = static_cast<int>(threadIdx.x % 32);
  const bool inside = th.x < width && th.y < height;
  const float x = float(th.x), y = float(th.y);
  PixelBackward p = start_pixel(inside, inside ? static_cast<size_t>(th.y) * width + th.x : 0, settings, state,
                                grad_out);
  const gs::Vec3<float> bg{settings.background[0], settings.background[1], settings.background[2]};
  const int max_contrib = static_cast<int>(__reduce_max_sync(kFull, p.n_contrib));  // the warp's
  const uint2 range = ranges[tile];

  if constexpr (kWalk == WalkOrder::kStaged) {
    __shared__ uint32_t block_max[kThreads / 32];
    if (lane == 0) block_max[threadIdx.x / 32] = static_cast<uint32_t>(max_contrib);
    __syncthreads();
    uint32_t last = 0;
    for (int w = 0; w < kThreads / 32; ++w) last = max(last, block_max[w]);
    __shared__ DeviceSplat batch[kThreads];
    __shared__ uint32_t batch_id[kThreads];
    // Positions [0, last) of the list, back to front, kThreads at a time.
    for (int end = static_cast<int>(last); end > 0; end -= kThreads) {
      const int begin = max(0, end - kThreads);
      __syncthreads();
      const int k = begin + static_cast<int>(threadIdx.x);
      if (k < end) {
        batch_id[threadIdx.x] = sorted_ids[range.x + k];
        batch[threadIdx.x] = splats[batch_id[threadIdx.x]];
      }
      __syncthreads();
      // 32 splats at a time, back to front, those before the warp's last contributor whose box
      // meets its block.
      const int warp_end = min(end, max_contrib);
      for (int r = ((end - begin - 1) / 32) * 32; r >= 0; r -= 32) {
        const int j = r + lane;
        uint32_t hits = __ballot_sync(kFull, begin + j < warp_end && box_meets_block(batch[j], th));
        while (hits != 0) {
          const int b = 31 - __clz(hits);
          hits &= ~(1u << b);
          Grad2D g{};
          const bool contributes = splat_gradient(batch[r + b], begin + r + b, x, y, bg, &p, &g);
          // Warps where no pixel took part skip the sums (most, for small Gaussians).
          if (__any_sync(kFull, contributes))
            warp_add_grad2d(g, reinterpret_cast<float*>(&grad2d[batch_id[r + b]]));
        }
      }
    }
  } else {
    // The warp walks positions [0, its last contributor) on its own, back to front, 32 at a time.
    for (int r = ((max_contrib - 1) / 32) * 32; max_contrib > 0 && r >= 0; r -= 32) {
      const int k = r + lane;
      uint32_t id = 0;
      bool meets = false;
      if (k < max_contrib) {
        id = sorted_ids[range.x + k];
        meets = box_meets_block(splats[id], th);
      }
      uint32_t hits = __ballot_sync(kFull, meets);
      while (hits != 0) {
        const int b = 31 - __clz(hits);
        hits &= ~(1u << b);
        const uint32_t sid = __shfl_sync(kFull, id, b);
        const DeviceSplat s = splats[sid];  // the same for every lane: one load, broadcast
        Grad2D g{};
        const bool contributes = splat_gradient(s, r + b, x, y, bg, &p, &g);
        if (__any_sync(kFull, contributes)) warp_add_grad2d(g, reinterpret_cast<float*>(&grad2d[sid]));
      }
    }
  }
}

__global__ void project_vjp_kernel(DeviceGaussians g, gs::CameraView<float> cam, const uint32_t* tile_count,
                                   const Grad2D* grad2d, float* grad_position, float* grad_log_scale,
                                   float* grad_rotation, float* grad_opacity, float* grad_colour, bool zero_culled) {
  const size_t i = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= g.count) return;
  if (tile_count[i] == 0) {  // culled: no gradient (zeros, or left as it is)
    if (!zero_culled) return;
    grad_opacity[i] = 0.f;
    for (int c = 0; c < 3; ++c) grad_colour[3 * i + c] = grad_position[3 * i + c] = grad_log_scale[3 * i + c] = 0.f;
    for (int c = 0; c < 4; ++c) grad_rotation[4 * i + c] = 0.f;
    return;
  }
  const Grad2D t = grad2d[i];
  const size_t e = entry_of(g, i);
  // Written, not added: the arrays need no zeroing for the Gaussians a pass reached.
  float v_position[3] = {0.f, 0.f, 0.f}, v_log_scale[3] = {0.f, 0.f, 0.f};
  float v_rotation[4] = {0.f, 0.f, 0.f, 0.f};
  gs::project_gaussian_vjp(g.position + 3 * e, g.log_scale + 3 * e, g.rotation + 4 * e, cam,
                           gs::Vec2<float>{t.mean2d[0], t.mean2d[1]}, gs::Sym2<float>{t.conic[0], t.conic[1], t.conic[2]},
                           t.depth, v_position, v_log_scale, v_rotation, static_cast<gs::Mat3<float>*>(nullptr),
                           static_cast<gs::Vec3<float>*>(nullptr));
  grad_opacity[i] = t.opacity;
  for (int c = 0; c < 3; ++c) {
    grad_colour[3 * i + c] = t.colour[c];
    grad_position[3 * i + c] = v_position[c];
    grad_log_scale[3 * i + c] = v_log_scale[c];
  }
  for (int c = 0; c < 4; ++c) grad_rotation[4 * i + c] = v_rotation[c];
}

}  // namespace

void launch_backward(int width, int height, const uint32_t* tile_order, const uint2* ranges,
                     const uint32_t* sorted_ids, const DeviceSplat* splats, const ForwardSettings& settings,
                     const ForwardState& state, const ImageGradientsDevice& grad_out, Grad2D* grad2d, WalkOrder walk,
                     cudaStream_t stream) {
  const int tiles_x = (width + kTileSize - 1) / kTileSize, tiles_y = (height + kTileSize - 1) / kTileSize;
  if (tiles_x * tiles_y == 0) return;
  if (walk == WalkOrder::kStaged)
    backward_kernel<WalkOrder::kStaged><<<tiles_x * tiles_y, kThreads, 0, stream>>>(
        width, height, tiles_x, tile_order, ranges, sorted_ids, splats, settings, state, grad_out, grad2d);
  else
    backward_kernel<WalkOrder::kPerWarp><<<tiles_x * tiles_y, kThreads, 0, stream>>>(
        width, height, tiles_x, tile_order, ranges, sorted_ids, splats, settings, state, grad_out, grad2d);
}


void launch_project_vjp(const DeviceGaussians& g, const gs::CameraView<float>& cam, const uint32_t* tile_count,
                        const Grad2D* grad2d, float* grad_position, float* grad_log_scale, float* grad_rotation,
                        float* grad_opacity, float* grad_colour, bool zero_culled, cudaStream_t stream) {
  if (g.count == 0) return;
  constexpr int kBlock = 256;
  project_vjp_kernel<<<static_cast<unsigned>((g.count + kBlock - 1) / kBlock), kBlock, 0, stream>>>(
      g, cam, tile_count, grad2d, grad_position, grad_log_scale, grad_rotation, grad_opacity, grad_colour,
      zero_culled);
}

}  // namespace dqo::cuda::detail
