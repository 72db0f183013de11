// The per-frame pipeline: dense alignment to the previous frame, feature tracking from the best
// guess available (dense, then the motion model, then PnP against the last keyframe), pose-only
// refinement fusing both, relocalisation when lost; where dense alignment failed or had no
// reference but the features hold, dense alignment again from their pose (realign()). The map
// side is in tracker_map.cpp.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <unordered_set>

#include <Eigen/Eigenvalues>

#include "relocaliser.h"
#include "rolling_shutter.h"
#include "tracker_impl.h"

namespace dqo::tracking {

const char* to_string(TrackingState state) {
  switch (state) {
    case TrackingState::kNotInitialised:
      return "not_initialised";
    case TrackingState::kOk:
      return "ok";
    case TrackingState::kDegraded:
      return "degraded";
    case TrackingState::kLost:
      return "lost";
  }
  return "unknown";
}

namespace {

bool valid_input(const RgbdInput& input, const PinholeCamera& camera) {
  return input.rgb != nullptr && input.depth != nullptr && input.rgb->channels == 3 &&
         input.rgb->same_size(camera.width, camera.height) &&
         input.depth->same_size(camera.width, camera.height) &&
         input.rgb->data.size() == static_cast<size_t>(camera.width) * camera.height * 3 &&
         input.depth->data.size() == static_cast<size_t>(camera.width) * camera.height;
}

// Enough to start a map: keypoints with depth, or (dense on) a depth image to align against.
constexpr int kMinInitialKeypoints = 50;
constexpr int kMinInitialDensePoints = 1000;

}  // namespace

Tracker::Impl::Impl(const PinholeCamera& camera, const TrackerParams& params)
    : camera_(camera), params_(params), extractor_(params.orb) {
  if (params_.local_ba.enabled && !params_.local_ba.synchronous)
    ba_ = std::make_unique<LocalBaWorker>(camera_, params_.local_ba, params_.pose);
}

Tracker::Impl::~Impl() = default;  // the worker's destructor aborts and joins

TrackResult Tracker::Impl::track(const RgbdInput& input) {
  const auto start = std::chrono::steady_clock::now();
  TrackResult result;
  result.state = state_;
  if (!valid_input(input, camera_)) {
    // Nothing tracked, nothing changed; the pose stays the last one's.
    if (last_ && state_ == TrackingState::kOk) result.T_wc = last_->T_wc;
    return result;
  }
  if (params_.local_ba.deterministic) {
    apply_due_ba_result(frame_counter_ + 1);
  } else {
    apply_ba_results();
  }
  close_pending_loop();
  submit_local_ba();
  // The previous frame's pose, after any correction above: the anchor's if it becomes one.
  const SE3 T_wc_previous = last_ ? last_->T_wc : SE3();
  const Eigen::Matrix<double, 6, 6> odometry_covariance_previous = odometry_covariance_;
  const bool odometry_valid_previous = odometry_valid_;
  const uint64_t last_keyframe_previous = last_keyframe_;

  depth_asynchronous_ = input.depth_timestamp.has_value() &&
                        std::abs(*input.depth_timestamp - input.timestamp) >
                            params_.pose.max_depth_gap_s;
  TrackedFrame frame;
  frame.number = ++frame_counter_;
  frame.timestamp = input.timestamp;
  if (params_.use_features) extractor_.extract(*input.rgb, *input.depth, &frame.features);
  if (depth_asynchronous_) mark_asynchronous_depth(&frame);
  // A rolling shutter's rows moved to the stamp's instant by the motion model (rolling_shutter.h),
  // where its velocity describes the motion during this frame's readout.
  const RollingShutterParams& shutter = params_.rolling_shutter;
  if (shutter.readout_s > 0.0 && params_.use_features && has_velocity_ && last_ &&
      velocity_dt_ > 0.0 && velocity_dt_ <= shutter.max_step_s &&
      input.timestamp - last_->timestamp <= shutter.max_step_s) {
    compensate_rolling_shutter(camera_, velocity_.log() / velocity_dt_, shutter.readout_s,
                               &frame.features);
  }
  frame.map_points.assign(frame.features.size(), kNoId);
  // Two pyramids, swapped every frame: their buffers are reused (no allocation per frame).
  const RgbdPyramid* pyramid = nullptr;
  if (params_.use_dense) {
    current_pyramid_.rebuild(camera_, *input.rgb, *input.depth, params_.dense);
    pyramid = &current_pyramid_;
  }

  const int features = static_cast<int>(frame.features.size());
  switch (state_.load()) {
    case TrackingState::kNotInitialised:
      result = initialise(&frame, pyramid);
      break;
    case TrackingState::kOk:
    case TrackingState::kDegraded:  // reported only, never the mode (tracker_impl.h): tracks as kOk
      result = track_frame(&frame, pyramid);
      break;
    case TrackingState::kLost:
      // Relocalisation needs features: with dense alignment alone (use_features false) a lost
      // tracker stays lost, since a pose chained from a guess across the gap would be wrong.
      result = track_lost(&frame, pyramid);
      break;
  }
  result.features = features;
  reported_state_ = result.state;
  if (pyramid != nullptr) {
    const bool dense_ready =
        result.state == TrackingState::kOk &&
        pyramid->valid_points(pyramid->finest_level()) >= kMinInitialDensePoints;
    if (!dense_ready && last_dense_ready_) {
      // The chain of dense references breaks here: keep the last good one (realign()).
      std::swap(anchor_pyramid_, last_pyramid_);
      anchor_T_wc_ = T_wc_previous;
      anchor_frame_ = frame.number - 1;
      has_anchor_ = true;
      anchor_odometry_covariance_ = odometry_covariance_previous;
      anchor_odometry_valid_ = odometry_valid_previous;
      anchor_keyframe_ = last_keyframe_previous;
    }
    std::swap(current_pyramid_, last_pyramid_);
    has_last_pyramid_ = true;
    last_dense_ready_ = dense_ready;
  }
  result.milliseconds =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return result;
}

TrackResult Tracker::Impl::initialise(TrackedFrame* frame, const RgbdPyramid* pyramid) {
  TrackResult result;
  int with_depth = 0;
  for (size_t i = 0; i < frame->features.size(); ++i) with_depth += frame->features.has_depth(i);
  const bool features_enough = params_.use_features && with_depth >= kMinInitialKeypoints;
  const bool dense_enough = pyramid != nullptr &&
                            pyramid->valid_points(pyramid->finest_level()) >= kMinInitialDensePoints;
  if (!features_enough && !dense_enough) return result;  // still kNotInitialised

  // The world frame is the first camera's.
  frame->T_wc = SE3();
  create_keyframe(frame);
  first_keyframe_ = last_keyframe_;
  state_ = TrackingState::kOk;
  failures_ = 0;
  finish_frame(frame, SE3(), false);
  result.state = TrackingState::kOk;
  result.T_wc = SE3();
  result.new_keyframe = true;
  return result;
}

QualityEvidence Tracker::Impl::evidence_base() const {
  QualityEvidence e;
  e.use_features = params_.use_features;
  e.use_dense = params_.use_dense;
  e.min_inliers = params_.min_inliers_ok;
  return e;
}

namespace {

// A relocalised pose that dense alignment to the anchor confirmed (fuse_realigned).
void add_dense_evidence(const DenseResult& dense, QualityEvidence* e) {
  e->dense_tried = true;
  e->dense_ok = true;
  e->dense_rms = dense.whitened_rms;
  e->dense_inlier_ratio = dense.inlier_ratio;
}

}  // namespace

double Tracker::Impl::spread_of(const TrackedFrame& frame) const {
  std::vector<Eigen::Vector2f> uv;
  for (size_t k = 0; k < frame.map_points.size(); ++k)
    if (frame.map_points[k] != kNoId) uv.push_back(frame.features.keypoints[k].uv);
  return inlier_spread(uv, camera_);
}

int Tracker::Impl::depth_inliers_of(const TrackedFrame& frame) const {
  int n = 0;
  for (size_t k = 0; k < frame.map_points.size(); ++k)
    n += frame.map_points[k] != kNoId && frame.features.has_depth(static_cast<int>(k));
  return n;
}

namespace {

double angle_deg(const SE3& T) {
  const double w = std::min(1.0, std::abs(T.quaternion().w()));
  return 2.0 * std::acos(w) * 180.0 / M_PI;
}

}  // namespace

TrackResult Tracker::Impl::track_frame(TrackedFrame* frame, const RgbdPyramid* pyramid) {
  TrackResult result;
  const SE3 T_wc_mm = last_->T_wc * (has_velocity_ ? velocity_ : SE3());
  DenseResult dense;
  const bool dense_tried = pyramid != nullptr && has_last_pyramid_ && last_;
  std::optional<DensePrior> prior = align_to_last(pyramid, &dense);
  FeatureOutcome features = track_features(frame, prior ? &*prior : nullptr, T_wc_mm);
  // Whether the dense prior is relative to the last frame (and may enter the odometry).
  bool prior_to_last = prior.has_value();
  if (!prior && features.ok) {
    fuse_realigned(frame, pyramid, &features.T_wc, &features.inliers, &dense, &prior,
                   &prior_to_last);
  }

  QualityEvidence e = evidence_base();
  e.dense_tried = dense_tried || prior.has_value();
  e.dense_ok = prior.has_value();
  e.dense_rms = dense.whitened_rms;
  e.dense_inlier_ratio = dense.inlier_ratio;
  SE3 T_wc_dense = prior ? prior->T_w_ref * prior->T_ref_cur : SE3();
  bool dense_pose = prior.has_value();
  // Features alone (asynchronous depth) with nothing to confirm them: dense alignment from their
  // pose, as evidence only (QualityParams::confirm_features). Soon after a frame that was not ok,
  // against the last ok one (the anchor) instead, whether dense from the motion model held or not:
  // held, it only confirms a step from a pose nothing confirmed (on fr1/desk the frame after two
  // blurred ones: its features 5.3 cm off, consistent with theirs).
  const bool after_doubt = reported_state_ != TrackingState::kOk && has_anchor_ &&
                           frame->number <= anchor_frame_ + static_cast<uint64_t>(std::max(
                                                                0, params_.quality.confirm_window_frames));
  if (features.ok && (!prior || after_doubt) && depth_asynchronous_ &&
      params_.quality.confirm_features) {
    DenseResult check;
    e.dense_tried = true;
    e.dense_from_features = true;
    e.dense_ok = false;
    if (const auto T_wc_check = confirm_features(pyramid, features.T_wc, after_doubt, &check)) {
      e.dense_ok = true;
      T_wc_dense = *T_wc_check;
      dense_pose = true;
    } else {
      dense_pose = false;
    }
    e.dense_rms = check.whitened_rms;
    e.dense_inlier_ratio = check.inlier_ratio;
  }
  auto compare = [&](const SE3& T_wc_features) {
    if (!dense_pose) return;
    const SE3 delta = T_wc_dense.inverse() * T_wc_features;
    e.compared = true;
    e.disagreement_m = delta.translation().norm();
    e.disagreement_deg = angle_deg(delta);
  };

  SE3 T_wc;
  bool features_ok = false;
  if (features.ok) {
    T_wc = features.T_wc;
    features_ok = true;
    e.inliers = features.inliers;
    e.spread = spread_of(*frame);
    e.depth_inliers = depth_inliers_of(*frame);
    compare(features.T_wc);
  } else if (prior) {
    // Features too few (a plain scene, a fast turn): the dense alignment holds the pose, fused
    // with whatever features agreed with it.
    T_wc = features.used_prior ? features.T_wc : T_wc_dense;
    e.inliers = features.used_prior ? features.inliers : 0;
    e.spread = features.used_prior ? spread_of(*frame) : 0.0;
    e.depth_inliers = features.used_prior ? depth_inliers_of(*frame) : 0;
    if (features.contradicted_dense) {
      e.inliers = features.inliers_alone;
      compare(features.T_wc_alone);
    }
  } else {
    odometry_valid_ = false;
    // Neither held: try to relocalise at once rather than drift on the motion model.
    int inliers = 0;
    if (relocalise_frame(frame, &T_wc, &inliers)) {
      const bool realigned =
          fuse_realigned(frame, pyramid, &T_wc, &inliers, &dense, nullptr, nullptr);
      QualityEvidence r = evidence_base();
      r.inliers = inliers;
      r.spread = spread_of(*frame);
      r.depth_inliers = depth_inliers_of(*frame);
      if (realigned) add_dense_evidence(dense, &r);
      const QualityVerdict verdict = assess_quality(r, params_.quality);
      has_velocity_ = false;
      accept(frame, T_wc, inliers, true, false, &result);
      result.state = verdict.state;
      result.quality = verdict.quality;
      return result;
    }
    e.predicted = true;
    T_wc = T_wc_mm;
  }

  const QualityVerdict verdict = assess_quality(e, params_.quality);
  if (verdict.state != TrackingState::kLost) {
    // Dense odometry between keyframes measures the depth's instants where those are not the
    // colour's: left out of bundle adjustment then, like the prior (max_depth_gap_s).
    // (Aligned to the anchor instead, fuse_realigned has set the odometry.)
    const bool to_anchor = prior && !prior_to_last;
    if (prior && prior_to_last && !depth_asynchronous_) accumulate_odometry(&*prior, T_wc);
    else if (!to_anchor) odometry_valid_ = false;
    // Keyframes from poses the RGB-D evidence supports: a monocular pose (depth dropped) adds no
    // points and would anchor the map on its weaker rotation.
    const uint32_t no_depth = quality_reason::kNoDepth | quality_reason::kDenseFailed;
    const bool keyframe_ok = (verdict.quality.reasons & no_depth) != no_depth;
    accept(frame, T_wc, e.inliers, features_ok, true, &result, keyframe_ok);
    result.state = verdict.state;
    result.quality = verdict.quality;
    return result;
  }

  // No pose the evidence supports: report lost, make no keyframe, count no map point as found.
  // The best guess (dense, else the motion model) carries the next frame's search; after
  // frames_to_lost such frames in a row, relocalisation takes over.
  odometry_valid_ = false;
  ++failures_;
  std::fill(frame->map_points.begin(), frame->map_points.end(), kNoId);
  result.state = TrackingState::kLost;
  result.quality = verdict.quality;
  result.predicted = e.predicted;
  result.T_wc = T_wc;
  if (failures_ >= params_.frames_to_lost) {
    state_ = TrackingState::kLost;
    has_velocity_ = false;
  }
  finish_frame(frame, T_wc, false);
  return result;
}

TrackResult Tracker::Impl::track_lost(TrackedFrame* frame, const RgbdPyramid* pyramid) {
  TrackResult result;
  result.state = TrackingState::kLost;
  result.quality.reasons = quality_reason::kRelocalising;
  SE3 T_wc;
  int inliers = 0;
  if (!relocalise_frame(frame, &T_wc, &inliers)) return result;
  odometry_valid_ = false;
  DenseResult dense;
  const bool realigned =
      fuse_realigned(frame, pyramid, &T_wc, &inliers, &dense, nullptr, nullptr);
  QualityEvidence e = evidence_base();
  e.inliers = inliers;
  e.spread = spread_of(*frame);
  e.depth_inliers = depth_inliers_of(*frame);
  if (realigned) add_dense_evidence(dense, &e);
  const QualityVerdict verdict = assess_quality(e, params_.quality);
  state_ = TrackingState::kOk;
  has_velocity_ = false;
  last_relocalised_frame_ = frame->number;
  accept(frame, T_wc, inliers, true, false, &result);
  result.state = verdict.state;
  result.quality = verdict.quality;
  result.relocalised = true;
  return result;
}

void Tracker::Impl::accept(TrackedFrame* frame, const SE3& T_wc, int inliers, bool features_ok,
                           bool update_velocity, TrackResult* result, bool keyframe_allowed) {
  failures_ = 0;
  frame->T_wc = T_wc;
  count_found(*frame);
  if (keyframe_allowed && need_keyframe(*frame, inliers, features_ok)) {
    create_keyframe(frame);
    result->new_keyframe = true;
  }
  finish_frame(frame, T_wc, update_velocity);
  result->state = TrackingState::kOk;  // the caller sets the assessed state
  result->T_wc = T_wc;
  result->inliers = inliers;
}

void Tracker::Impl::finish_frame(TrackedFrame* frame, const SE3& T_wc, bool update_velocity) {
  frame->T_wc = T_wc;
  if (update_velocity && last_) {
    velocity_ = last_->T_wc.inverse() * T_wc;
    velocity_dt_ = frame->timestamp - last_->timestamp;
    has_velocity_ = true;
  }
  frame->reference_keyframe = reference_keyframe_;
  if (const KeyFrame* ref = map_.keyframe(reference_keyframe_))
    frame->T_ref_frame = ref->T_wc.inverse() * T_wc;
  last_ = std::move(*frame);
}

void Tracker::Impl::mark_asynchronous_depth(TrackedFrame* frame) const {
  // PoseOptimiserParams::asynchronous_depth_sigma_per_m2 says why; the sensor's own σ stays in
  // keypoint_depth_sigma, this term brings the total to the coarser model.
  const double k = params_.pose.asynchronous_depth_sigma_per_m2;
  for (Keypoint& kp : frame->features.keypoints) {
    if (kp.depth <= 0.0f) continue;
    kp.depth_sync_sigma = static_cast<float>(k * kp.depth * kp.depth);
  }
}

namespace {

// Adjoint of T on [rho; phi]: T exp(xi) = exp(Ad(T) xi) T.
Eigen::Matrix<double, 6, 6> adjoint(const SE3& T) {
  const Eigen::Matrix3d R = T.rotation();
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Zero();
  A.topLeftCorner<3, 3>() = R;
  A.topRightCorner<3, 3>() = skew(T.translation()) * R;
  A.bottomRightCorner<3, 3>() = R;
  return A;
}

// Inverse of a symmetric positive semi-definite matrix whose small eigenvalues stand for "no
// information" (a direction dense alignment could not see): they become a huge variance.
Eigen::Matrix<double, 6, 6> inverse_psd(const Eigen::Matrix<double, 6, 6>& M, double floor) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(0.5 * (M + M.transpose()));
  const Eigen::Matrix<double, 6, 1> inv = eig.eigenvalues().cwiseMax(floor).cwiseInverse();
  return eig.eigenvectors() * inv.asDiagonal() * eig.eigenvectors().transpose();
}

}  // namespace

