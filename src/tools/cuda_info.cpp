// dqo_cuda_info: prints the GPUs the CUDA backend sees (used by scripts/gpu_check's table).
#include <cstdio>

#include "dqo_map/cuda/device_info.h"

int main() {
  const auto list = dqo::cuda::list_devices();
  if (list.devices.empty()) {
    std::printf("no GPU: %s\n", list.error.c_str());
    return 1;
  }
  for (const auto& d : list.devices)
    std::printf("gpu %d: %s, sm_%d%d, %d SMs, %.1f GiB (%.1f free)\n", d.index, d.name.c_str(),
                d.compute_major, d.compute_minor, d.multiprocessors, d.memory_gib, d.free_memory_gib);
  return 0;
}
