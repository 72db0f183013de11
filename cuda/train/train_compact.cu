// remove_if() of the resident map (resident_map.cpp) on the device: keep flags from the host's
// removal mask, then each array copied down over the removed Gaussians by the exclusive scan of
// those flags, in the map's order (GaussianMap::remove_if's). One thread per element.

#include "train_cuda.h"

namespace dqo::cuda::detail {

namespace {

constexpr int kBlock = 256;

unsigned blocks(size_t n) { return static_cast<unsigned>((n + kBlock - 1) / kBlock); }

__global__ void keep_flags_kernel(size_t n, const uint8_t* remove, uint32_t* keep) {
  const size_t i = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i < n) keep[i] = remove[i] ? 0u : 1u;
  if (i == n) keep[i] = 0u;  // the scan's extra entry: its offset is the total
}

template <typename T>
__global__ void compact_kernel(size_t n, size_t width, const uint8_t* remove, const uint32_t* offsets, const T* src,
                               T* dst) {
  const size_t e = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (e >= n * width) return;
  const size_t i = e / width;
  if (!remove[i]) dst[static_cast<size_t>(offsets[i]) * width + (e - i * width)] = src[e];
}

}  // namespace

void launch_keep_flags(size_t n, const uint8_t* remove, uint32_t* keep, cudaStream_t stream) {
  keep_flags_kernel<<<blocks(n + 1), kBlock, 0, stream>>>(n, remove, keep);
}

void launch_compact(size_t n, size_t width, const uint8_t* remove, const uint32_t* offsets, const uint32_t* src,
                    uint32_t* dst, cudaStream_t stream) {
  if (n == 0) return;
  compact_kernel<<<blocks(n * width), kBlock, 0, stream>>>(n, width, remove, offsets, src, dst);
}

void launch_compact(size_t n, size_t width, const uint8_t* remove, const uint32_t* offsets, const uint8_t* src,
                    uint8_t* dst, cudaStream_t stream) {
  if (n == 0) return;
  compact_kernel<<<blocks(n * width), kBlock, 0, stream>>>(n, width, remove, offsets, src, dst);
}

}  // namespace dqo::cuda::detail
