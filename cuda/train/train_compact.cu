// remove() of the resident map (resident_map.cpp) on the device: the host's RemovalPlan
// (dqo_map/gaussians/removal_plan.h) applied to each array in place, the holes below the new size
// filled from the kept entries above it, as GaussianMap::remove_if does on the host. One thread
// per moved value.

#include "train_cuda.h"

namespace dqo::cuda::detail {

namespace {

constexpr int kBlock = 256;

unsigned blocks(size_t n) { return static_cast<unsigned>((n + kBlock - 1) / kBlock); }

template <typename T>
__global__ void fill_holes_kernel(size_t moves, size_t width, const uint32_t* holes, const uint32_t* sources, T* a) {
  const size_t e = static_cast<size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (e >= moves * width) return;
  const size_t k = e / width, c = e - k * width;
  a[static_cast<size_t>(holes[k]) * width + c] = a[static_cast<size_t>(sources[k]) * width + c];
}

}  // namespace

void launch_fill_holes(size_t moves, size_t width, const uint32_t* holes, const uint32_t* sources, uint32_t* a,
                       cudaStream_t stream) {
  if (moves == 0) return;
  fill_holes_kernel<<<blocks(moves * width), kBlock, 0, stream>>>(moves, width, holes, sources, a);
}

void launch_fill_holes(size_t moves, size_t width, const uint32_t* holes, const uint32_t* sources, uint16_t* a,
                       cudaStream_t stream) {
  if (moves == 0) return;
  fill_holes_kernel<<<blocks(moves * width), kBlock, 0, stream>>>(moves, width, holes, sources, a);
}

void launch_fill_holes(size_t moves, size_t width, const uint32_t* holes, const uint32_t* sources, uint8_t* a,
                       cudaStream_t stream) {
  if (moves == 0) return;
  fill_holes_kernel<<<blocks(moves * width), kBlock, 0, stream>>>(moves, width, holes, sources, a);
}

}  // namespace dqo::cuda::detail
