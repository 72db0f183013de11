#pragma once
// Removal of the removed Gaussians' entries from per-Gaussian arrays by one plan
// (dqo_map/gaussians/removal_plan.h: the holes filled from the end), every array of a map at once.

#include <cstdint>
#include <functional>
#include <vector>

#include "dqo_map/gaussians/removal_plan.h"
#include "parallel.h"

namespace dqo::gs::detail {

// Applies one plan (a mask's, or one made once for several owners) to several arrays: add()
// each, then run().
class Compaction {
 public:
  explicit Compaction(const std::vector<uint8_t>& remove) : own_(plan_removal(remove)), plan_(own_) {}
  explicit Compaction(const RemovalPlan& plan) : plan_(plan) {}
  template <typename T>
  void add(std::vector<T>* values, size_t width) {
    jobs_.push_back([values, width, this] { apply_removal(values, width, plan_); });
  }
  void run() {
    // Few moves on the calling thread: handing them to threads would cost more than them.
    const int threads = plan_.holes.size() < kThreadedFrom ? 1 : resolve_threads(0);
    parallel_for_dynamic(threads, jobs_.size(), [this](size_t k) { jobs_[k](); });
    jobs_.clear();
  }

 private:
  static constexpr size_t kThreadedFrom = 1 << 16;  // moves
  RemovalPlan own_;  // the mask's
  const RemovalPlan& plan_;
  std::vector<std::function<void()>> jobs_;
};

}  // namespace dqo::gs::detail
