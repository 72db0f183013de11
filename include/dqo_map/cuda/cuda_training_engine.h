#pragma once
// The CUDA training engine (cuda/train/): GaussianTrainer's iterations on the GPU. A batch uploads
// the map and the optimiser state once, keeps the window's images on the device from batch to
// batch, runs every iteration there (forward, losses, backward, Adam; one wait per iteration for
// the sort's size) and brings the map back once.

#include <memory>

#include "dqo_map/gaussians/training_engine.h"

namespace dqo::cuda {

// Throws std::runtime_error when no GPU can be used.
std::unique_ptr<gs::TrainingEngine> make_cuda_training_engine();

}  // namespace dqo::cuda
