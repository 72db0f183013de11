#include "relocaliser.h"

#include <algorithm>
#include <random>

#include <Eigen/Geometry>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "matching.h"
#include "pose_optimiser.h"

namespace dqo::tracking {
namespace {

// Without a vocabulary to narrow the candidates, brute force sees more look-alikes than
// ORB-SLAM2's bag-of-words search: a stricter ratio keeps PnP's inlier ratio workable.
constexpr float kRatio = 0.9f;
constexpr int kMaxDistance = 80;
constexpr int kMinMatchesForPnp = 12;

struct KeyframeMatches {
  uint64_t keyframe = kNoId;
  std::vector<std::pair<int, uint64_t>> matches;  // (frame keypoint, map point)
};

KeyframeMatches match_keyframe(const OrbFrame& frame, const KeyFrame& kf, const MapStore& map) {
  KeyframeMatches out;
  out.keyframe = kf.id;
  std::vector<Descriptor> train;
  std::vector<int> train_keypoint;
  for (size_t i = 0; i < kf.map_points.size(); ++i) {
    if (map.map_point(kf.map_points[i]) == nullptr) continue;
    train.push_back(kf.features.descriptors[i]);
    train_keypoint.push_back(static_cast<int>(i));
  }
  std::vector<std::pair<int, int>> pairs =
      match_descriptors(frame.descriptors, train, kRatio, kMaxDistance);
  // Orientation consistency, as ORB-SLAM2's SearchByBoW.
  std::vector<Match> matches;
  for (const auto& [q, t] : pairs) matches.push_back({q, t, 0});
  keep_consistent_orientation(
      frame,
      [&](const Match& m) { return kf.features.keypoints[train_keypoint[m.candidate]].angle; },
      &matches);
  for (const Match& m : matches)
    out.matches.emplace_back(m.keypoint, kf.map_points[train_keypoint[m.candidate]]);
  return out;
}

PnpResult solve_pnp(const OrbFrame& frame, const KeyframeMatches& km, const MapStore& map,
                    const PinholeCamera& camera, const ScalePyramid& scales,
                    const PoseOptimiserParams& pose_params, int min_inliers) {
  PnpResult result;
  result.keyframe = km.keyframe;
  if (static_cast<int>(km.matches.size()) < std::max(kMinMatchesForPnp, 4)) return result;
  std::vector<cv::Point3f> object;
  std::vector<cv::Point2f> image;
  for (const auto& [k, id] : km.matches) {
    const Eigen::Vector3d& p = map.map_point(id)->p_w;
    object.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()),
                        static_cast<float>(p.z()));
    image.emplace_back(frame.keypoints[k].uv.x(), frame.keypoints[k].uv.y());
  }
  cv::Mat K = (cv::Mat_<double>(3, 3) << camera.fx, 0, camera.cx, 0, camera.fy, camera.cy, 0, 0, 1);
  cv::Mat rvec, tvec;
  std::vector<int> ransac_inliers;
  const bool solved = cv::solvePnPRansac(object, image, K, cv::noArray(), rvec, tvec, false, 200,
                                         4.0f, 0.99, ransac_inliers, cv::SOLVEPNP_EPNP);
  if (!solved || static_cast<int>(ransac_inliers.size()) < std::max(6, min_inliers / 2))
    return result;
  cv::Mat R_cv;
  cv::Rodrigues(rvec, R_cv);
  Eigen::Matrix3d R_cw;
  Eigen::Vector3d t_cw;
  cv::cv2eigen(R_cv, R_cw);
  cv::cv2eigen(tvec, t_cw);
  const SE3 T_wc = SE3::from_rotation_translation(R_cw, t_cw).inverse();

  // Refine on RANSAC's inliers (with depth), then take back every match that agrees with the
  // refined pose: the first optimisation round must not start among the outliers.
  auto observation = [&](const std::pair<int, uint64_t>& m) {
    PoseObservation o;
    o.p_w = map.map_point(m.second)->p_w;
    o.uv = frame.keypoints[m.first].uv.cast<double>();
    const Keypoint& kp = frame.keypoints[m.first];
    o.depth = kp.depth;
    o.inv_sigma = scales.inv_scale[kp.octave];
    o.depth_sigma = match_depth_sigma(kp.depth, kp.depth_slope, scales.scale[kp.octave], pose_params,
                                      kp.depth_sync_sigma);
    return o;
  };
  std::vector<PoseObservation> observations;
  for (const int i : ransac_inliers) observations.push_back(observation(km.matches[i]));
  const PoseOptimisationResult refined =
      optimise_pose(T_wc, observations, camera, nullptr, pose_params);
  for (const auto& m : km.matches) {
    const PoseObservation o = observation(m);
    const double limit = o.depth > 0.0 ? kChi2Rgbd : kChi2Mono;
    if (observation_chi2(refined.T_wc, o, camera, pose_params) <= limit) result.matches.push_back(m);
  }
  if (static_cast<int>(result.matches.size()) < min_inliers) {
    result.matches.clear();
    return result;
  }
  result.ok = true;
  result.T_wc = refined.T_wc;
  return result;
}

