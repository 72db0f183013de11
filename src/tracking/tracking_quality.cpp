#include "tracking_quality.h"

#include <array>

namespace dqo::tracking {

std::string reasons_to_string(uint32_t reasons) {
  static constexpr std::array<std::pair<uint32_t, const char*>, 8> kNames = {{
      {quality_reason::kFewInliers, "few_inliers"},
      {quality_reason::kPoorSpread, "poor_spread"},
      {quality_reason::kDenseFailed, "dense_failed"},
      {quality_reason::kDenseResidual, "dense_residual"},
      {quality_reason::kDisagreement, "features_dense_disagree"},
      {quality_reason::kNoEvidence, "no_evidence"},
      {quality_reason::kRelocalising, "relocalising"},
      {quality_reason::kNoDepth, "few_depth_inliers"},
  }};
  std::string out;
  for (const auto& [bit, name] : kNames) {
    if ((reasons & bit) == 0) continue;
    if (!out.empty()) out += '+';
    out += name;
  }
  return out;
}

QualityVerdict assess_quality(const QualityEvidence& e, const QualityParams& p) {
  namespace r = quality_reason;
  QualityVerdict v;
  TrackQuality& q = v.quality;
  q.inliers = e.inliers;
  q.depth_inliers = e.depth_inliers;
  q.spread = e.spread;
  q.dense_tried = e.dense_tried;
  q.dense_ok = e.dense_ok;
  q.dense_rms = e.dense_rms;
  q.dense_inlier_ratio = e.dense_inlier_ratio;
  q.disagreement_m = e.compared ? e.disagreement_m : 0.0;
  q.disagreement_deg = e.compared ? e.disagreement_deg : 0.0;

  if (e.predicted) {
    q.reasons = r::kNoEvidence;
    v.state = TrackingState::kLost;
    return v;
  }
  // A source not in use (configuration, or dense not run at relocalisation) is no evidence
  // either way: the frame is judged on the other.
  const bool features = e.use_features;
  const bool dense = e.use_dense && e.dense_tried;
  if (features) {
    if (e.inliers < p.ok_inliers) q.reasons |= r::kFewInliers;
    if (e.spread < p.min_spread) q.reasons |= r::kPoorSpread;
    if (e.depth_inliers < p.ok_depth_inliers) q.reasons |= r::kNoDepth;
  }
  // A check of the features' pose (dense_from_features) has its own limits: a looser fit, since
  // the fast or wide steps where it runs fit worse whatever the pose, and a tighter agreement.
  const bool check = e.dense_from_features;
  const double max_rms = check ? p.confirm_max_rms : p.dense_max_rms;
  if (dense) {
    if (!e.dense_ok) {
      q.reasons |= r::kDenseFailed;
    } else if (e.dense_rms > max_rms || e.dense_inlier_ratio < p.dense_min_inlier_ratio) {
      q.reasons |= r::kDenseResidual;
    }
  }
  const double max_m = check ? p.confirm_max_disagreement_m : p.max_disagreement_m;
  const double max_deg = check ? p.confirm_max_disagreement_deg : p.max_disagreement_deg;
  const bool disagree =
      e.compared && (e.disagreement_m > max_m || e.disagreement_deg > max_deg);
  if (disagree) q.reasons |= r::kDisagreement;

  const bool features_hold =
      features && (q.reasons & (r::kFewInliers | r::kPoorSpread | r::kNoDepth)) == 0;
  const bool features_some = features && e.inliers >= e.min_inliers;
  const bool dense_holds = dense && (q.reasons & (r::kDenseFailed | r::kDenseResidual)) == 0;

  if (disagree) {
    // Two sources contradict each other: only features that hold by themselves are believed.
    v.state = features_hold ? TrackingState::kDegraded : TrackingState::kLost;
  } else if (features_hold && dense && !dense_holds && e.dense_from_features &&
             p.confirm_features) {
    // Dense alignment from the features' own pose failed or fit poorly: the features are
    // unconfirmed. On fr1/desk these are the motion-blurred frames, where many inliers still
    // agree on a pose 3-5 cm off (the blur moves every keypoint alike).
    v.state = TrackingState::kDegraded;
  } else if (features_hold) {
    // Enough well spread inliers: dense alignment from the motion model that failed to converge
    // (a large step beyond its basin, missing depth) or fit poorly is no evidence against them;
    // only contradiction is.
    v.state = TrackingState::kOk;
  } else if (dense_holds && !features) {
    v.state = TrackingState::kOk;  // dense alone by configuration, and it holds
  } else if (dense_holds || features_some) {
    // One source alone: a low-texture view (dense without feature support) or a few inliers.
    // Dense alone can converge to the wrong translation with the rotation right (large baselines
    // on plain scenes): never ok.
    v.state = TrackingState::kDegraded;
  } else {
    v.state = TrackingState::kLost;
  }
  if (v.state == TrackingState::kOk) q.reasons = 0;
  return v;
}

double inlier_spread(const std::vector<Eigen::Vector2f>& uv, const PinholeCamera& camera) {
  constexpr int kCells = 4;
  std::array<bool, kCells * kCells> hit{};
  if (camera.width <= 0 || camera.height <= 0) return 0.0;
  for (const Eigen::Vector2f& p : uv) {
    const int cx = static_cast<int>(p.x() * kCells / camera.width);
    const int cy = static_cast<int>(p.y() * kCells / camera.height);
    if (cx < 0 || cy < 0 || cx >= kCells || cy >= kCells) continue;
    hit[cy * kCells + cx] = true;
  }
  int n = 0;
  for (const bool h : hit) n += h;
  return static_cast<double>(n) / (kCells * kCells);
}

}  // namespace dqo::tracking
