#pragma once
// The CUDA rasteriser (cuda/raster/): the Rasteriser interface on the GPU, stage for stage the CPU
// reference's (projection, tile binning with a CUB radix sort, front-to-back compositing) on the
// shared per-Gaussian maths. Work in progress (issue 12): forward only so far; backward() throws.
// Errors of the CUDA runtime (no device, out of memory) are thrown as std::runtime_error naming
// the step; the rasteriser stays usable after one.

#include <memory>

#include "dqo_map/gaussians/rasteriser.h"

namespace dqo::cuda {

// Throws std::runtime_error when no GPU can be used.
std::unique_ptr<gs::Rasteriser> make_cuda_rasteriser();

}  // namespace dqo::cuda
