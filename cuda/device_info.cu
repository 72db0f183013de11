#include "dqo_map/cuda/device_info.h"

#include <cuda_runtime.h>

namespace dqo::cuda {

DeviceList list_devices() {
  DeviceList out;
  int count = 0;
  const cudaError_t err = cudaGetDeviceCount(&count);
  if (err != cudaSuccess) {
    out.error = cudaGetErrorString(err);
    cudaGetLastError();  // clear the sticky error so later calls see a clean state
    return out;
  }
  for (int i = 0; i < count; ++i) {
    cudaDeviceProp prop{};
    if (cudaGetDeviceProperties(&prop, i) != cudaSuccess) continue;
    DeviceInfo info;
    info.index = i;
    info.name = prop.name;
    info.compute_major = prop.major;
    info.compute_minor = prop.minor;
    info.multiprocessors = prop.multiProcessorCount;
    info.memory_gib = static_cast<double>(prop.totalGlobalMem) / (1024.0 * 1024.0 * 1024.0);
    size_t free_bytes = 0, total_bytes = 0;
    if (cudaSetDevice(i) == cudaSuccess && cudaMemGetInfo(&free_bytes, &total_bytes) == cudaSuccess)
      info.free_memory_gib = static_cast<double>(free_bytes) / (1024.0 * 1024.0 * 1024.0);
    out.devices.push_back(info);
  }
  if (out.devices.empty() && out.error.empty()) out.error = "no CUDA device";
  return out;
}

bool gpu_available() { return !list_devices().devices.empty(); }

}  // namespace dqo::cuda