void Tracker::Impl::accumulate_odometry(const DensePrior* prior, const SE3& T_wc) {
  if (prior == nullptr || !last_) {
    odometry_valid_ = false;
    return;
  }
  // Right perturbations compose as Σ_ac = Ad(T_cb) Σ_ab Ad(T_cb)ᵀ + Σ_bc.
  const Eigen::Matrix<double, 6, 6> A = adjoint(T_wc.inverse() * last_->T_wc);
  odometry_covariance_ =
      A * odometry_covariance_ * A.transpose() + inverse_psd(prior->information, 1e-3);
}

std::optional<DensePrior> Tracker::Impl::align_to_last(const RgbdPyramid* pyramid,
                                                       DenseResult* result) {
  if (pyramid == nullptr || !has_last_pyramid_ || !last_) return std::nullopt;
  // A lost frame's pose is a guess (the motion model's): a step from it, however well aligned,
  // would chain the guess on as a pose with evidence (a jump of 1 m: a frame lost, then the next
  // ones ok 1 m off). Without this prior the frame is tracked on features or relocalised.
  if (reported_state_ == TrackingState::kLost) return std::nullopt;
  *result = align_dense(last_pyramid_, *pyramid, has_velocity_ ? velocity_ : SE3(), params_.dense);
  const DenseResult& dense = *result;
  if (!dense.ok) return std::nullopt;
  DensePrior prior;
  prior.T_w_ref = last_->T_wc;
  prior.T_ref_cur = dense.T_ref_cur;
  prior.information = params_.pose.dense_prior_weight * dense.information;
  return prior;
}

