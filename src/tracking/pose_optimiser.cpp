#include "pose_optimiser.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include <Eigen/Eigenvalues>
#include <ceres/loss_function.h>
#include <ceres/manifold.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include "residuals.h"

namespace dqo::tracking {

Eigen::Matrix<double, 6, 6> sqrt_information(const Eigen::Matrix<double, 6, 6>& information) {
  const Eigen::Matrix<double, 6, 6> symmetric = 0.5 * (information + information.transpose());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(symmetric);
  const Eigen::Matrix<double, 6, 1> root = eig.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  return root.asDiagonal() * eig.eigenvectors().transpose();
}

double depth_sigma(double depth, const PoseOptimiserParams& params) {
  return std::max(params.depth_sigma_min_m, params.depth_sigma_per_m2 * depth * depth);
}

double keypoint_depth_sigma(double depth, double slope, double scale,
                            const PoseOptimiserParams& params, double sync_sigma) {
  const double sensor = depth_sigma(depth, params);
  const double position = slope * scale;
  return std::sqrt(sensor * sensor + position * position + sync_sigma * sync_sigma);
}

double match_depth_sigma(double depth, double slope, double scale,
                         const PoseOptimiserParams& params, double sync_sigma) {
  const double keypoint = keypoint_depth_sigma(depth, slope, scale, params, sync_sigma);
  // The point came from another depth image of the same sensor: as coarse as this one.
  const double point = depth_sigma(depth, params);
  return std::sqrt(keypoint * keypoint + point * point + sync_sigma * sync_sigma);
}

namespace {

double sigma_of(const PoseObservation& o, const PoseOptimiserParams& params) {
  return o.depth_sigma > 0.0 ? o.depth_sigma : depth_sigma(o.depth, params);
}

}  // namespace

double observation_chi2(const SE3& T_wc, const PoseObservation& o, const PinholeCamera& camera,
                        const PoseOptimiserParams& params) {
  const Eigen::Vector3d p_c = T_wc.inverse() * o.p_w;
  if (p_c.z() <= 1e-6) return std::numeric_limits<double>::infinity();
  const Eigen::Vector2d e =
      (Eigen::Vector2d(camera.fx * p_c.x() / p_c.z() + camera.cx,
                       camera.fy * p_c.y() / p_c.z() + camera.cy) -
       o.uv) *
      o.inv_sigma;
  double chi2 = e.squaredNorm();
  if (o.depth > 0.0) {
    const double ez = (p_c.z() - o.depth) / sigma_of(o, params);
    chi2 += ez * ez;
  }
  return chi2;
}

namespace {

// The residual blocks of one observation, built once and reused by every round.
struct ObservationBlocks {
  std::unique_ptr<ceres::CostFunction> reprojection;
  std::unique_ptr<ceres::CostFunction> depth;
  std::unique_ptr<ceres::LossFunction> depth_loss;
};

}  // namespace

PoseOptimisationResult optimise_pose(const SE3& T_wc_guess,
                                     const std::vector<PoseObservation>& observations,
                                     const PinholeCamera& camera, const DensePrior* prior,
                                     const PoseOptimiserParams& params) {
  PoseOptimisationResult result;
  result.T_wc = T_wc_guess;
  result.inlier.assign(observations.size(), 1);

  const Intrinsics K(camera);
  std::vector<ObservationBlocks> blocks(observations.size());
  for (size_t i = 0; i < observations.size(); ++i) {
    const PoseObservation& o = observations[i];
    blocks[i].reprojection.reset(ReprojectionCost::Create(K, o.p_w, o.uv, o.inv_sigma));
    if (o.depth > 0.0) {
      const double sigma = sigma_of(o, params);
      blocks[i].depth.reset(DepthCost::Create(o.p_w, o.depth, 1.0 / sigma));
      blocks[i].depth_loss = std::make_unique<ceres::HuberLoss>(params.huber_depth_m / sigma);
    }
  }
  ceres::HuberLoss reprojection_loss(params.huber_reprojection_px);
  std::unique_ptr<ceres::CostFunction> prior_cost;
  if (prior != nullptr) {
    prior_cost.reset(DensePriorCost::Create((prior->T_w_ref * prior->T_ref_cur).inverse(),
                                            sqrt_information(prior->information)));
  }
  ceres::EigenQuaternionManifold quaternion_manifold;

  // The optimisation variable is T_cw (the direction residuals use).
  const SE3 T_cw_guess = T_wc_guess.inverse();
  Eigen::Quaterniond q_cw = T_cw_guess.quaternion();
  Eigen::Vector3d t_cw = T_cw_guess.translation();

  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.enable_fast_removal = false;

  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = std::max(1, params.iterations);
  options.num_threads = 1;
  options.logging_type = ceres::SILENT;
  options.minimizer_progress_to_stdout = false;
  options.function_tolerance = 1e-6;
  options.parameter_tolerance = 1e-8;

  const int rounds = std::max(1, params.rounds);
  for (int round = 0; round < rounds; ++round) {
    // ORB-SLAM2 drops the robust kernel for the last rounds, once the outliers are out.
    const bool robust = round < std::max(1, rounds - 2);
    ceres::Problem problem(problem_options);
    problem.AddParameterBlock(q_cw.coeffs().data(), 4, &quaternion_manifold);
    problem.AddParameterBlock(t_cw.data(), 3);
    int used = 0;
    for (size_t i = 0; i < observations.size(); ++i) {
      if (!result.inlier[i]) continue;
      problem.AddResidualBlock(blocks[i].reprojection.get(), robust ? &reprojection_loss : nullptr,
                               q_cw.coeffs().data(), t_cw.data());
      if (blocks[i].depth) {
        problem.AddResidualBlock(blocks[i].depth.get(),
                                 robust ? blocks[i].depth_loss.get() : nullptr,
                                 q_cw.coeffs().data(), t_cw.data());
      }
      ++used;
    }
    if (prior_cost) {
      problem.AddResidualBlock(prior_cost.get(), nullptr, q_cw.coeffs().data(), t_cw.data());
    } else if (used < 3) {
      break;  // nothing to constrain the pose: keep the guess
    }
    ceres::Solver::Summary summary;
    ceres::Solve(options, &problem, &summary);
    result.solved = summary.termination_type == ceres::CONVERGENCE ||
                       summary.termination_type == ceres::NO_CONVERGENCE;
    result.T_wc = SE3(q_cw, t_cw).inverse();

    // Classify every observation, also those rejected before: they may come back.
    int inliers = 0;
    for (size_t i = 0; i < observations.size(); ++i) {
      const double chi2 = observation_chi2(result.T_wc, observations[i], camera, params);
      const double limit = observations[i].depth > 0.0 ? kChi2Rgbd : kChi2Mono;
      result.inlier[i] = chi2 <= limit;
      inliers += result.inlier[i];
    }
    result.inliers = inliers;
    if (inliers < 10 && !prior_cost) break;
  }

  if (prior_cost) {
    Eigen::Matrix<double, 6, 1> r;
    const double* parameters[2] = {q_cw.coeffs().data(), t_cw.data()};
    prior_cost->Evaluate(parameters, r.data(), nullptr);
    result.prior_chi2 = r.squaredNorm();
  }
  return result;
}

}  // namespace dqo::tracking
