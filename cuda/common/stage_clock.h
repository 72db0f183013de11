#pragma once
// GPU time per stage over many passes, without waiting in between: each stage's end is an event
// on the stream, and the time of a stage is the time since the event before it. Read once, when
// the work is done (take()). Off unless enabled: a disabled clock records nothing.
//
// Set DQO_CUDA_STAGE_TIMES=1 to have the training engine log its totals when it is destroyed
// (cuda_training_engine.cpp): where an iteration's time goes, on a real run.
// The events of a batch are read once its work is done (collect()) and kept as running totals.

#include <cuda_runtime.h>

#include <array>
#include <cstddef>
#include <cstdio>
#include <string>
#include <vector>

namespace dqo::cuda::detail {

enum class Stage : int { kUpload, kSelect, kProject, kBin, kComposite, kLosses, kBackward, kAdam, kDownload, kCount };

inline const char* stage_name(Stage s) {
  static const char* const names[] = {"upload", "select",   "project", "bin",     "composite",
                                      "losses", "backward", "adam",    "download"};
  return names[static_cast<int>(s)];
}

class StageClock {
 public:
  static constexpr size_t kStages = static_cast<size_t>(Stage::kCount);

  StageClock() = default;
  StageClock(const StageClock&) = delete;
  StageClock& operator=(const StageClock&) = delete;
  ~StageClock() {
    for (cudaEvent_t e : pool_) cudaEventDestroy(e);
  }

  void enable(bool on) { enabled_ = on; }
  bool enabled() const { return enabled_; }

  // The start of a run of stages (its time goes to no stage: host work before it is not counted).
  void start(cudaStream_t stream) { record(-1, stream); }
  // The end of stage `s`: the time since the previous event is its.
  void end(Stage s, cudaStream_t stream) { record(static_cast<int>(s), stream); }

  // Adds the recorded stages to the totals (waits for the last event) and starts over; a pass is
  // counted per kProject stage (iterations and renders).
  void collect() {
    if (used_ == 0) return;  // nothing recorded (or disabled)
    if (cudaEventSynchronize(pool_[used_ - 1]) == cudaSuccess) {
      for (size_t i = 1; i < used_; ++i) {
        if (stage_[i] < 0) continue;
        float t = 0.f;
        if (cudaEventElapsedTime(&t, pool_[i - 1], pool_[i]) == cudaSuccess) totals_[stage_[i]] += t;
        passes_ += stage_[i] == static_cast<int>(Stage::kProject);
      }
    }
    cudaGetLastError();
    used_ = 0;
    stage_.clear();
  }

  // The totals so far, one line: "N passes (T ms): upload t ms (t per pass), project …".
  std::string summary() const {
    double total = 0.0;
    for (const double ms : totals_) total += ms;
    char head[64];
    std::snprintf(head, sizeof(head), "%zu passes (%.1f ms): ", passes_, total);
    std::string line = head;
    for (size_t s = 0; s < kStages; ++s) {
      char part[96];
      std::snprintf(part, sizeof(part), "%s%s %.1f ms (%.3f per pass)", s ? ", " : "", stage_name(static_cast<Stage>(s)),
                    totals_[s], passes_ ? totals_[s] / static_cast<double>(passes_) : 0.0);
      line += part;
    }
    return line;
  }

 private:
  void record(int stage, cudaStream_t stream) {
    if (!enabled_) return;
    if (used_ == pool_.size()) {
      cudaEvent_t e = nullptr;
      if (cudaEventCreate(&e) != cudaSuccess) {
        cudaGetLastError();
        return;
      }
      pool_.push_back(e);
    }
    if (cudaEventRecord(pool_[used_], stream) != cudaSuccess) {
      cudaGetLastError();
      return;
    }
    stage_.push_back(stage);
    ++used_;
  }

  bool enabled_ = false;
  std::array<double, kStages> totals_{};
  size_t passes_ = 0;
  std::vector<cudaEvent_t> pool_;
  std::vector<int> stage_;
  size_t used_ = 0;
};

}  // namespace dqo::cuda::detail
