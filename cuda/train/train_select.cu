// The training batch's selection (CudaTrainingEngine::run): the Gaussians that at least one of the
// batch's views can bin, as an ascending index list the batch's passes work on. A Gaussian that no
// view reaches gets no gradient and so cannot move: leaving it out changes nothing but the cost of
// the passes, which then grows with what the window sees rather than with the map (issue 12: the
// keyframe update flat as the map grows).

#include <algorithm>

#include "train_cuda.h"

namespace dqo::cuda::detail {

namespace {

constexpr int kBlock = 256;
constexpr size_t kViewsPerLaunch = 8;  // the cameras travel as the kernel's argument

struct ViewSet {
  gs::CameraView<float> cam[kViewsPerLaunch];
  int count;
};

// keep[i] = 1 where some view's projection keeps Gaussian i (the projection's own rule), else 0.
__global__ void flag_in_views_kernel(DeviceGaussians g, ViewSet views, uint32_t* keep) {
  const size_t i = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= g.count) return;
  uint32_t k = keep[i];
  for (int v = 0; v < views.count && !k; ++v) {
    Footprint f;
    k = project_footprint(g, i, views.cam[v], &f) ? 1u : 0u;
  }
  keep[i] = k;
}

// index[offsets[i]] = i for the kept ones: the list in ascending order.
__global__ void list_kept_kernel(size_t n, const uint32_t* keep, const uint32_t* offsets, uint32_t* index) {
  const size_t i = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i < n && keep[i]) index[offsets[i]] = static_cast<uint32_t>(i);
}

}  // namespace

cudaError_t select_in_views(const DeviceGaussians& g, const gs::CameraView<float>* views, size_t view_count,
                            uint32_t* keep, uint32_t* offsets, uint32_t* index, void** temp, size_t* temp_bytes,
                            cudaStream_t stream) {
  if (g.index) return cudaErrorInvalidValue;  // a selection of the whole map
  const size_t n = g.count;
  // n + 1 entries scanned: keep[n] is 0, so offsets[n] is the count.
  cudaError_t err = cudaMemsetAsync(keep, 0, (n + 1) * sizeof(uint32_t), stream);
  if (err != cudaSuccess) return err;
  const unsigned blocks = static_cast<unsigned>((n + kBlock - 1) / kBlock);
  for (size_t first = 0; first < view_count && n > 0; first += kViewsPerLaunch) {
    ViewSet set{};
    set.count = static_cast<int>(std::min(kViewsPerLaunch, view_count - first));
    for (int v = 0; v < set.count; ++v) set.cam[v] = views[first + v];
    flag_in_views_kernel<<<blocks, kBlock, 0, stream>>>(g, set, keep);
  }
  err = cudaGetLastError();
  if (err == cudaSuccess) err = exclusive_scan(n, keep, offsets, temp, temp_bytes, stream);
  if (err != cudaSuccess || n == 0) return err;
  list_kept_kernel<<<blocks, kBlock, 0, stream>>>(n, keep, offsets, index);
  return cudaGetLastError();
}

}  // namespace dqo::cuda::detail
