#pragma once
// The CUDA training engine (cuda/train/): GaussianTrainer's iterations on the GPU. The map and the
// optimiser state stay on the device from batch to batch (a batch sends the Gaussians appended
// since the last and the stable flags and IDs, and brings back the trained attributes), as do the
// window's images; every iteration runs there (forward, losses, backward, Adam; one wait per
// iteration for the sort's size).

#include <memory>

#include "dqo_map/gaussians/training_engine.h"

namespace dqo::cuda {

// Throws std::runtime_error when no GPU can be used.
std::unique_ptr<gs::TrainingEngine> make_cuda_training_engine();

}  // namespace dqo::cuda
