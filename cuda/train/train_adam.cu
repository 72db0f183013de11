// The CUDA training engine's optimiser step: GaussianAdam::step (src/gaussians/adam.cpp) for the
// Gaussians that GaussianTrainer::iterate would step — unstable, with a non-zero gradient of
// position, colour, scale or rotation — by the same per-value maths (math/adam_step.h), and the
// confidence count that goes with it. One thread per Gaussian.

#include "train_cuda.h"

#include "dqo_map/gaussians/math/adam_step.h"

namespace dqo::cuda::detail {

namespace {

__device__ bool any_nonzero(const float* g, int width) {
  for (int k = 0; k < width; ++k)
    if (g[k] != 0.f) return true;
  return false;
}

__global__ void adam_kernel(DeviceTrainable t, const uint32_t* tile_count, const float* grad_position,
                            const float* grad_log_scale, const float* grad_rotation, const float* grad_colour,
                            AdamRates r) {
  const size_t j = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;  // in the pass
  if (j >= t.count || tile_count[j] == 0) return;
  const size_t i = t.index ? t.index[j] : j;  // in the map
  if (t.stable[i]) return;
  const float* gp = grad_position + 3 * j;
  const float* gs_ = grad_log_scale + 3 * j;
  const float* gq = grad_rotation + 4 * j;
  const float* gc = grad_colour + 3 * j;
  if (!(any_nonzero(gp, 3) || any_nonzero(gc, 3) || any_nonzero(gs_, 3) || any_nonzero(gq, 4))) return;
  const unsigned step = ++t.steps[i];
  const gs::AdamCorrection c = gs::adam_correction(r.beta1, r.beta2, step);
  if (r.lr_position > 0.f)
    gs::adam_update(t.position + 3 * i, t.m[0] + 3 * i, t.v[0] + 3 * i, gp, 3, r.lr_position, r.beta1, r.beta2,
                    r.epsilon, c);
  if (r.lr_log_scale > 0.f)
    gs::adam_update(t.log_scale + 3 * i, t.m[1] + 3 * i, t.v[1] + 3 * i, gs_, 3, r.lr_log_scale, r.beta1, r.beta2,
                    r.epsilon, c);
  if (r.lr_rotation > 0.f) {
    float* q = t.rotation + 4 * i;
    gs::adam_update(q, t.m[2] + 4 * i, t.v[2] + 4 * i, gq, 4, r.lr_rotation, r.beta1, r.beta2, r.epsilon, c);
    if (r.normalise_rotation) gs::normalise_quaternion(q);
  }
  if (r.lr_colour > 0.f) {
    float* rgb = t.colour + 3 * i;
    gs::adam_update(rgb, t.m[3] + 3 * i, t.v[3] + 3 * i, gc, 3, r.lr_colour, r.beta1, r.beta2, r.epsilon, c);
    if (r.clamp_colour) gs::clamp_unit(rgb, 3);
  }
  t.confidence[i] += 1.f;
}

}  // namespace

void launch_adam(const DeviceTrainable& t, const uint32_t* tile_count, const float* grad_position,
                 const float* grad_log_scale, const float* grad_rotation, const float* grad_colour,
                 const AdamRates& rates, cudaStream_t stream) {
  if (t.count == 0) return;
  constexpr int kBlock = 256;
  adam_kernel<<<static_cast<unsigned>((t.count + kBlock - 1) / kBlock), kBlock, 0, stream>>>(
      t, tile_count, grad_position, grad_log_scale, grad_rotation, grad_colour, rates);
}

}  // namespace dqo::cuda::detail
