#pragma once
// Internals of the CUDA rasteriser shared by its stage files (the CPU rasteriser's stages, on the
// device): raster_projection.cu → raster_binning.cu → raster_forward.cu, sequenced by
// cuda_rasteriser.cu. Per-Gaussian and per-pixel maths come from include/dqo_map/gaussians/math/,
// the same functions the CPU reference calls, so the two cannot drift apart.

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

#include "dqo_map/gaussians/math/alpha.h"
#include "dqo_map/gaussians/math/composite.h"
#include "dqo_map/gaussians/math/project_gaussian.h"

namespace dqo::cuda::detail {

constexpr int kTileSize = 16;  // as the CPU rasteriser's tiles: same bins, same per-tile order
constexpr int kMaxImageSide = 32767;  // as the CPU rasteriser's (src/gaussians/raster_internal.h)
// GaussianType::kOpaque (gaussians/gaussian_map.h, which brings Eigen: kept out of device code;
// cuda_rasteriser.cpp asserts the value).
constexpr uint8_t kOpaqueType = 0;

// The map's arrays on the device (float; rotations w x y z of any norm).
struct DeviceGaussians {
  // The Gaussians a pass works on: entries index[0 .. count) of the arrays, ascending (a training
  // batch's selection: those its views reach, train_select.cu), or the first `count` when null.
  // The pass's own per-Gaussian arrays (splats, tile counts, 2D and attribute gradients) are
  // indexed by position in that list, the map's arrays by the entry.
  size_t count = 0;
  const uint32_t* index = nullptr;
  const float* position = nullptr;      // [N*3]
  const float* log_scale = nullptr;     // [N*3]
  const float* rotation = nullptr;      // [N*4]
  const float* opacity = nullptr;       // [N]
  const float* colour = nullptr;        // [N*3]
  const uint32_t* object_id = nullptr;  // [N]
  const uint8_t* type = nullptr;        // [N] GaussianType
};

// What the compositing kernel reads of one visible Gaussian.
struct DeviceSplat {
  gs::Vec2<float> mean2d;
  gs::Sym2<float> conic;
  float opacity;
  gs::Vec3<float> colour;
  float depth;
  uint32_t object_id;
  uint32_t counts_for_ins;  // an opaque Gaussian of settings.ins_object
  // Pixel centres outside [box[0], box[2]] × [box[1], box[3]] (inclusive, clipped to the image)
  // have α < 1/255 for sure (math/alpha.h's alpha_extent): a warp whose pixels all lie outside
  // skips the splat without evaluating it.
  uint16_t box[4];
};

struct TileRect {
  int x0, y0, x1, y1;  // inclusive tiles; tile_count 0 when culled
  // Which of the rectangle's tiles the ellipse reaches (bit k: the k-th tile, row by row), when it
  // has at most kReachedBits tiles (most splats): the projection tests each tile once and the key
  // emission reads the answer instead of testing again. Larger rectangles are tested again.
  uint32_t reached;
};
constexpr int kReachedBits = 32;

#ifdef __CUDACC__
// The map entry of the pass's i-th Gaussian.
__device__ __forceinline__ size_t entry_of(const DeviceGaussians& g, size_t i) { return g.index ? g.index[i] : i; }

// A Gaussian projected for the pass: culled by the near plane and the image bounds, its α ≥ 1/255
// box (clipped, pixel centres) and the tiles of that box within its 3σ square — the CPU
// reference's rule (src/gaussians/raster_projection.cpp). False: no pixel of the image sees it.
// The projection (raster_projection.cu) and the training batch's selection (train_select.cu)
// both ask it, so the selection keeps exactly what a pass of its views could bin.
struct Footprint {
  gs::ProjectedGaussian<float> p;
  float opacity;
  int box[4];  // x0 y0 x1 y1
  TileRect rect;
};
__device__ __forceinline__ bool project_footprint(const DeviceGaussians& g, size_t e, const gs::CameraView<float>& cam,
                                                  Footprint* f) {
  if (!gs::project_gaussian(g.position + 3 * e, g.log_scale + 3 * e, g.rotation + 4 * e, cam, &f->p)) return false;
  const gs::ProjectedGaussian<float>& p = f->p;
  f->opacity = g.opacity[e];
  gs::Vec2<float> half;
  if (!gs::alpha_extent(p.cov2d, f->opacity, &half)) return false;
  const int width = cam.K.width, height = cam.K.height;
  const float r = static_cast<float>(p.radius);
  const float fx0 = ceilf(p.mean2d.x - r), fx1 = floorf(p.mean2d.x + r);
  const float fy0 = ceilf(p.mean2d.y - r), fy1 = floorf(p.mean2d.y + r);
  if (!(fx1 >= 0 && fy1 >= 0 && fx0 <= float(width - 1) && fy0 <= float(height - 1))) return false;
  const int px0 = static_cast<int>(fmaxf(0.f, fx0)), px1 = static_cast<int>(fminf(float(width - 1), fx1));
  const int py0 = static_cast<int>(fmaxf(0.f, fy0)), py1 = static_cast<int>(fminf(float(height - 1), fy1));
  const float ax0 = ceilf(p.mean2d.x - half.x), ax1 = floorf(p.mean2d.x + half.x);
  const float ay0 = ceilf(p.mean2d.y - half.y), ay1 = floorf(p.mean2d.y + half.y);
  if (!(ax1 >= 0 && ay1 >= 0 && ax0 <= float(width - 1) && ay0 <= float(height - 1))) return false;
  f->box[0] = static_cast<int>(fmaxf(0.f, ax0)), f->box[2] = static_cast<int>(fminf(float(width - 1), ax1));
  f->box[1] = static_cast<int>(fmaxf(0.f, ay0)), f->box[3] = static_cast<int>(fminf(float(height - 1), ay1));
  f->rect = TileRect{max(px0, f->box[0]) / kTileSize, max(py0, f->box[1]) / kTileSize,
                     min(px1, f->box[2]) / kTileSize, min(py1, f->box[3]) / kTileSize, 0u};
  return f->rect.x0 <= f->rect.x1 && f->rect.y0 <= f->rect.y1;
}
#endif

// Whether a splat's α ≥ 1/255 ellipse reaches tile (tx, ty) of a width × height image: the CPU
// binning's question (src/gaussians/raster_binning.cpp), asked by projection (to count) and by
// the key emission (to emit).
#ifdef __CUDACC__
__device__ __forceinline__ bool tile_reached(const DeviceSplat& s, int tx, int ty, int width, int height) {
  return gs::ellipse_reaches_rect(s.conic, s.mean2d, s.opacity, float(tx * kTileSize), float(ty * kTileSize),
                                  float(min(tx * kTileSize + kTileSize - 1, width - 1)),
                                  float(min(ty * kTileSize + kTileSize - 1, height - 1)));
}
#endif

// A tile's kTileSize² threads as eight warps of 8×4 pixels: warp w takes block (w % 2, w / 2) of
// the tile, lane l pixel (l % 8, l / 8) of it. A compact block meets fewer splat boxes than a
// 16×2 strip, and a warp skips, as one, every splat whose box misses its block (the per-pixel
// results are those of evaluating it: α < 1/255 there).
constexpr int kWarpBlockW = 8, kWarpBlockH = 4;
static_assert(kTileSize * kTileSize == 8 * 32 && kTileSize == 2 * kWarpBlockW && kTileSize == 4 * kWarpBlockH,
              "the thread layout below assumes 16×16 tiles of eight 8×4 warps");

struct TileThread {
  int x, y;               // the thread's pixel (may lie outside the image)
  int bx0, by0, bx1, by1;  // its warp's block, clipped to the image (bx0 > bx1 or by0 > by1: empty)
};

#ifdef __CUDACC__
__device__ __forceinline__ TileThread tile_thread(int tile, int tiles_x, int width, int height) {
  const int warp = static_cast<int>(threadIdx.x) / 32, lane = static_cast<int>(threadIdx.x) % 32;
  TileThread t;
  t.bx0 = (tile % tiles_x) * kTileSize + (warp % 2) * kWarpBlockW;
  t.by0 = (tile / tiles_x) * kTileSize + (warp / 2) * kWarpBlockH;
  t.x = t.bx0 + lane % kWarpBlockW;
  t.y = t.by0 + lane / kWarpBlockW;
  t.bx1 = min(t.bx0 + kWarpBlockW - 1, width - 1);
  t.by1 = min(t.by0 + kWarpBlockH - 1, height - 1);
  return t;
}

// Whether the splat's α box meets the warp's block (false for an empty block).
__device__ __forceinline__ bool box_meets_block(const DeviceSplat& s, const TileThread& t) {
  return t.bx0 <= t.bx1 && t.by0 <= t.by1 && int(s.box[0]) <= t.bx1 && int(s.box[2]) >= t.bx0 &&
         int(s.box[1]) <= t.by1 && int(s.box[3]) >= t.by0;
}
#endif

struct ForwardSettings {
  bool surface_depth = false;
  bool normalise_depth = false;
  float gap_abs = 0.02f, gap_rel = 0.03f;
  uint32_t ins_object = 0;
  const uint32_t* ins_labels = nullptr;  // [P] on the device: per-label `ins` (RenderSettings::ins_labels)
  float background[3] = {0.f, 0.f, 0.f};
};

// What the forward pass keeps per pixel for the backward one (every pointer null: not kept).
struct ForwardState {
  float* t_final = nullptr;          // transmittance after the last contributor
  uint32_t* n_contrib = nullptr;     // list position of the last contributor + 1 (0: none)
  float* depth_raw = nullptr;        // Σ T α z before any normalisation
  gs::SurfaceAccum<float>* surface = nullptr;  // with surface_depth only
};

// Gradients of one Gaussian's screen-space quantities, summed over pixels (float atomics).
struct Grad2D {
  float mean2d[2];
  float conic[3];  // xx xy yy
  float opacity;
  float colour[3];
  float depth;
};

struct ImageGradientsDevice {
  const float* rgb = nullptr;  // [P*3] or null
  const float* depth = nullptr;
  const float* alpha = nullptr;
  const float* ins = nullptr;
};

struct ForwardImages {
  float* rgb = nullptr;  // [P*3]
  float* depth = nullptr;
  float* alpha = nullptr;
  float* ins = nullptr;
  uint32_t* dominant_id = nullptr;
};

// Stage 1: splats[i], rects[i] and tile_count[i] (0: culled) for every Gaussian.
// ins_per_label: every object's opaque Gaussians count for `ins` (ForwardSettings::ins_labels).
// zero_grad2d (may be null): zeroed for every Gaussian with tile_count > 0, for the backward.
void launch_project(const DeviceGaussians& g, const gs::CameraView<float>& cam, uint32_t ins_object, bool ins_per_label,
                    DeviceSplat* splats, TileRect* rects, uint32_t* tile_count, Grad2D* zero_grad2d,
                    cudaStream_t stream);
// A pair's depth key: the depth's float bits less `base` (those of the largest power of two not
// above the near plane, below which nothing is binned), capped at `max`, in the key's low `bits`.
// Positive floats' bits sort as unsigned integers, so 28 bits above the base order 32 octaves of
// depth exactly (near 0.01 m: up to 33 000 km; farther ones tie, by index) — with 12 bits of tile
// a 40-bit key, 5 radix passes of 8 bits instead of the 6 of the float's whole 32.
struct DepthKey {
  uint32_t base;
  int bits;
  uint64_t max;
};
DepthKey depth_key_for(float near);
// Stage 2: one (tile << dk.bits | depth key, index) pair per Gaussian and tile it touches, written
// at offsets[i] (the exclusive scan of tile_count), then (after the sort) each tile's range.
void launch_emit_keys(size_t n, const DeviceSplat* splats, const TileRect* rects, const uint32_t* offsets,
                      int width, int height, const DepthKey& dk, uint64_t* keys, uint32_t* values,
                      cudaStream_t stream);
// Sorts the pairs by the low key_bits of their keys (CUB radix sort; stable, so ties keep the
// index order), into *_out; `temp` grows as needed. Returns the first error (an allocation's
// included).
cudaError_t sort_pairs(size_t pairs, int key_bits, const uint64_t* keys_in, uint64_t* keys_out, const uint32_t* values_in,
                       uint32_t* values_out, void** temp, size_t* temp_bytes, cudaStream_t stream);
// Exclusive scan of tile_count into offsets ([n + 1]: the last is the total); as sort_pairs.
cudaError_t exclusive_scan(size_t n, const uint32_t* tile_count, uint32_t* offsets, void** temp,
                           size_t* temp_bytes, cudaStream_t stream);
void launch_tile_ranges(size_t pairs, const uint64_t* sorted_keys, int depth_bits, uint2* ranges,
                        cudaStream_t stream);
// The tiles, most pairs first (ties in index order), into tile_order: the compositing kernels take
// their blocks' tiles in this order, so the longest lists start first and the last wave on the
// SMs holds short ones (Nsight Compute: a third of the forward kernel's SM time was idle in the
// tail of tiles in image order). `keys` and `ids` are scratch of `tiles` entries.
cudaError_t order_tiles(size_t tiles, const uint2* ranges, uint32_t* keys, uint32_t* ids, uint32_t* keys_out,
                        uint32_t* tile_order, void** temp, size_t* temp_bytes, cudaStream_t stream);
// How the compositing kernels walk a tile's list (raster_forward.cu): staged through shared memory
// by the whole block, or by each warp on its own. The same images and gradients either way; the
// pass picks by its lists' mean length (walk_for()).
enum class WalkOrder { kStaged, kPerWarp };
// From this many pairs a tile on (mean), each warp walks on its own: measured on an H100 over the
// comparison maps (BENCHMARKS.md), the per-warp walk is 8 % faster at 1 220 a tile (2M), even at
// 610 (1M) and 4 % slower at 305 (500k) and on room's training passes.
constexpr double kPerWarpFromPairsPerTile = 900.0;
inline WalkOrder walk_for(size_t pairs, size_t tiles) {
  return static_cast<double>(pairs) >= kPerWarpFromPairsPerTile * static_cast<double>(tiles) ? WalkOrder::kPerWarp
                                                                                             : WalkOrder::kStaged;
}
// Stage 3: one block per tile (taken in tile_order), one thread per pixel, front to back with
// early stop.
void launch_forward(int width, int height, const uint32_t* tile_order, const uint2* ranges,
                    const uint32_t* sorted_ids, const DeviceSplat* splats, const ForwardSettings& settings,
                    const ForwardImages& out, const ForwardState& state, WalkOrder walk, cudaStream_t stream);
// Stage 4: the tile lists walked back to front per pixel, gradients of each Gaussian's 2D
// quantities summed into grad2d ([N], zero for the binned Gaussians); then each binned Gaussian's
// through project_gaussian_vjp() into the attribute gradients (written; the culled ones' zeroed
// with zero_culled, else left as they are).
void launch_backward(int width, int height, const uint32_t* tile_order, const uint2* ranges,
                     const uint32_t* sorted_ids, const DeviceSplat* splats, const ForwardSettings& settings,
                     const ForwardState& state, const ImageGradientsDevice& grad_out, Grad2D* grad2d, WalkOrder walk,
                     cudaStream_t stream);
void launch_project_vjp(const DeviceGaussians& g, const gs::CameraView<float>& cam, const uint32_t* tile_count,
                        const Grad2D* grad2d, float* grad_position, float* grad_log_scale, float* grad_rotation,
                        float* grad_opacity, float* grad_colour, bool zero_culled, cudaStream_t stream);

}  // namespace dqo::cuda::detail
