// The CUDA training engine's losses: per pixel, the host trainer's L1 terms (src/gaussians/
// losses.cpp) and their gradients; the sums of absolute errors reduced per block, then added in
// double.

#include "train_cuda.h"

namespace dqo::cuda::detail {

namespace {

constexpr int kBlock = 256;

__device__ float sign_of(float x) { return x > 0.f ? 1.f : (x < 0.f ? -1.f : 0.f); }

__device__ float block_sum(float v, float* scratch) {
  for (int offset = 16; offset > 0; offset /= 2) v += __shfl_down_sync(0xffffffffu, v, offset);
  if (threadIdx.x % 32 == 0) scratch[threadIdx.x / 32] = v;
  __syncthreads();
  float total = 0.f;
  if (threadIdx.x == 0)
    for (int w = 0; w < kBlock / 32; ++w) total += scratch[w];
  __syncthreads();
  return total;
}

__global__ void __launch_bounds__(kBlock)
    losses_kernel(size_t pixels, const float* rgb, const float* depth, const float* ins, DeviceView view,
                  LossFactors f, float* grad_rgb, float* grad_depth, float* grad_ins, double* sums) {
  const size_t p = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  float e_rgb = 0.f, e_depth = 0.f, e_ins = 0.f;
  if (p < pixels) {
    for (int c = 0; c < 3; ++c) {
      const float d = rgb[3 * p + c] - view.rgb[3 * p + c];
      e_rgb += fabsf(d);
      grad_rgb[3 * p + c] = f.rgb * sign_of(d);
    }
    if (grad_depth) {
      const float target = view.depth[p];
      float g = 0.f;
      if (isfinite(target) && target > 0.f) {
        const float e = depth[p] - target;
        e_depth = fabsf(e);
        g = f.depth * sign_of(e);
      }
      grad_depth[p] = g;
    }
    if (grad_ins) {
      const float rendered = ins[p];
      const float e = fminf(rendered, 1.f) - (view.labels[p] == f.object ? 1.f : 0.f);
      e_ins = fabsf(e);
      grad_ins[p] = rendered < 1.f ? f.ins * sign_of(e) : 0.f;
    }
  }
  __shared__ float scratch[kBlock / 32];
  const float s_rgb = block_sum(e_rgb, scratch);
  const float s_depth = block_sum(e_depth, scratch);
  const float s_ins = block_sum(e_ins, scratch);
  if (threadIdx.x == 0) {
    atomicAdd(sums + 0, static_cast<double>(s_rgb));
    if (grad_depth) atomicAdd(sums + 1, static_cast<double>(s_depth));
    if (grad_ins) atomicAdd(sums + 2, static_cast<double>(s_ins));
  }
}

__global__ void unit_colours_kernel(size_t values, const uint8_t* in, float* out) {
  const size_t k = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (k < values) out[k] = in[k] * (1.f / 255.f);  // gs::unit_colour()'s float (losses.h brings Eigen)
}

}  // namespace

void launch_unit_colours(size_t values, const uint8_t* in, float* out, cudaStream_t stream) {
  if (values == 0) return;
  unit_colours_kernel<<<static_cast<unsigned>((values + kBlock - 1) / kBlock), kBlock, 0, stream>>>(values, in, out);
}

void launch_losses(size_t pixels, const float* rgb, const float* depth, const float* ins, const DeviceView& view,
                   const LossFactors& f, float* grad_rgb, float* grad_depth, float* grad_ins, double* sums,
                   cudaStream_t stream) {
  if (pixels == 0) return;
  losses_kernel<<<static_cast<unsigned>((pixels + kBlock - 1) / kBlock), kBlock, 0, stream>>>(
      pixels, rgb, depth, ins, view, f, grad_rgb, grad_depth, grad_ins, sums);
}

}  // namespace dqo::cuda::detail
