#pragma once
// Removal of the removed Gaussians' entries from per-Gaussian arrays, in place and in order (the
// map's arrays, the optimiser's moments), every array at once on threads of its own: at a million
// Gaussians the map and its optimiser state are about 200 MB to move, 60 ms on one core.

#include <algorithm>
#include <cstdint>
#include <functional>
#include <vector>

#include "parallel.h"

namespace dqo::gs::detail {

// Keeps the `width` values of every item i with remove[i] == 0.
template <typename T>
void compact(std::vector<T>* values, size_t width, const std::vector<uint8_t>& remove) {
  size_t out = 0;
  for (size_t i = 0; i < remove.size(); ++i) {
    if (remove[i]) continue;
    if (out != i) std::copy_n(values->begin() + i * width, width, values->begin() + out * width);
    ++out;
  }
  values->resize(out * width);
}

// Compacts several arrays by one mask: add() each, then run().
class Compaction {
 public:
  explicit Compaction(const std::vector<uint8_t>& remove) : remove_(remove) {}
  template <typename T>
  void add(std::vector<T>* values, size_t width) {
    jobs_.push_back([values, width, this] { compact(values, width, remove_); });
  }
  void run() {
    // Small maps on the calling thread: handing the copies to threads would cost more than them.
    const int threads = remove_.size() < kThreadedFrom ? 1 : resolve_threads(0);
    parallel_for_dynamic(threads, jobs_.size(), [this](size_t k) { jobs_[k](); });
    jobs_.clear();
  }

 private:
  static constexpr size_t kThreadedFrom = 1 << 16;  // Gaussians
  const std::vector<uint8_t>& remove_;
  std::vector<std::function<void()>> jobs_;
};

}  // namespace dqo::gs::detail
