// The pruning's tests on the device (CudaTrainingEngine::flag_prune): math/prune.h's size test on
// the log-scales the device holds and the invisibility count of the review counters it keeps, one
// flag byte a Gaussian down instead of 12 bytes of log-scales and 2 of counts.

#include "dqo_map/gaussians/math/prune.h"
#include "train_cuda.h"

namespace dqo::cuda::detail {

namespace {

constexpr int kBlock = 256;

__global__ void flag_prune_kernel(size_t n, const float* log_scale, float max_log_scale, const uint16_t* invisible,
                                  int max_invisible, uint8_t* flags) {
  const size_t i = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= n) return;
  uint8_t f = gs::oversized(log_scale + 3 * i, max_log_scale) ? kPruneOversized : 0;
  if (invisible && max_invisible > 0 && invisible[i] >= max_invisible) f |= kPruneInvisible;
  flags[i] = f;
}

}  // namespace

void launch_flag_prune(size_t n, const float* log_scale, float max_log_scale, const uint16_t* invisible,
                       int max_invisible, uint8_t* flags, cudaStream_t stream) {
  if (n == 0) return;
  flag_prune_kernel<<<static_cast<unsigned>((n + kBlock - 1) / kBlock), kBlock, 0, stream>>>(
      n, log_scale, max_log_scale, invisible, max_invisible, flags);
}

}  // namespace dqo::cuda::detail