std::optional<DensePrior> Tracker::Impl::realign(const RgbdPyramid* pyramid,
                                                  const SE3& T_wc_guess, DenseResult* result,
                                                  bool* to_last) const {
  // Asynchronous depth: the features alone give the pose where they hold (max_depth_gap_s).
  if (pyramid == nullptr || !params_.realign_dense || depth_asynchronous_) return std::nullopt;
  const RgbdPyramid* reference = nullptr;
  SE3 T_w_ref;
  if (last_dense_ready_ && has_last_pyramid_ && last_) {
    reference = &last_pyramid_;
    T_w_ref = last_->T_wc;
    *to_last = true;
  } else if (has_anchor_) {
    reference = &anchor_pyramid_;
    T_w_ref = anchor_T_wc_;
    *to_last = false;
  } else {
    return std::nullopt;
  }
  *result = align_dense(*reference, *pyramid, T_w_ref.inverse() * T_wc_guess, params_.dense);
  if (!result->ok) return std::nullopt;
  DensePrior prior;
  prior.T_w_ref = T_w_ref;
  prior.T_ref_cur = result->T_ref_cur;
  prior.information = params_.pose.dense_prior_weight * result->information;
  return prior;
}

std::optional<SE3> Tracker::Impl::confirm_features(const RgbdPyramid* pyramid,
                                                   const SE3& T_wc_features, bool to_anchor,
                                                   DenseResult* result) const {
  // To the last frame, whatever its state, unless told to the anchor: against the last frame
  // tracked ok every time, a gap of a few fast frames already fails on fr1/desk (whitened RMS
  // 2-2.8) and every frame after one unconfirmed frame stayed degraded to the end
  // (QualityParams::confirm_window_frames bounds it).
  if (pyramid == nullptr || !last_) return std::nullopt;
  if (to_anchor && !has_anchor_) return std::nullopt;
  if (!to_anchor && !has_last_pyramid_) return std::nullopt;
  const RgbdPyramid& reference = to_anchor ? anchor_pyramid_ : last_pyramid_;
  const SE3 T_w_ref = to_anchor ? anchor_T_wc_ : last_->T_wc;
  // Its own residual limit (QualityParams::confirm_max_rms): the agreement with the features
  // decides, not the fit alone.
  DenseParams check = params_.dense;
  check.max_whitened_rms = params_.quality.confirm_max_rms;
  *result = align_dense(reference, *pyramid, T_w_ref.inverse() * T_wc_features, check);
  if (!result->ok) return std::nullopt;
  return T_w_ref * result->T_ref_cur;
}

