// The GPU backend (cuda_backend.h): one resident map, shared by the rasteriser and the engine.

#include "dqo_map/cuda/cuda_backend.h"

#include <memory>

#include "train/resident_map.h"

namespace dqo::cuda {

CudaBackend make_cuda_backend() {
  auto resident = std::make_shared<detail::ResidentMap>();
  CudaBackend b;
  b.rasteriser = detail::make_cuda_rasteriser_sharing(resident);
  b.engine = detail::make_cuda_training_engine_sharing(resident);
  return b;
}

}  // namespace dqo::cuda
