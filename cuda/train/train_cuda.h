#pragma once
// Kernels of the CUDA training engine (cuda_training_engine.cpp sequences them around the
// rasteriser's device pipeline): the per-pixel losses with their output gradients, and the sparse
// Adam step with the confidence count. The per-value maths is the host trainer's (losses.cpp,
// math/adam_step.h).

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

#include "../raster/raster_cuda.h"
#include "dqo_map/gaussians/math/review.h"

namespace dqo::cuda::detail {

// One training view's images on the device.
struct DeviceView {
  const float* rgb = nullptr;       // [P*3] in [0, 1]
  const float* depth = nullptr;     // [P] metres; 0 / NaN: none
  const uint32_t* labels = nullptr; // [P]
};

struct LossFactors {
  float rgb = 0.f;    // dL/d(rgb) magnitude per value: 1 / (3 P)
  float depth = 0.f;  // λ_d / (pixels with depth); 0: no depth term
  float ins = 0.f;    // λ_ins / P; 0 or object 0: no instance term
  uint32_t object = 0;
};

// Per pixel: the L1 colour, depth and instance terms of the rendered images against the view
// (the host's l1_rgb_loss, l1_depth_loss, ins_loss with unit weights), their gradients written to
// grad_* (every pixel; grad_depth / grad_ins may be null when their factor is 0), and the three
// sums of absolute errors added to sums[0..2] (double atomics).
void launch_losses(size_t pixels, const float* rgb, const float* depth, const float* ins, const DeviceView& view,
                   const LossFactors& f, float* grad_rgb, float* grad_depth, float* grad_ins, double* sums,
                   cudaStream_t stream);
// The colour target of a view from its 8-bit image: value / 255, the float to_float_rgb() makes.
void launch_unit_colours(size_t values, const uint8_t* in, float* out, cudaStream_t stream);

struct AdamRates {
  float lr_position, lr_log_scale, lr_rotation, lr_colour;
  float beta1, beta2, epsilon;
  bool normalise_rotation, clamp_colour;
};

// The trainable map and its optimiser state on the device.
struct DeviceTrainable {
  // As DeviceGaussians: the pass's Gaussians are entries index[0 .. count) (ascending), or the
  // first `count` when null; the gradients and tile counts are indexed by position in the list.
  size_t count = 0;
  const uint32_t* index = nullptr;
  float* position = nullptr;    // [N*3]
  float* log_scale = nullptr;   // [N*3]
  float* rotation = nullptr;    // [N*4]
  float* colour = nullptr;      // [N*3]
  float* confidence = nullptr;  // [N]
  const uint8_t* stable = nullptr;  // [N]
  float* m[4] = {};  // first moments: position, log-scale, rotation, colour
  float* v[4] = {};  // second moments
  uint32_t* steps = nullptr;  // [N]
};

// One step on every unstable Gaussian with a non-zero gradient (GaussianTrainer::iterate's rule).
// tile_count: the pass's (RasterPipeline::tile_counts()); the Gaussians it culled have no gradient
// and are skipped without reading theirs (left unzeroed by the backward pass).
void launch_adam(const DeviceTrainable& t, const uint32_t* tile_count, const float* grad_position,
                 const float* grad_log_scale, const float* grad_rotation, const float* grad_colour,
                 const AdamRates& rates, cudaStream_t stream);

// The training batch's selection (train_select.cu): into index[0 .. *count) (ascending), the
// Gaussians of g (all n of the map: g.index null) that project_footprint() keeps in the view —
// all that its passes can bin; the others get no gradient from it, so a pass that works on the
// list alone trains as one on the whole map. keep and offsets hold n + 1 entries of scratch
// (keep[i]: selected), index n; temp is the scan's scratch, grown as needed (raster_binning.cu's
// exclusive_scan). Asynchronous: *count is on the device.
cudaError_t select_in_view(const DeviceGaussians& g, const gs::CameraView<float>& cam, uint32_t* keep,
                           uint32_t* offsets, uint32_t* index, uint32_t* count, void** temp, size_t* temp_bytes,
                           cudaStream_t stream);

// Sets object_id[pairs[k].x] = pairs[k].y for k < count: the host's relabelling (GaussianMap::
// relabel_each) applied to the device's copy instead of sending every ID again (train_review.cu).
void launch_apply_relabels(size_t count, const uint2* pairs, uint32_t* object_id, cudaStream_t stream);

// The resident map's remove() (train_compact.cu), by the host's RemovalPlan
// (dqo_map/gaussians/removal_plan.h): a[holes[k]·width + c] = a[sources[k]·width + c] for every
// k < moves, c < width, in place (holes lie below the new size, sources at or above it: no entry
// is both read and written); for 4-byte (float bits too) and 1-byte values.
void launch_fill_holes(size_t moves, size_t width, const uint32_t* holes, const uint32_t* sources, uint32_t* a,
                       cudaStream_t stream);
void launch_fill_holes(size_t moves, size_t width, const uint32_t* holes, const uint32_t* sources, uint16_t* a,
                       cudaStream_t stream);
void launch_fill_holes(size_t moves, size_t width, const uint32_t* holes, const uint32_t* sources, uint8_t* a,
                       cudaStream_t stream);

// The pruning's tests (train_prune.cu): flags[i] = kPruneOversized where gs::oversized(log_scale +
// 3i, max_log_scale), | kPruneInvisible where invisible (may be null: not tested) holds at least
// max_invisible (> 0).
constexpr uint8_t kPruneOversized = 1, kPruneInvisible = 2;
void launch_flag_prune(size_t n, const float* log_scale, float max_log_scale, const uint16_t* invisible,
                       int max_invisible, uint8_t* flags, cudaStream_t stream);

// The review counters of Gaussians [from, n) as the trainer starts them: usefulness +inf (not yet
// measured), no invisible keyframes, no votes (train_review.cu).
void launch_start_counters(size_t from, size_t n, float* usefulness, uint16_t* invisible, uint8_t* votes,
                           cudaStream_t stream);

// The keyframe review on the device (train_review.cu). The probe's output gradient per pixel:
// v_rgb = (1, [label = 0], [label != 0]).
void launch_review_probe(size_t pixels, const uint32_t* labels, float* v_rgb, cudaStream_t stream);
// math/review.h's step for each of n Gaussians, with the colour sums of grad2d (zero where
// tile_count is 0: the pass culled it); `view`'s depth and labels on the device. Each relabel
// appends (index, new label) at atomicAdd(relabel_count), in no particular order, and starts the
// Gaussian's votes over (as GaussianTrainer's relabelling does).
void launch_review(size_t n, const float* position, const uint32_t* object_id, const uint32_t* tile_count,
                   const Grad2D* grad2d, const gs::ReviewView& view, const gs::ReviewSettings& settings,
                   float* usefulness, uint16_t* invisible, uint8_t* votes, uint2* relabels, uint32_t* relabel_count,
                   cudaStream_t stream);

}  // namespace dqo::cuda::detail