bool Tracker::Impl::fuse_realigned(TrackedFrame* frame, const RgbdPyramid* pyramid, SE3* T_wc,
                                   int* inliers, DenseResult* dense,
                                   std::optional<DensePrior>* prior_out, bool* to_last_out) {
  DenseResult again;
  bool to_last = false;
  const std::optional<DensePrior> prior = realign(pyramid, *T_wc, &again, &to_last);
  if (!prior) return false;
  // The features' matches again, now with the dense pose as a prior: accepted only where the two
  // agree (the prior's chi-square, as in track_features) and the features still hold.
  Refinement fused = refine(*frame, *T_wc, &*prior, {});
  if (fused.pose.prior_chi2 > params_.pose.max_prior_chi2 ||
      fused.map_inliers < params_.min_inliers_ok)
    return false;
  keep_inliers(frame, fused);
  *T_wc = fused.pose.T_wc;
  *inliers = fused.map_inliers;
  *dense = again;
  if (!to_last) {
    // The odometry continues from the anchor: Σ_ac = Ad(T_cb) Σ_ab Ad(T_cb)ᵀ + Σ_bc as in
    // accumulate_odometry, b the anchor; valid if no keyframe came between.
    const Eigen::Matrix<double, 6, 6> A = adjoint(T_wc->inverse() * anchor_T_wc_);
    odometry_covariance_ = A * anchor_odometry_covariance_ * A.transpose() +
                           inverse_psd(prior->information, 1e-3);
    odometry_valid_ = anchor_odometry_valid_ && anchor_keyframe_ == last_keyframe_;
  }
  if (prior_out != nullptr) *prior_out = prior;
  if (to_last_out != nullptr) *to_last_out = to_last;
  return true;
}

