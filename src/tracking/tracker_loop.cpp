// The tracker's loop closing (loop_closing.h): place recognition for the newest keyframe at the
// start of the next frame, on the tracker's thread (so that the trajectory is the same on any
// machine load), the correction, and the global bundle adjustment after it and at the end of a run.

#include <chrono>
#include <map>

#include "loop_closing.h"
#include "trajectory_refiner.h"
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
  if (params_.refine.enabled) refine_registered_frames();
}

void Tracker::Impl::refine_registered_frames() {
  std::lock_guard<std::mutex> lock(registry_mutex_);
  // One entry per tracked frame (a frame may be registered under several IDs), in time order.
  std::map<uint64_t, std::vector<uint64_t>> ids_of;  // frame number -> registered IDs
  for (const auto& [id, r] : registered_)
    if (map_.keyframe(r.reference_keyframe) != nullptr) ids_of[r.number].push_back(id);
  std::vector<RefinerFrame> frames;
  std::vector<uint64_t> numbers;
  for (const auto& [number, ids] : ids_of) {
    const RegisteredFrame& r = registered_.at(ids.front());
    RefinerFrame f;
    f.timestamp = r.timestamp;
    f.degraded = r.degraded;
    f.T_wc = map_.keyframe(r.reference_keyframe)->T_wc * r.T_ref_frame;
    if (params_.refine.reregister) {
      std::vector<PoseObservation> observations;
      for (const auto& [point, o] : r.observations) {
        const MapPoint* p = map_.map_point(point);
        if (p == nullptr) continue;
        observations.push_back(o);
        observations.back().p_w = p->p_w;
      }
      if (static_cast<int>(observations.size()) >= params_.min_inliers_ok) {
        const PoseOptimisationResult solved =
            optimise_pose(f.T_wc, observations, camera_, nullptr, params_.pose);
        if (solved.solved && solved.inliers >= params_.min_inliers_ok) f.T_wc = solved.T_wc;
      }
    }
    if (!frames.empty() && f.timestamp <= frames.back().timestamp) continue;  // not in time order
    frames.push_back(f);
    numbers.push_back(number);
  }
  const std::vector<SE3> refined = refine_trajectory(frames, params_.refine);
  for (size_t i = 0; i < numbers.size(); ++i)
    for (const uint64_t id : ids_of.at(numbers[i])) corrections_[id] = refined[i];
}

}  // namespace dqo::tracking
