// The keyframe review on the device (CudaTrainingEngine::review): the probe's output gradient from
// the view's labels, then math/review.h's step for every Gaussian on the colour sums of the
// rasteriser's 2D gradients, the trainer's counters updated in place and the relabels listed; and
// the relabels the host then makes, applied to the device's object IDs.

#include "train_cuda.h"

namespace dqo::cuda::detail {

namespace {

constexpr int kBlock = 256;

unsigned blocks(size_t n) { return static_cast<unsigned>((n + kBlock - 1) / kBlock); }

__global__ void review_probe_kernel(size_t pixels, const uint32_t* labels, float* v_rgb) {
  const size_t p = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (p >= pixels) return;
  const bool object = labels[p] != 0;
  v_rgb[3 * p] = 1.f;
  v_rgb[3 * p + 1] = object ? 0.f : 1.f;
  v_rgb[3 * p + 2] = object ? 1.f : 0.f;
}

__global__ void review_kernel(size_t n, const float* position, const uint32_t* object_id, const uint32_t* tile_count,
                              const Grad2D* grad2d, gs::ReviewView view, gs::ReviewSettings settings,
                              float* usefulness, uint16_t* invisible, uint8_t* votes, uint2* relabels,
                              uint32_t* relabel_count) {
  const size_t i = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= n) return;
  float sums[3] = {0.f, 0.f, 0.f};  // a Gaussian the pass culled reached no pixel
  if (tile_count[i] > 0) {
    const Grad2D& g = grad2d[i];
    sums[0] = g.colour[0], sums[1] = g.colour[1], sums[2] = g.colour[2];
  }
  uint32_t new_label = 0;
  if (!gs::review_gaussian(view, settings, position + 3 * i, object_id[i], sums, usefulness + i, invisible + i,
                           votes + i, &new_label))
    return;
  votes[i] = 0;
  const uint32_t k = atomicAdd(relabel_count, 1u);
  relabels[k] = make_uint2(static_cast<uint32_t>(i), new_label);  // room for n: never out of bounds
}

__global__ void apply_relabels_kernel(size_t count, const uint2* pairs, uint32_t* object_id) {
  const size_t k = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (k < count) object_id[pairs[k].x] = pairs[k].y;
}

__global__ void start_counters_kernel(size_t from, size_t n, float* usefulness, uint16_t* invisible, uint8_t* votes) {
  const size_t i = from + static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= n) return;
  usefulness[i] = INFINITY;
  invisible[i] = 0;
  votes[i] = 0;
}

}  // namespace

void launch_review_probe(size_t pixels, const uint32_t* labels, float* v_rgb, cudaStream_t stream) {
  if (pixels == 0) return;
  review_probe_kernel<<<blocks(pixels), kBlock, 0, stream>>>(pixels, labels, v_rgb);
}

void launch_start_counters(size_t from, size_t n, float* usefulness, uint16_t* invisible, uint8_t* votes,
                           cudaStream_t stream) {
  if (n <= from) return;
  start_counters_kernel<<<blocks(n - from), kBlock, 0, stream>>>(from, n, usefulness, invisible, votes);
}

void launch_review(size_t n, const float* position, const uint32_t* object_id, const uint32_t* tile_count,
                   const Grad2D* grad2d, const gs::ReviewView& view, const gs::ReviewSettings& settings,
                   float* usefulness, uint16_t* invisible, uint8_t* votes, uint2* relabels, uint32_t* relabel_count,
                   cudaStream_t stream) {
  if (n == 0) return;
  review_kernel<<<blocks(n), kBlock, 0, stream>>>(n, position, object_id, tile_count, grad2d, view, settings,
                                                  usefulness, invisible, votes, relabels, relabel_count);
}

void launch_apply_relabels(size_t count, const uint2* pairs, uint32_t* object_id, cudaStream_t stream) {
  if (count == 0) return;
  apply_relabels_kernel<<<blocks(count), kBlock, 0, stream>>>(count, pairs, object_id);
}

}  // namespace dqo::cuda::detail