FeatureOutcome Tracker::Impl::track_features(TrackedFrame* frame, const DensePrior* prior,
                                             const SE3& T_wc_mm) {
  FeatureOutcome out;
  if (!params_.use_features || map_.num_keyframes() == 0 || frame->features.size() == 0)
    return out;
  const int min_matches = params_.search.min_matches;
  update_local_map(*last_);

  // The dense pose is good to a pixel or so: search the local map from it straight away.
  SE3 guess = prior != nullptr ? prior->T_w_ref * prior->T_ref_cur : T_wc_mm;
  int matched =
      prior != nullptr ? search_local_map(frame, guess, params_.search.dense_radius_px) : 0;
  if (matched < min_matches) {
    // No dense pose, or one the map disagrees with: frame to frame from the motion model, else
    // PnP against the last keyframe; the local map is searched from the pose they give.
    std::fill(frame->map_points.begin(), frame->map_points.end(), kNoId);
    if (!track_motion_model(frame, T_wc_mm, &guess)) {
      std::fill(frame->map_points.begin(), frame->map_points.end(), kNoId);
      if (match_with_pnp(frame, &guess) == 0) return out;
    }
    update_local_map(*frame);
    search_local_map(frame, guess, params_.search.local_map_radius_px);
  }

  if (prior != nullptr && depth_asynchronous_) {
    // Depth not captured with the colour: the features alone where they hold by themselves
    // (max_depth_gap_s), the fusion only to carry weak ones.
    Refinement alone = refine(*frame, guess, nullptr, {});
    if (alone.map_inliers >= 2 * params_.min_inliers_ok) {
      keep_inliers(frame, alone);
      out.ran = true;
      out.T_wc = alone.pose.T_wc;
      out.inliers = alone.map_inliers;
      out.ok = true;
      return out;
    }
  }
  Refinement fused = refine(*frame, guess, prior, {});
  out.ran = true;
  out.used_prior = prior != nullptr;
  if (prior != nullptr && fused.pose.prior_chi2 > params_.pose.max_prior_chi2) {
    // Dense and features disagree: believe the features if they hold by themselves, else dense.
    Refinement alone = refine(*frame, guess, nullptr, {});
    if (alone.map_inliers >= 2 * params_.min_inliers_ok) {
      fused = std::move(alone);
      out.used_prior = false;
    } else {
      std::fill(frame->map_points.begin(), frame->map_points.end(), kNoId);
      out.used_prior = false;
      out.contradicted_dense = alone.map_inliers >= params_.min_inliers_ok;
      out.T_wc_alone = alone.pose.T_wc;
      out.inliers_alone = alone.map_inliers;
      return out;  // the caller takes the dense pose (or reports the frame lost)
    }
  }
  keep_inliers(frame, fused);
  out.T_wc = fused.pose.T_wc;
  out.inliers = fused.map_inliers;
  out.ok = out.inliers >= params_.min_inliers_ok;
  return out;
}

