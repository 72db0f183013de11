// The tracker's own map: ORB-SLAM2's RGB-D keyframe policy, map points created from keypoint
// depth and culled when rarely re-found, the local BA hand-over (snapshot out, result back on the
// tracker's thread), and the registered frames that follow their reference keyframe.

#include <algorithm>
#include <cmath>
#include <unordered_set>

#include <Eigen/Eigenvalues>

#include "tracker_impl.h"

namespace dqo::tracking {
namespace {

double rotation_angle_deg(const SE3& T) {
  const double w = std::min(1.0, std::abs(T.quaternion().w()));
  return 2.0 * std::acos(w) * 180.0 / M_PI;
}

}  // namespace

bool Tracker::Impl::need_keyframe(const TrackedFrame& frame, int inliers,
                                  bool features_ok) const {
  if (map_.num_keyframes() == 0) return true;
  const KeyFrame* last_kf = map_.keyframe(last_keyframe_);
  if (last_kf == nullptr) return true;
  const KeyframeParams& p = params_.keyframes;
  if (!features_ok) {
    // Dense alone holds the pose: keep the map up with the camera so that features, when they
    // come back, have points to match.
    const SE3 delta = last_kf->T_wc.inverse() * frame.T_wc;
    return delta.translation().norm() > p.weak_translation_m ||
           rotation_angle_deg(delta) > p.weak_rotation_deg;
  }
  const uint64_t since = frame.number - last_keyframe_frame_;
  const int keyframes = static_cast<int>(map_.num_keyframes());
  // Right after relocalisation the pose is not yet worth a keyframe (once the map is big).
  if (frame.number < last_relocalised_frame_ + static_cast<uint64_t>(p.max_frames) &&
      keyframes > p.max_frames)
    return false;

  // Observations count keyframes here (ORB-SLAM2 counts an RGB-D observation twice).
  const int reference_tracked = map_.tracked_points(reference_keyframe_, keyframes <= 2 ? 1 : 2);
  int tracked_close = 0, untracked_close = 0;
  for (size_t k = 0; k < frame.features.size(); ++k) {
    const float z = frame.features.keypoints[k].depth;
    if (z <= 0.0f || z > params_.orb.max_depth) continue;
    if (frame.map_points[k] != kNoId) {
      ++tracked_close;
    } else {
      ++untracked_close;
    }
  }
  const bool need_close = tracked_close < p.min_close_points && untracked_close > 70;
  const double ratio = keyframes < 2 ? 0.4 : p.min_tracked_ratio;
  const bool mapping_idle = this->mapping_idle();
  const bool c1a = since >= static_cast<uint64_t>(p.max_frames);
  const bool c1b = since >= static_cast<uint64_t>(p.min_frames) && mapping_idle;
  const bool c1c = inliers < 0.25 * reference_tracked || need_close;
  const bool c2 = (inliers < ratio * reference_tracked || need_close) && inliers > 15;
  // Far from the last keyframe (wide baselines: every 10th frame of a hand-held sweep moves
  // 15-30 cm): a keyframe whatever the mapping's state, or the next frame finds nothing of the map
  // in view to match against.
  const SE3 moved = last_kf->T_wc.inverse() * frame.T_wc;
  const bool c1d = moved.translation().norm() > p.far_translation_m ||
                   rotation_angle_deg(moved) > p.far_rotation_deg;
  return (c1a || c1b || c1c || c1d) && c2;
}

void Tracker::Impl::create_keyframe(TrackedFrame* frame) {
  KeyFrame kf;
  kf.frame_number = frame->number;
  kf.T_wc = frame->T_wc;
  kf.features = frame->features;
  kf.map_points.assign(frame->features.size(), kNoId);
  const KeyFrame* previous = map_.keyframe(last_keyframe_);
  if (odometry_valid_ && previous != nullptr) {
    kf.odometry_from = previous->id;
    kf.T_odometry = previous->T_wc.inverse() * frame->T_wc;
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(odometry_covariance_);
    const Eigen::Matrix<double, 6, 1> inv = eig.eigenvalues().cwiseMax(1e-12).cwiseInverse();
    kf.odometry_information = eig.eigenvectors() * inv.asDiagonal() * eig.eigenvectors().transpose();
  }
  odometry_covariance_.setZero();
  odometry_valid_ = params_.use_dense;
  const uint64_t id = map_.add_keyframe(std::move(kf));
  for (size_t k = 0; k < frame->map_points.size(); ++k) {
    const uint64_t point = frame->map_points[k];
    if (map_.map_point(point) == nullptr) {
      frame->map_points[k] = kNoId;
      continue;
    }
    map_.add_observation(point, id, static_cast<int>(k));
    map_.update_point_appearance(point, extractor_.scales());
  }
  cull_recent_points();
  create_points(id, frame);
  map_.update_covisibility(id);
  if (first_keyframe_ == kNoId) first_keyframe_ = id;
  last_keyframe_ = id;
  last_keyframe_frame_ = frame->number;
  reference_keyframe_ = id;
  run_local_ba(id);
  loop_query_ = id;  // place recognition at the start of the next frame (tracker_loop.cpp)
}

void Tracker::Impl::create_points(uint64_t keyframe_id, TrackedFrame* frame) {
  // Unmatched keypoints with depth become points, the nearest first (their depth is the most
  // precise: σ grows with z²).
  std::vector<std::pair<float, int>> fresh;
  for (size_t k = 0; k < frame->features.size(); ++k) {
    const float z = frame->features.keypoints[k].depth;
    if (z > 0.0f && z <= params_.orb.max_depth && frame->map_points[k] == kNoId)
      fresh.emplace_back(z, static_cast<int>(k));
  }
  std::sort(fresh.begin(), fresh.end());
  const size_t limit = map_.num_keyframes() <= 1
                           ? fresh.size()  // the first keyframe takes everything it has
                           : static_cast<size_t>(std::max(0, params_.keyframes.max_new_points));
  if (fresh.size() > limit) fresh.resize(limit);
  for (const auto& [z, k] : fresh) {
    MapPoint point;
    point.p_w = frame->T_wc * frame->features.point_c(k, camera_);
    point.descriptor = frame->features.descriptors[k];
    point.first_keyframe = keyframe_id;
    const uint64_t id = map_.add_map_point(point);
    map_.add_observation(id, keyframe_id, k);
    map_.update_point_appearance(id, extractor_.scales());
    frame->map_points[k] = id;
    recent_points_.push_back(id);
  }
}

void Tracker::Impl::cull_recent_points() {
  // ORB-SLAM2's MapPointCulling: a new point must keep being found where it should be seen and
  // be matched by a second keyframe soon, or it was noise (or a duplicate).
  const uint64_t now = map_.keyframes_created();
  size_t out = 0;
  for (const uint64_t id : recent_points_) {
    const MapPoint* p = map_.map_point(id);
    if (p == nullptr) continue;
    const uint64_t age = now - p->created_at_keyframe_count;
    if (p->found_ratio() < 0.25f || (age >= 2 && p->observations.size() < 2)) {
      map_.erase_map_point(id);
      continue;
    }
    if (age >= 3) continue;  // survived: no longer on probation
    recent_points_[out++] = id;
  }
  recent_points_.resize(out);
}

void Tracker::Impl::count_found(const TrackedFrame& frame) {
  for (const uint64_t id : frame.map_points)
    if (MapPoint* p = map_.map_point(id)) ++p->found;
}

LocalBaProblem Tracker::Impl::local_ba_problem(uint64_t keyframe_id) const {
  LocalBaProblem problem;
  problem.generation = generation_;
  std::unordered_map<uint64_t, int> index;
  auto add_keyframe = [&](uint64_t id, bool fixed) {
    const KeyFrame* kf = map_.keyframe(id);
    if (kf == nullptr || index.count(id) != 0) return;
    index.emplace(id, static_cast<int>(problem.keyframes.size()));
    problem.keyframes.push_back({id, kf->T_wc, fixed || id == first_keyframe_});
  };
  add_keyframe(keyframe_id, false);
  for (const uint64_t id :
       map_.covisible(keyframe_id, static_cast<size_t>(params_.local_ba.covisible_keyframes)))
    add_keyframe(id, false);

  // The window's points, and the keyframes outside it that see them (held fixed, the most
  // sharing first: they anchor the window to the rest of the map).
  std::unordered_set<uint64_t> seen;
  std::unordered_map<uint64_t, int> outside;
  const size_t window = problem.keyframes.size();
  for (size_t i = 0; i < window; ++i) {
    for (const uint64_t id : map_.keyframe(problem.keyframes[i].id)->map_points) {
      const MapPoint* p = map_.map_point(id);
      if (p == nullptr || !seen.insert(id).second) continue;
      problem.points.push_back({id, p->p_w});
      for (const auto& [kf, k] : p->observations)
        if (index.count(kf) == 0) ++outside[kf];
    }
  }
  std::vector<std::pair<int, uint64_t>> fixed;
  for (const auto& [kf, n] : outside) fixed.emplace_back(n, kf);
  std::sort(fixed.begin(), fixed.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second < b.second;
  });
  const size_t max_fixed = static_cast<size_t>(std::max(0, params_.local_ba.fixed_keyframes));
  for (size_t i = 0; i < fixed.size() && i < max_fixed; ++i) add_keyframe(fixed[i].second, true);