// RGB-D relocalisation: the frame's keypoints have depth, so three matches fix a rigid pose and a
// match agrees with it in 3D, which tells right from wrong far more sharply than a reprojection
// does. Where the texture repeats, brute-force matching keeps few right matches (a ratio test
// rejects look-alikes): a handful agreeing in 3D is a hypothesis, and the caller checks it
// against the local map (relocalise_frame: reloc.min_inliers after a projection search).
constexpr int kRigidIterations = 300;
constexpr int kMinRigidInliers = 8;

PnpResult solve_rigid(const OrbFrame& frame, const KeyframeMatches& km, const MapStore& map,
                      const PinholeCamera& camera) {
  PnpResult result;
  result.keyframe = km.keyframe;
  std::vector<Eigen::Vector3d> p_c, p_w;
  std::vector<size_t> index;
  for (size_t i = 0; i < km.matches.size(); ++i) {
    const auto& [k, id] = km.matches[i];
    if (!frame.has_depth(k)) continue;
    p_c.push_back(frame.point_c(k, camera));
    p_w.push_back(map.map_point(id)->p_w);
    index.push_back(i);
  }
  const int n = static_cast<int>(p_c.size());
  if (n < kMinRigidInliers) return result;
  // A fixed seed: relocalisation gives the same answer for the same input (offline determinism).
  std::mt19937 rng(12345);
  std::uniform_int_distribution<int> pick(0, n - 1);
  auto inliers_of = [&](const SE3& T_wc, std::vector<int>* in) {
    in->clear();
    for (int i = 0; i < n; ++i) {
      // Depth noise grows with z²; 2 cm floor for keypoint position and map point error.
      const double z = p_c[i].z();
      const double tolerance = std::max(0.02, 3.0 * 0.0015 * z * z);
      if ((T_wc * p_c[i] - p_w[i]).norm() < tolerance) in->push_back(i);
    }
  };
  std::vector<int> best, in;
  SE3 best_T;
  for (int it = 0; it < kRigidIterations; ++it) {
    const int a = pick(rng), b = pick(rng), c = pick(rng);
    if (a == b || b == c || a == c) continue;
    Eigen::Matrix3d src, dst;
    src << p_c[a], p_c[b], p_c[c];
    dst << p_w[a], p_w[b], p_w[c];
    // Degenerate triples (nearly collinear) fit anything along their line.
    if ((p_c[b] - p_c[a]).cross(p_c[c] - p_c[a]).norm() < 1e-4) continue;
    const Eigen::Matrix4d M = Eigen::umeyama(src, dst, false);
    const SE3 T = SE3::from_rotation_translation(M.topLeftCorner<3, 3>(), M.topRightCorner<3, 1>());
    inliers_of(T, &in);
    if (in.size() > best.size()) {
      best = in;
      best_T = T;
    }
  }
  if (static_cast<int>(best.size()) < kMinRigidInliers) return result;
  // Refit on every inlier.
  Eigen::Matrix3Xd src(3, best.size()), dst(3, best.size());
  for (size_t j = 0; j < best.size(); ++j) {
    src.col(static_cast<Eigen::Index>(j)) = p_c[best[j]];
    dst.col(static_cast<Eigen::Index>(j)) = p_w[best[j]];
  }
  const Eigen::Matrix4d M = Eigen::umeyama(src, dst, false);
  result.T_wc = SE3::from_rotation_translation(M.topLeftCorner<3, 3>(), M.topRightCorner<3, 1>());
  inliers_of(result.T_wc, &best);
  if (static_cast<int>(best.size()) < kMinRigidInliers) return result;
  for (const int j : best) result.matches.push_back(km.matches[index[j]]);
  result.ok = true;
  return result;
}

}  // namespace

PnpResult pnp_against_keyframe(const OrbFrame& frame, const KeyFrame& keyframe,
                               const MapStore& map, const PinholeCamera& camera,
                               const ScalePyramid& scales, const PoseOptimiserParams& pose_params,
                               int min_inliers) {
  return solve_pnp(frame, match_keyframe(frame, keyframe, map), map, camera, scales, pose_params,
                   min_inliers);
}

PnpResult relocalise(const OrbFrame& frame, const MapStore& map,
                     const std::vector<uint64_t>& candidates, const PinholeCamera& camera,
                     const ScalePyramid& scales, const PoseOptimiserParams& pose_params,
                     const RelocParams& params) {
  std::vector<KeyframeMatches> ranked;
  for (const uint64_t id : candidates) {
    const KeyFrame* kf = map.keyframe(id);
    if (kf == nullptr) continue;
    KeyframeMatches km = match_keyframe(frame, *kf, map);
    if (static_cast<int>(km.matches.size()) >= kMinMatchesForPnp) ranked.push_back(std::move(km));
  }
  std::sort(ranked.begin(), ranked.end(), [](const KeyframeMatches& a, const KeyframeMatches& b) {
    return a.matches.size() > b.matches.size();
  });
  const size_t tries = std::min(ranked.size(), static_cast<size_t>(std::max(1, params.max_pnp)));
  for (size_t i = 0; i < tries; ++i) {
    PnpResult r =
        solve_pnp(frame, ranked[i], map, camera, scales, pose_params, params.min_inliers);
    if (r.ok) return r;
  }
  // PnP found nothing among the matches: hypotheses from those that agree in 3D.
  for (size_t i = 0; i < tries; ++i) {
    PnpResult r = solve_rigid(frame, ranked[i], map, camera);
    if (r.ok) return r;
  }
  return PnpResult{};
}

}  // namespace dqo::tracking