bool Tracker::Impl::track_motion_model(TrackedFrame* frame, const SE3& T_wc_mm, SE3* T_wc) {
  // Without a velocity the prediction is only "no motion": ORB-SLAM2 goes to the reference
  // keyframe directly, and so does this.
  if (!has_velocity_) return false;
  const int min_matches = params_.search.min_matches;
  std::vector<PoseObservation> temporary;
  int matched = match_last_frame(frame, T_wc_mm, params_.search.frame_radius_px, &temporary);
  if (matched < min_matches) {
    std::fill(frame->map_points.begin(), frame->map_points.end(), kNoId);
    temporary.clear();
    matched = match_last_frame(frame, T_wc_mm, 2.0 * params_.search.frame_radius_px, &temporary);
  }
  if (matched < min_matches) return false;
  const Refinement refined = refine(*frame, T_wc_mm, nullptr, temporary);
  // Wrong matches from a wrong prediction can still agree on some wrong pose; right ones mostly
  // survive the outlier rounds.
  if (refined.map_inliers < 10 || 2 * refined.pose.inliers < matched) return false;
  keep_inliers(frame, refined);
  *T_wc = refined.pose.T_wc;
  return true;
}

int Tracker::Impl::match_last_frame(TrackedFrame* frame, const SE3& T_wc_guess, double radius,
                                    std::vector<PoseObservation>* temporary) {
  const TrackedFrame& last = *last_;
  std::vector<ProjectionCandidate> candidates;
  candidates.reserve(last.features.size());
  for (size_t k = 0; k < last.features.size(); ++k) {
    ProjectionCandidate c;
    const MapPoint* p = map_.map_point(last.map_points[k]);
    if (p != nullptr) {
      c.map_point = p->id;
      c.p_w = p->p_w;
    } else if (last.features.has_depth(static_cast<int>(k))) {
      // The last frame's own depth: a point for this step only (ORB-SLAM2's visual odometry
      // points), never added to the map.
      c.p_w = last.T_wc * last.features.point_c(static_cast<int>(k), camera_);
    } else {
      continue;
    }
    c.descriptor = last.features.descriptors[k];
    c.level = last.features.keypoints[k].octave;
    c.angle = last.features.keypoints[k].angle;
    candidates.push_back(c);
  }
  ProjectionSearch search;
  search.radius_px = radius;
  search.check_orientation = true;
  const std::vector<Match> matches = search_by_projection(
      frame->features, camera_, extractor_.scales(), T_wc_guess, candidates, search, nullptr,
      nullptr);
  int n = 0;
  for (const Match& m : matches) {
    const ProjectionCandidate& c = candidates[m.candidate];
    if (c.map_point != kNoId) {
      frame->map_points[m.keypoint] = c.map_point;
    } else {
      const Keypoint& k = frame->features.keypoints[m.keypoint];
      PoseObservation o;
      o.p_w = c.p_w;
      o.uv = k.uv.cast<double>();
      o.depth = k.depth;
      o.inv_sigma = extractor_.scales().inv_scale[k.octave];
      o.depth_sigma = match_depth_sigma(k.depth, k.depth_slope,
                                        extractor_.scales().scale[k.octave], params_.pose,
                                        k.depth_sync_sigma);
      temporary->push_back(o);
    }
    ++n;
  }
  return n;
}