  // Dense odometry from each window keyframe's predecessor, which joins (held fixed) if it is
  // not in the window already.
  for (size_t i = 0; i < window; ++i) {
    const KeyFrame* kf = map_.keyframe(problem.keyframes[i].id);
    if (kf->odometry_from == kNoId || map_.keyframe(kf->odometry_from) == nullptr) continue;
    add_keyframe(kf->odometry_from, true);
    problem.odometry.push_back({index.at(kf->odometry_from), static_cast<int>(i), kf->T_odometry,
                                kf->odometry_information});
  }

  // Gauge: something must hold still, or the window floats (rank-deficient by 6).
  const bool any_fixed = std::any_of(problem.keyframes.begin(), problem.keyframes.end(),
                                     [](const BaKeyframe& k) { return k.fixed; });
  if (!any_fixed && !problem.keyframes.empty()) {
    auto oldest = std::min_element(problem.keyframes.begin(), problem.keyframes.end(),
                                   [](const BaKeyframe& a, const BaKeyframe& b) { return a.id < b.id; });
    oldest->fixed = true;
  }

  const ScalePyramid& scales = extractor_.scales();
  for (size_t pi = 0; pi < problem.points.size(); ++pi) {
    const MapPoint* p = map_.map_point(problem.points[pi].id);
    for (const auto& [kf_id, k] : p->observations) {
      const auto it = index.find(kf_id);
      if (it == index.end()) continue;
      const Keypoint& kp = map_.keyframe(kf_id)->features.keypoints[k];
      BaObservation o;
      o.keyframe = it->second;
      o.point = static_cast<int>(pi);
      o.uv = kp.uv.cast<double>();
      o.depth = kp.depth;
      o.inv_sigma = scales.inv_scale[kp.octave];
      o.depth_sigma =
          keypoint_depth_sigma(kp.depth, kp.depth_slope, scales.scale[kp.octave], params_.pose,
                               kp.depth_sync_sigma);
      problem.observations.push_back(o);
    }
  }
  if (params_.objects.enabled) {
    for (size_t i = 0; i < problem.keyframes.size(); ++i) {
      if (problem.keyframes[i].fixed) continue;
      objects_.observations(problem.keyframes[i].id, static_cast<int>(i), problem.keyframes[i].T_wc,
                            camera_, params_.objects, &problem.objects);
    }
  }
  return problem;
}

