#pragma once
// Pose-only refinement of one frame in Ceres: reprojection and depth residuals of its matched 3D
// points (Huber), optionally a prior from the dense alignment, and ORB-SLAM2's outlier rounds
// (optimise, classify every observation by its chi-square, optimise again on the inliers, the
// robust kernel dropped for the last rounds). A free function: no state.

#include <vector>

#include <Eigen/Core>

#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"
#include "dqo_map/tracking/tracker_params.h"

namespace dqo::tracking {

struct PoseObservation {
  Eigen::Vector3d p_w = Eigen::Vector3d::Zero();
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();  // level-0 pixel of the keypoint
  double depth = 0.0;      // measured depth at the keypoint (metres); 0: reprojection only
  double inv_sigma = 1.0;  // 1 / σ of the keypoint position in pixels (1 / level scale)
  double depth_sigma = 0.0;  // σ of the depth residual (metres); 0: depth_sigma(depth, params)
};

// The dense alignment of the current frame to a reference frame, as a Gaussian on the pose.
struct DensePrior {
  SE3 T_w_ref;   // the reference frame's pose, held fixed
  SE3 T_ref_cur; // the dense estimate
  // Right perturbation of T_ref_cur, [rho; phi] (dense_alignment.h), already weighted.
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
};

struct PoseOptimisationResult {
  SE3 T_wc;
  std::vector<char> inlier;  // per observation
  int inliers = 0;
  double prior_chi2 = 0.0;   // δᵀΛδ of the dense prior at the solution (0 without one)
  bool solved = false;        // Ceres ran to convergence or to its iteration limit
};

// Chi-square thresholds at 95 %: 2 DoF for a reprojection, 3 with depth (ORB-SLAM2's values).
constexpr double kChi2Mono = 5.991;
constexpr double kChi2Rgbd = 7.815;

// σ of a depth measurement: k z², never below a floor that covers the map point's own error.
double depth_sigma(double depth, const PoseOptimiserParams& params);

// σ of the depth residual of a keypoint: the sensor's noise, what a keypoint position error
// of one pixel at its level (`scale` pixels at level 0) does on a surface of that slope, and
// `sync_sigma` (Keypoint::depth_sync_sigma: depth captured apart from the colour), in quadrature.
double keypoint_depth_sigma(double depth, double slope, double scale,
                            const PoseOptimiserParams& params, double sync_sigma = 0.0);
// The same for a keypoint matched to a 3D point measured by another depth image: both sensors'
// noise counts (and sync_sigma for both).
double match_depth_sigma(double depth, double slope, double scale,
                         const PoseOptimiserParams& params, double sync_sigma = 0.0);

PoseOptimisationResult optimise_pose(const SE3& T_wc_guess,
                                     const std::vector<PoseObservation>& observations,
                                     const PinholeCamera& camera, const DensePrior* prior,
                                     const PoseOptimiserParams& params);

// The whitened squared error of one observation at T_wc (reprojection plus depth when measured);
// +inf behind the camera.
double observation_chi2(const SE3& T_wc, const PoseObservation& observation,
                        const PinholeCamera& camera, const PoseOptimiserParams& params);

}  // namespace dqo::tracking