int Tracker::Impl::match_with_pnp(TrackedFrame* frame, SE3* T_wc) {
  for (const uint64_t id : {last_keyframe_, reference_keyframe_}) {
    const KeyFrame* kf = map_.keyframe(id);
    if (kf == nullptr) continue;
    const PnpResult pnp = pnp_against_keyframe(frame->features, *kf, map_, camera_,
                                               extractor_.scales(), params_.pose,
                                               params_.min_inliers_ok);
    if (!pnp.ok) continue;
    for (const auto& [k, point] : pnp.matches) frame->map_points[k] = point;
    *T_wc = pnp.T_wc;
    return static_cast<int>(pnp.matches.size());
  }
  return 0;
}

void Tracker::Impl::update_local_map(const TrackedFrame& source) {
  // Keyframes sharing points with the frame, the most shared first, then their neighbours
  // (ORB-SLAM2's UpdateLocalKeyFrames); the heaviest becomes the reference keyframe.
  std::unordered_map<uint64_t, int> shared;
  for (const uint64_t id : source.map_points) {
    const MapPoint* p = map_.map_point(id);
    if (p == nullptr) continue;
    for (const auto& [kf, index] : p->observations) ++shared[kf];
  }
  std::vector<std::pair<int, uint64_t>> ranked;
  for (const auto& [kf, n] : shared) ranked.emplace_back(n, kf);
  std::sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second > b.second;
  });
  if (ranked.empty()) {
    if (map_.keyframe(reference_keyframe_) == nullptr) return;  // keep the old local map
    ranked.emplace_back(1, reference_keyframe_);
  }
  reference_keyframe_ = ranked.front().second;

  const size_t limit = static_cast<size_t>(std::max(1, params_.search.local_map_keyframes));
  local_keyframes_.clear();
  std::unordered_set<uint64_t> in_local;
  for (const auto& [n, kf] : ranked) {
    if (local_keyframes_.size() >= limit) break;
    if (in_local.insert(kf).second) local_keyframes_.push_back(kf);
  }
  const size_t direct = local_keyframes_.size();
  for (size_t i = 0; i < direct && local_keyframes_.size() < limit; ++i) {
    for (const uint64_t n : map_.covisible(local_keyframes_[i], 10)) {
      if (local_keyframes_.size() >= limit) break;
      if (in_local.insert(n).second) local_keyframes_.push_back(n);
    }
  }

  local_points_.clear();
  std::unordered_set<uint64_t> seen;
  seen.reserve(8192);
  for (const uint64_t kf_id : local_keyframes_) {
    const KeyFrame* kf = map_.keyframe(kf_id);
    if (kf == nullptr) continue;
    for (const uint64_t id : kf->map_points)
      if (id != kNoId && seen.insert(id).second) local_points_.push_back(id);
  }
}

int Tracker::Impl::search_local_map(TrackedFrame* frame, const SE3& T_wc, double radius) {
  std::unordered_set<uint64_t> matched;
  std::vector<char> taken(frame->features.size(), 0);
  for (size_t k = 0; k < frame->map_points.size(); ++k) {
    if (frame->map_points[k] == kNoId) continue;
    matched.insert(frame->map_points[k]);
    taken[k] = 1;
  }
  std::vector<ProjectionCandidate> candidates;
  candidates.reserve(local_points_.size());
  for (const uint64_t id : local_points_) {
    if (matched.count(id) != 0) continue;
    const MapPoint* p = map_.map_point(id);
    if (p == nullptr) continue;
    ProjectionCandidate c;
    c.map_point = id;
    c.p_w = p->p_w;
    c.descriptor = p->descriptor;
    c.normal = p->normal;
    c.min_distance = p->min_distance;
    c.max_distance = p->max_distance;
    candidates.push_back(c);
  }
  ProjectionSearch search;
  search.radius_px = radius;
  // Soon after relocalisation the pose is rougher: a wider window (ORB-SLAM2).
  if (frame->number < last_relocalised_frame_ + 2) search.radius_px *= 2.0;
  search.levels_below = 1;
  search.levels_above = 0;
  search.ratio = params_.search.local_map_ratio;
  search.check_orientation = false;
  search.check_viewing = true;
  std::vector<char> in_frustum;
  const std::vector<Match> matches =
      search_by_projection(frame->features, camera_, extractor_.scales(), T_wc, candidates,
                           search, &taken, &in_frustum);
  for (size_t c = 0; c < candidates.size(); ++c)
    if (in_frustum[c]) ++map_.map_point(candidates[c].map_point)->visible;
  for (const Match& m : matches) frame->map_points[m.keypoint] = candidates[m.candidate].map_point;
  int n = 0;
  for (const uint64_t id : frame->map_points) n += id != kNoId;
  return n;
}

