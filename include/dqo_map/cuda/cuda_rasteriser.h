#pragma once
// The CUDA rasteriser (cuda/raster/): the Rasteriser interface on the GPU, stage for stage the CPU
// reference's (projection, tile binning with a CUB radix sort, front-to-back compositing) on the
// shared per-Gaussian maths. backward() takes the state of this
// rasteriser's latest forward() only (it keeps that pass's buffers on the device).
// Errors of the CUDA runtime (no device, out of memory) are thrown as std::runtime_error naming
// the step; the rasteriser stays usable after one.

#include <cstddef>
#include <memory>
#include <optional>

#include "dqo_map/gaussians/rasteriser.h"

namespace dqo::cuda {

// Throws std::runtime_error when no GPU can be used.
std::unique_ptr<gs::Rasteriser> make_cuda_rasteriser();

// GPU time of each stage of the last forward() and backward() (CUDA events on its stream), for the
// benchmarks.
struct ForwardTimings {
  double upload_ms = 0, project_ms = 0, bin_ms = 0, composite_ms = 0, download_ms = 0;
  double backward_ms = 0;  // of the latest backward() after it (tile pass + projection VJP), 0 before
  size_t pairs = 0;  // (Gaussian, tile) pairs sorted
  bool resident = false;  // rendered the backend's device copy of the map: nothing was sent
};
// nullopt for a rasteriser that make_cuda_rasteriser() did not make.
std::optional<ForwardTimings> last_forward_timings(const gs::Rasteriser& rasteriser);

}  // namespace dqo::cuda
