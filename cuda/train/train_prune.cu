// The pruning's size test on the device (CudaTrainingEngine::flag_oversized): math/prune.h's test
// for every Gaussian on the log-scales the device holds, one flag byte each down instead of 12
// bytes of log-scales.

#include "dqo_map/gaussians/math/prune.h"
#include "train_cuda.h"

namespace dqo::cuda::detail {

namespace {

constexpr int kBlock = 256;

__global__ void flag_oversized_kernel(size_t n, const float* log_scale, float max_log_scale, uint8_t* flags) {
  const size_t i = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= n) return;
  flags[i] = gs::oversized(log_scale + 3 * i, max_log_scale) ? 1 : 0;
}

}  // namespace

void launch_flag_oversized(size_t n, const float* log_scale, float max_log_scale, uint8_t* flags,
                           cudaStream_t stream) {
  if (n == 0) return;
  flag_oversized_kernel<<<static_cast<unsigned>((n + kBlock - 1) / kBlock), kBlock, 0, stream>>>(
      n, log_scale, max_log_scale, flags);
}

}  // namespace dqo::cuda::detail