void Tracker::Impl::run_local_ba(uint64_t keyframe_id) {
  if (!params_.local_ba.enabled || map_.num_keyframes() < 2) return;
  if (params_.local_ba.synchronous) {
    apply_ba_result(solve_local_ba(local_ba_problem(keyframe_id), camera_, params_.local_ba,
                                   params_.pose, nullptr));
    return;
  }
  // The snapshot is taken when the worker is free, after the previous result is in the map: a
  // snapshot queued behind a running adjustment would be stale when it starts and undo it.
  ba_wanted_ = keyframe_id;
  submit_local_ba();
}

bool Tracker::Impl::mapping_idle() const {
  if (!ba_) return true;
  // Deterministic: whether the thread has finished depends on the machine's load; whether its
  // result has been applied does not.
  return params_.local_ba.deterministic ? !ba_outstanding_ : !ba_->busy();
}

void Tracker::Impl::submit_local_ba() {
  if (!ba_ || ba_wanted_ == kNoId || !mapping_idle()) return;
  if (!params_.local_ba.deterministic) apply_ba_results();
  if (map_.keyframe(ba_wanted_) != nullptr) {
    ba_->submit(local_ba_problem(ba_wanted_));
    if (params_.local_ba.deterministic) {
      ba_outstanding_ = true;
      ba_due_frame_ = frame_counter_ + static_cast<uint64_t>(std::max(1, params_.local_ba.apply_after_frames));
    }
  }
  ba_wanted_ = kNoId;
}

void Tracker::Impl::apply_due_ba_result(uint64_t frame_number) {
  if (!ba_ || !ba_outstanding_ || frame_number < ba_due_frame_) return;
  ba_->wait_idle();
  apply_ba_results();
  ba_outstanding_ = false;
}

void Tracker::Impl::apply_ba_results() {
  if (!ba_) return;
  for (const LocalBaResult& result : ba_->take_results()) apply_ba_result(result);
}

