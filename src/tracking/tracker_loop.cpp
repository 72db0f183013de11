// The tracker's loop closing (loop_closing.h): place recognition for the newest keyframe at the
// start of the next frame, on the tracker's thread (so that the trajectory is the same on any
// machine load), the correction, and the global bundle adjustment after it and at the end of a run.

#include <chrono>

#include "loop_closing.h"
#include "tracker_impl.h"

namespace dqo::tracking {

void Tracker::Impl::close_pending_loop() {
  const uint64_t query = loop_query_;
  loop_query_ = kNoId;
  if (!params_.loop.enabled || query == kNoId || map_.keyframe(query) == nullptr) return;
  const auto start = std::chrono::steady_clock::now();
  ++loop_queries_;
  const LoopDetection loop =
      detect_loop(map_, query, camera_, extractor_.scales(), params_.pose, params_.loop);
  if (loop.found) {
    // An adjustment running on a snapshot from before the correction would undo it: it enters
    // first, at this fixed point.
    if (ba_) {
      ba_->wait_idle();
      apply_ba_results();
      ba_outstanding_ = false;
    }
    const LoopCorrection correction =
        correct_loop(&map_, loop, first_keyframe_, extractor_.scales(), params_.loop);
    if (correction.ok) {
      ++loops_closed_;
      follow_keyframes(correction.moved);
      if (params_.loop.global_ba) run_global_ba(params_.loop.global_ba_iterations);
    }
  }
  loop_milliseconds_ +=
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

void Tracker::Impl::run_global_ba(int iterations) {
  if (map_.num_keyframes() < 2) return;
  LocalBaParams ba_params = params_.local_ba;
  ba_params.iterations = iterations;
  apply_ba_result(solve_local_ba(
      global_ba_problem(map_, first_keyframe_, extractor_.scales(), params_.pose, generation_),
      camera_, ba_params, params_.pose, nullptr));
}

void Tracker::Impl::optimise_map() {
  wait_for_mapping();
  if (params_.loop.final_global_ba) run_global_ba(params_.loop.global_ba_iterations);
}

}  // namespace dqo::tracking