Refinement Tracker::Impl::refine(const TrackedFrame& frame, const SE3& T_wc_guess,
                                 const DensePrior* prior,
                                 const std::vector<PoseObservation>& extra) const {
  Refinement out;
  std::vector<PoseObservation> observations;
  observations.reserve(frame.map_points.size() + extra.size());
  for (size_t k = 0; k < frame.map_points.size(); ++k) {
    const MapPoint* p = map_.map_point(frame.map_points[k]);
    if (p == nullptr) continue;
    const Keypoint& kp = frame.features.keypoints[k];
    PoseObservation o;
    o.p_w = p->p_w;
    o.uv = kp.uv.cast<double>();
    o.depth = kp.depth;
    o.inv_sigma = extractor_.scales().inv_scale[kp.octave];
    o.depth_sigma = match_depth_sigma(kp.depth, kp.depth_slope,
                                      extractor_.scales().scale[kp.octave], params_.pose,
                                      kp.depth_sync_sigma);
    observations.push_back(o);
    out.keypoints.push_back(static_cast<int>(k));
  }
  for (const PoseObservation& o : extra) {
    observations.push_back(o);
    out.keypoints.push_back(-1);
  }
  out.pose = optimise_pose(T_wc_guess, observations, camera_, prior, params_.pose);
  for (size_t i = 0; i < out.keypoints.size(); ++i)
    out.map_inliers += out.keypoints[i] >= 0 && out.pose.inlier[i];
  return out;
}

void Tracker::Impl::keep_inliers(TrackedFrame* frame, const Refinement& refinement) const {
  std::vector<char> keep(frame->map_points.size(), 0);
  for (size_t i = 0; i < refinement.keypoints.size(); ++i)
    if (refinement.keypoints[i] >= 0 && refinement.pose.inlier[i]) keep[refinement.keypoints[i]] = 1;
  for (size_t k = 0; k < frame->map_points.size(); ++k)
    if (!keep[k]) frame->map_points[k] = kNoId;
}

bool Tracker::Impl::relocalise_frame(TrackedFrame* frame, SE3* T_wc, int* inliers) {
  if (!params_.use_features || map_.num_keyframes() == 0 || frame->features.size() == 0)
    return false;
  const PnpResult pnp = relocalise(frame->features, map_, relocalisation_candidates(), camera_,
                                   extractor_.scales(), params_.pose, params_.reloc);
  if (!pnp.ok) return false;
  std::fill(frame->map_points.begin(), frame->map_points.end(), kNoId);
  for (const auto& [k, point] : pnp.matches) frame->map_points[k] = point;
  update_local_map(*frame);
  last_relocalised_frame_ = frame->number;
  search_local_map(frame, pnp.T_wc, params_.search.local_map_radius_px);
  const Refinement refined = refine(*frame, pnp.T_wc, nullptr, {});
  if (refined.map_inliers < params_.reloc.min_inliers) {
    std::fill(frame->map_points.begin(), frame->map_points.end(), kNoId);
    return false;
  }
  keep_inliers(frame, refined);
  *T_wc = refined.pose.T_wc;
  *inliers = refined.map_inliers;
  return true;
}

std::vector<uint64_t> Tracker::Impl::relocalisation_candidates() {
  // The last reference keyframe and its neighbours (where the camera most likely is), then the
  // rest of the map in turns: each lost frame tries the next slice, so every keyframe gets its
  // chance while the cost per frame stays bounded.
  const size_t n = static_cast<size_t>(std::max(1, params_.reloc.candidate_keyframes));
  std::vector<uint64_t> out;
  std::unordered_set<uint64_t> chosen;
  auto add = [&](uint64_t id) {
    if (out.size() < n && map_.keyframe(id) != nullptr && chosen.insert(id).second)
      out.push_back(id);
  };
  add(reference_keyframe_);
  for (const uint64_t id : map_.covisible(reference_keyframe_, n / 2)) add(id);
  std::vector<uint64_t> all;
  all.reserve(map_.num_keyframes());
  for (const auto& [id, kf] : map_.keyframes()) all.push_back(id);
  std::sort(all.begin(), all.end());
  for (size_t tried = 0; tried < all.size() && out.size() < n; ++tried)
    add(all[reloc_cursor_++ % all.size()]);
  return out;
}

// ---------------------------------------------------------------- the public class

Tracker::Tracker(const PinholeCamera& camera, const TrackerParams& params)
    : impl_(std::make_unique<Impl>(camera, params)) {}
Tracker::~Tracker() = default;

TrackResult Tracker::track(const RgbdInput& input) { return impl_->track(input); }
void Tracker::reset() { impl_->reset(); }
void Tracker::register_frame(uint64_t id) { impl_->register_frame(id); }
std::vector<CorrectedPose> Tracker::corrected_frames() { return impl_->corrected_frames(); }
void Tracker::wait_for_mapping() { impl_->wait_for_mapping(); }
TrackingState Tracker::state() const { return impl_->reported_state_.load(); }
size_t Tracker::num_keyframes() const { return impl_->map_.num_keyframes(); }
size_t Tracker::num_map_points() const { return impl_->map_.num_map_points(); }
uint64_t Tracker::local_ba_runs() const { return impl_->ba_runs_.load(); }
void Tracker::optimise_map() { impl_->optimise_map(); }
LoopStats Tracker::loop_stats() const {
  return {impl_->loop_queries_.load(), impl_->loops_closed_.load(), impl_->loop_milliseconds_};
}

}  // namespace dqo::tracking
