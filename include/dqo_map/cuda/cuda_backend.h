#pragma once
// The mapping stage's GPU backend: a CUDA rasteriser and a CUDA training engine that share the
// engine's device copy of the map (cuda/train/resident_map.h). The trainer's renders of the map it
// trains (the review of each keyframe, the masks, the budget's render) then use that copy instead
// of sending the map across the bus; renders of any other map, or of one changed since the engine
// last saw it, upload it as make_cuda_rasteriser()'s do. Because every render of the trained map
// shows the engine's copy, this engine alone may keep the trained attributes on the device between
// batches (TrainingEngine::defer_attributes); a lone make_cuda_training_engine() does not.

#include <memory>

#include "dqo_map/gaussians/rasteriser.h"
#include "dqo_map/gaussians/training_engine.h"

namespace dqo::cuda {

struct CudaBackend {
  std::unique_ptr<gs::Rasteriser> rasteriser;
  std::unique_ptr<gs::TrainingEngine> engine;
};

// Throws std::runtime_error when no GPU can be used.
CudaBackend make_cuda_backend();

}  // namespace dqo::cuda
