#pragma once
// What the CUDA runtime reports about the GPUs of this machine. Plain C++: no CUDA header leaks out.
#include <string>
#include <vector>

namespace dqo::cuda {

struct DeviceInfo {
  int index = 0;
  std::string name;
  int compute_major = 0;
  int compute_minor = 0;
  int multiprocessors = 0;
  double memory_gib = 0.0;
  double free_memory_gib = 0.0;
};

struct DeviceList {
  std::vector<DeviceInfo> devices;
  std::string error;  // why there are none (no driver, no device), empty otherwise
};

// Lists the visible devices; never throws, never aborts on a machine without a GPU.
DeviceList list_devices();

// True when at least one device is usable: GPU tests GTEST_SKIP() otherwise.
bool gpu_available();

}  // namespace dqo::cuda
