// The training batch's selection (CudaTrainingEngine::run): for each view of the batch, the
// Gaussians its projection keeps, as an ascending index list its passes work on. A Gaussian that
// a view does not reach gets no gradient from it: leaving it out of that view's passes changes
// nothing but their cost, which then grows with what the view sees rather than with the map
// (issue 12: the keyframe update flat as the map grows).

#include <algorithm>

#include "train_cuda.h"

namespace dqo::cuda::detail {

namespace {

constexpr int kBlock = 256;

// keep[i] = 1 where the view's projection keeps Gaussian i (the projection's own rule), else 0.
__global__ void flag_in_view_kernel(DeviceGaussians g, gs::CameraView<float> cam, uint32_t* keep) {
  const size_t i = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= g.count) return;
  Footprint f;
  keep[i] = project_footprint(g, i, cam, &f) ? 1u : 0u;
}

// index[offsets[i]] = i for the kept ones: the list in ascending order; its length into *count.
__global__ void list_kept_kernel(size_t n, const uint32_t* keep, const uint32_t* offsets, uint32_t* index,
                                 uint32_t* count) {
  const size_t i = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i < n && keep[i]) index[offsets[i]] = static_cast<uint32_t>(i);
  if (i == 0) *count = offsets[n];
}

}  // namespace

cudaError_t select_in_view(const DeviceGaussians& g, const gs::CameraView<float>& cam, uint32_t* keep,
                           uint32_t* offsets, uint32_t* index, uint32_t* count, void** temp, size_t* temp_bytes,
                           cudaStream_t stream) {
  if (g.index) return cudaErrorInvalidValue;  // a selection of the whole map
  const size_t n = g.count;
  // n + 1 entries scanned: keep[n] is 0, so offsets[n] is the count.
  cudaError_t err = cudaMemsetAsync(keep + n, 0, sizeof(uint32_t), stream);
  if (err != cudaSuccess) return err;
  const unsigned blocks = static_cast<unsigned>((std::max<size_t>(n, 1) + kBlock - 1) / kBlock);
  if (n > 0) flag_in_view_kernel<<<blocks, kBlock, 0, stream>>>(g, cam, keep);
  err = cudaGetLastError();
  if (err == cudaSuccess) err = exclusive_scan(n, keep, offsets, temp, temp_bytes, stream);
  if (err != cudaSuccess) return err;
  list_kept_kernel<<<blocks, kBlock, 0, stream>>>(n, keep, offsets, index, count);
  return cudaGetLastError();
}

}  // namespace dqo::cuda::detail