void Tracker::Impl::apply_ba_result(const LocalBaResult& result) {
  if (result.generation != generation_ || !result.ok) return;
  ++ba_runs_;
  object_costs_ += static_cast<uint64_t>(result.object_costs);
  // Only what still exists: the map may have moved on while the worker ran.
  std::unordered_map<uint64_t, SE3> moved;
  for (const auto& [id, T_wc] : result.keyframes) {
    if (KeyFrame* kf = map_.keyframe(id)) {
      kf->T_wc = T_wc;
      moved.emplace(id, T_wc);
    }
  }
  for (const auto& [id, p_w] : result.points)
    if (MapPoint* p = map_.map_point(id)) p->p_w = p_w;
  for (const auto& [kf, point] : result.outliers) map_.erase_observation(point, kf);
  follow_keyframes(moved);
}

void Tracker::Impl::follow_keyframes(const std::unordered_map<uint64_t, SE3>& moved) {
  // The last frame follows its reference keyframe (ORB-SLAM2), so the next frame's motion model
  // and dense prior start from where the adjusted map says it was. This only helps because the
  // adjustment keeps the dense odometry between keyframes (OdometryCost): without it the
  // features alone moved keyframes by millimetres of noise and the trajectory got worse.
  if (last_) {
    const auto it = moved.find(last_->reference_keyframe);
    if (it != moved.end()) last_->T_wc = it->second * last_->T_ref_frame;
  }
  // Registered frames follow their reference keyframes.
  std::lock_guard<std::mutex> lock(registry_mutex_);
  for (const auto& [frame_id, registered] : registered_) {
    const auto it = moved.find(registered.reference_keyframe);
    if (it != moved.end()) corrections_[frame_id] = it->second * registered.T_ref_frame;
  }
}

void Tracker::Impl::register_frame(uint64_t id) {
  if (!last_ || !has_pose(reported_state_) || map_.keyframe(last_->reference_keyframe) == nullptr)
    return;
  RegisteredFrame r;
  r.reference_keyframe = last_->reference_keyframe;
  r.T_ref_frame = last_->T_ref_frame;
  r.number = last_->number;
  r.timestamp = last_->timestamp;
  r.degraded = reported_state_ == TrackingState::kDegraded;
  r.features_only = depth_asynchronous_;
  if (params_.refine.enabled && r.features_only &&
      (params_.refine.reregister || params_.refine.full_ba)) {
    const ScalePyramid& scales = extractor_.scales();
    for (size_t k = 0; k < last_->map_points.size(); ++k) {
      if (map_.map_point(last_->map_points[k]) == nullptr) continue;
      const Keypoint& kp = last_->features.keypoints[k];
      PoseObservation o;
      o.uv = kp.uv.cast<double>();
      o.depth = kp.depth;
      o.inv_sigma = scales.inv_scale[kp.octave];
      o.depth_sigma = match_depth_sigma(kp.depth, kp.depth_slope, scales.scale[kp.octave],
                                        params_.pose, kp.depth_sync_sigma);
      r.observations.emplace_back(last_->map_points[k], o);
    }
  }
  std::lock_guard<std::mutex> lock(registry_mutex_);
  registered_[id] = std::move(r);
}

std::vector<CorrectedPose> Tracker::Impl::corrected_frames() {
  std::lock_guard<std::mutex> lock(registry_mutex_);
  std::vector<CorrectedPose> out;
  out.reserve(corrections_.size());
  for (const auto& [id, T_wc] : corrections_) out.push_back({id, T_wc});
  corrections_.clear();
  return out;
}

void Tracker::Impl::wait_for_mapping() {
  if (!ba_) return;
  ba_->wait_idle();
  apply_ba_results();
  ba_outstanding_ = false;
  submit_local_ba();  // the one that waited for the worker, if any
  ba_->wait_idle();
  apply_ba_results();
  ba_outstanding_ = false;
}

void Tracker::Impl::reset() {
  // The worker first: once it is idle nothing refers to the old map any more.
  if (ba_) ba_->cancel_all();
  ++generation_;
  map_.clear();
  state_ = TrackingState::kNotInitialised;
  reported_state_ = TrackingState::kNotInitialised;
  failures_ = 0;
  last_.reset();
  has_last_pyramid_ = false;
  last_dense_ready_ = false;
  has_anchor_ = false;
  has_velocity_ = false;
  velocity_ = SE3();
  first_keyframe_ = reference_keyframe_ = last_keyframe_ = kNoId;
  last_keyframe_frame_ = 0;
  last_relocalised_frame_ = 0;
  local_keyframes_.clear();
  local_points_.clear();
  recent_points_.clear();
  reloc_cursor_ = 0;
  ba_wanted_ = kNoId;
  ba_outstanding_ = false;
  ba_due_frame_ = 0;
  loop_query_ = kNoId;
  odometry_covariance_.setZero();
  odometry_valid_ = false;
  objects_.clear();  // the objects and keyframes of the old map's world
  std::lock_guard<std::mutex> lock(registry_mutex_);
  registered_.clear();
  corrections_.clear();
}

}  // namespace dqo::tracking
