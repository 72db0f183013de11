// The tracker's loop closing (loop_closing.h): place recognition for the newest keyframe at the
// start of the next frame, on the tracker's thread (so that the trajectory is the same on any
// machine load), the correction, and the global bundle adjustment after it and at the end of a run.

#include <chrono>
#include <map>
#include <unordered_map>
#include <unordered_set>

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
  // registered_ changes on this thread only; the lock is for corrections_ (corrected_frames()).
  // One entry per tracked frame (a frame may be registered under several IDs), in time order.
  std::map<uint64_t, std::vector<uint64_t>> ids_of;  // frame number -> registered IDs
  for (const auto& [id, r] : registered_)
    if (map_.keyframe(r.reference_keyframe) != nullptr) ids_of[r.number].push_back(id);
  std::vector<const RegisteredFrame*> frames;
  std::vector<uint64_t> numbers;
  // Frames with dense support (depth captured with the colour) keep their pose relative to their
  // reference keyframe (the global BA moved it): re-estimating them by features alone, or
  // smoothing them, loses the dense precision (the tiny scene: 0.9 mm -> 3-8 mm).
  for (const auto& [number, ids] : ids_of) {
    const RegisteredFrame* r = &registered_.at(ids.front());
    if (!r->features_only) continue;
    if (!frames.empty() && r->timestamp <= frames.back()->timestamp) continue;  // not in time order
    frames.push_back(r);
    numbers.push_back(number);
  }
  const size_t n = frames.size();
  auto follow = [&](size_t i) {
    return map_.keyframe(frames[i]->reference_keyframe)->T_wc * frames[i]->T_ref_frame;
  };
  std::vector<SE3> measured(n);
  std::vector<char> adjusted(n, 0);
  if (params_.refine.full_ba && n > 0) {
    // Bundle adjustment over keyframes and frames together: every ok frame's matches refine the
    // points too (the map has a keyframe every 5-10 frames). Keyframes' own frames are already in.
    std::unordered_set<uint64_t> keyframe_frames;
    for (const auto& [id, kf] : map_.keyframes()) keyframe_frames.insert(kf.frame_number);
    LocalBaProblem problem =
        global_ba_problem(map_, first_keyframe_, extractor_.scales(), params_.pose, generation_);
    std::unordered_map<uint64_t, int> point_index;
    for (size_t i = 0; i < problem.points.size(); ++i)
      point_index.emplace(problem.points[i].id, static_cast<int>(i));
    constexpr uint64_t kFrameBase = uint64_t{1} << 62;  // apart from keyframe IDs
    for (size_t i = 0; i < n; ++i) {
      if (frames[i]->degraded || keyframe_frames.count(numbers[i]) != 0) continue;
      int usable = 0;
      for (const auto& [point, o] : frames[i]->observations) usable += point_index.count(point) != 0;
      if (usable < params_.min_inliers_ok) continue;
      const int slot = static_cast<int>(problem.keyframes.size());
      problem.keyframes.push_back({kFrameBase + numbers[i], follow(i), false});
      for (const auto& [point, o] : frames[i]->observations) {
        const auto it = point_index.find(point);
        if (it == point_index.end()) continue;
        BaObservation b;
        b.keyframe = slot;
        b.point = it->second;
        b.uv = o.uv;
        b.depth = o.depth;
        b.inv_sigma = o.inv_sigma;
        b.depth_sigma = o.depth_sigma;
        problem.observations.push_back(b);
      }
    }
    LocalBaParams ba_params = params_.local_ba;
    ba_params.iterations = params_.loop.global_ba_iterations;
    const LocalBaResult result =
        solve_local_ba(problem, camera_, ba_params, params_.pose, nullptr);
    if (result.ok) {
      std::unordered_map<uint64_t, SE3> poses(result.keyframes.begin(), result.keyframes.end());
      for (size_t i = 0; i < n; ++i) {
        const auto it = poses.find(kFrameBase + numbers[i]);
        if (it == poses.end()) continue;
        measured[i] = it->second;
        adjusted[i] = 1;
      }
      apply_ba_result(result);  // keyframes and points (frame IDs are no keyframes: ignored)
    }
  }
  for (size_t i = 0; i < n; ++i) {
    if (adjusted[i]) continue;
    measured[i] = follow(i);
    if (!params_.refine.reregister) continue;
    std::vector<PoseObservation> observations;
    for (const auto& [point, o] : frames[i]->observations) {
      const MapPoint* p = map_.map_point(point);
      if (p == nullptr) continue;
      observations.push_back(o);
      observations.back().p_w = p->p_w;
    }
    if (static_cast<int>(observations.size()) < params_.min_inliers_ok) continue;
    const PoseOptimisationResult solved =
        optimise_pose(measured[i], observations, camera_, nullptr, params_.pose);
    if (solved.solved && solved.inliers >= params_.min_inliers_ok) measured[i] = solved.T_wc;
  }
  std::vector<RefinerFrame> refiner(n);
  for (size_t i = 0; i < n; ++i) refiner[i] = {frames[i]->timestamp, measured[i], frames[i]->degraded};
  const std::vector<SE3> refined = refine_trajectory(refiner, params_.refine);
  std::lock_guard<std::mutex> lock(registry_mutex_);
  for (size_t i = 0; i < n; ++i)
    for (const uint64_t id : ids_of.at(numbers[i])) corrections_[id] = refined[i];
}

}  // namespace dqo::tracking
