#pragma once
// Host-side helpers of the CUDA ring (plain C++ with the CUDA runtime; no kernels): error checks
// that throw, and device arrays that only grow, so that a warm pipeline allocates nothing.

#include <cuda_runtime.h>

#include <algorithm>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

#include "dqo_map/gaussians/rasteriser.h"

namespace dqo::cuda {

// Throws on an error of the CUDA runtime, naming the step: gs::OutOfDeviceMemory when the device
// is full (callers prune and go on), std::runtime_error otherwise. A non-sticky error is cleared
// first, so that the next call can try again.
inline void check(cudaError_t err, const char* what) {
  if (err == cudaSuccess) return;
  cudaGetLastError();
  const std::string message = std::string("CUDA: ") + what + ": " + cudaGetErrorString(err);
  if (err == cudaErrorMemoryAllocation) throw gs::OutOfDeviceMemory(message);
  throw std::runtime_error(message);
}

// Throws std::runtime_error when no CUDA device can be used (the backends' factories).
inline void require_device() {
  int count = 0;
  const cudaError_t err = cudaGetDeviceCount(&count);
  if (err != cudaSuccess || count == 0) {
    cudaGetLastError();
    throw std::runtime_error(std::string("no CUDA device: ") + (err != cudaSuccess ? cudaGetErrorString(err) : "none found"));
  }
}

// A device array that only grows (contents are not kept across a growth).
template <typename T>
class DeviceBuffer {
 public:
  DeviceBuffer() = default;
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
  ~DeviceBuffer() { release(); }
  // Room for n elements. A buffer that grows again takes a quarter more than asked (where the
  // device has it): the per-Gaussian scratch follows a growing map, and each reallocation waits for
  // the device (cudaFree) — a dozen of them a keyframe otherwise.
  T* ensure(size_t n, const char* what) {
    if (n <= capacity_ && ptr_) return ptr_;
    const size_t exact = std::max<size_t>(n, 1);
    const size_t roomy = ptr_ ? std::max(exact, capacity_ + capacity_ / 4) : exact;
    release();
    if (roomy > exact && cudaMalloc(reinterpret_cast<void**>(&ptr_), roomy * sizeof(T)) == cudaSuccess) {
      capacity_ = roomy;
      return ptr_;
    }
    if (roomy > exact) cudaGetLastError();  // clears the failed allocation's error; the exact size next
    ptr_ = nullptr;
    check(cudaMalloc(reinterpret_cast<void**>(&ptr_), exact * sizeof(T)), what);
    capacity_ = exact;
    return ptr_;
  }
  void release() {
    if (ptr_) cudaFree(ptr_);
    ptr_ = nullptr;
    capacity_ = 0;
  }
  T* get() const { return ptr_; }
  size_t capacity() const { return capacity_; }
  size_t bytes() const { return capacity_ * sizeof(T); }
  void swap(DeviceBuffer& other) noexcept {
    std::swap(ptr_, other.ptr_);
    std::swap(capacity_, other.capacity_);
  }

 private:
  T* ptr_ = nullptr;
  size_t capacity_ = 0;
};

template <typename T>
T* upload(DeviceBuffer<T>* buffer, const std::vector<T>& host, const char* what, cudaStream_t stream) {
  T* d = buffer->ensure(host.size(), what);
  if (!host.empty())
    check(cudaMemcpyAsync(d, host.data(), host.size() * sizeof(T), cudaMemcpyHostToDevice, stream), what);
  return d;
}

template <typename T>
void download(std::vector<T>* host, const T* device, size_t n, cudaStream_t stream) {
  host->resize(n);
  if (n) check(cudaMemcpyAsync(host->data(), device, n * sizeof(T), cudaMemcpyDeviceToHost, stream), "download");
}

}  // namespace dqo::cuda
