#include "trajectory_refiner.h"

#include <algorithm>
#include <cmath>

#include <ceres/autodiff_cost_function.h>
#include <ceres/manifold.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include "ceres_poses.h"
#include "residuals.h"

namespace dqo::tracking {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

// Three consecutive poses, each as (q_cw, t_cw) (residuals.h). The prior is constant velocity on
// SE(3) (ORB-SLAM2's motion model): each step's motion in the camera's own frame, per second,
// changes little from one step to the next. A camera orbiting at a steady rate has zero residual
// however fast it turns; a hand-held camera's jolts are what σ allows.
struct AccelerationCost {
  AccelerationCost(double dt1, double dt2, double inv_sigma_a, double inv_sigma_alpha)
      : dt1_(dt1), dt2_(dt2), inv_sigma_a_(inv_sigma_a), inv_sigma_alpha_(inv_sigma_alpha) {}

  template <typename T>
  bool operator()(const T* q0, const T* t0, const T* q1, const T* t1, const T* q2, const T* t2,
                  T* r) const {
    using Q = Eigen::Quaternion<T>;
    using V = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Q> qa(q0), qb(q1), qc(q2);
    const Eigen::Map<const V> ta(t0), tb(t1), tc(t2);
    // T_prev,next = T_prev,w T_w,next: rotation q_prev q_next⁻¹, translation t_prev − R t_next.
    auto step = [](const Eigen::Map<const Q>& q_prev, const Eigen::Map<const V>& t_prev,
                   const Eigen::Map<const Q>& q_next, const Eigen::Map<const V>& t_next, T dt) {
      Q q = q_prev * q_next.conjugate();
      const V t = t_prev - q * t_next;
      if (q.w() < T(0.0)) q.coeffs() = -q.coeffs();
      Eigen::Matrix<T, 6, 1> xi;
      xi.template head<3>() = t / dt;
      xi.template tail<3>() = T(2.0) * q.vec() / dt;
      return xi;
    };
    const Eigen::Matrix<T, 6, 1> xi1 = step(qa, ta, qb, tb, T(dt1_));
    const Eigen::Matrix<T, 6, 1> xi2 = step(qb, tb, qc, tc, T(dt2_));
    const T mean_dt = T(0.5 * (dt1_ + dt2_));
    for (int i = 0; i < 3; ++i) {
      r[i] = (xi2[i] - xi1[i]) / mean_dt * T(inv_sigma_a_);
      r[3 + i] = (xi2[3 + i] - xi1[3 + i]) / mean_dt * T(inv_sigma_alpha_);
    }
    return true;
  }

  static ceres::CostFunction* Create(double dt1, double dt2, double inv_sigma_a,
                                     double inv_sigma_alpha) {
    return new ceres::AutoDiffCostFunction<AccelerationCost, 6, 4, 3, 4, 3, 4, 3>(
        new AccelerationCost(dt1, dt2, inv_sigma_a, inv_sigma_alpha));
  }

  double dt1_, dt2_, inv_sigma_a_, inv_sigma_alpha_;
};

Eigen::Matrix<double, 6, 6> measurement_sqrt_information(const RefineParams& p, bool degraded) {
  const double scale = degraded ? p.degraded_sigma_scale : 1.0;
  Eigen::Matrix<double, 6, 6> S = Eigen::Matrix<double, 6, 6>::Zero();
  S.topLeftCorner<3, 3>().diagonal().setConstant(1.0 / (scale * p.sigma_m));
  S.bottomRightCorner<3, 3>().diagonal().setConstant(1.0 / (scale * p.sigma_deg * kDegToRad));
  return S;
}

}  // namespace

Eigen::Matrix<double, 6, 1> acceleration_residual(const SE3& T0, const SE3& T1, const SE3& T2,
                                                  double dt1, double dt2, const RefineParams& p) {
  const AccelerationCost cost(dt1, dt2, 1.0 / p.acceleration_sigma,
                              1.0 / (p.angular_acceleration_sigma_deg * kDegToRad));
  SE3 T[3] = {T0.inverse(), T1.inverse(), T2.inverse()};
  Eigen::Quaterniond q[3];
  Eigen::Vector3d t[3];
  for (int i = 0; i < 3; ++i) {
    q[i] = T[i].quaternion();
    t[i] = T[i].translation();
  }
  Eigen::Matrix<double, 6, 1> r;
  cost(q[0].coeffs().data(), t[0].data(), q[1].coeffs().data(), t[1].data(), q[2].coeffs().data(),
       t[2].data(), r.data());
  return r;
}

std::vector<SE3> refine_trajectory(const std::vector<RefinerFrame>& frames, const RefineParams& p) {
  std::vector<SE3> out;
  for (const RefinerFrame& f : frames) out.push_back(f.T_wc);
  if (frames.size() < 3) return out;
  CameraBlocks cams(out);  // T_cw (q, t), as bundle adjustment keeps it
  auto& q = cams.q;
  auto& t = cams.t;
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::EigenQuaternionManifold quaternion_manifold;
  ceres::Problem problem(problem_options);
  for (size_t i = 0; i < frames.size(); ++i) {
    cams.add_to(&problem, i, &quaternion_manifold);
    problem.AddResidualBlock(
        DensePriorCost::Create(frames[i].T_wc.inverse(), measurement_sqrt_information(p, frames[i].degraded)),
        nullptr, q[i].coeffs().data(), t[i].data());
  }
  const double inv_sigma_a = 1.0 / p.acceleration_sigma;
  const double inv_sigma_alpha = 1.0 / (p.angular_acceleration_sigma_deg * kDegToRad);
  int tied = 0;
  for (size_t i = 1; i + 1 < frames.size(); ++i) {
    const double dt1 = frames[i].timestamp - frames[i - 1].timestamp;
    const double dt2 = frames[i + 1].timestamp - frames[i].timestamp;
    if (dt1 <= 1e-6 || dt2 <= 1e-6 || dt1 > p.max_gap_s || dt2 > p.max_gap_s) continue;
    problem.AddResidualBlock(AccelerationCost::Create(dt1, dt2, inv_sigma_a, inv_sigma_alpha),
                             nullptr, q[i - 1].coeffs().data(), t[i - 1].data(),
                             q[i].coeffs().data(), t[i].data(), q[i + 1].coeffs().data(),
                             t[i + 1].data());
    ++tied;
  }
  if (tied == 0) return out;
  const ceres::Solver::Summary summary = solve_pose_problem(&problem, p.iterations);
  if (summary.termination_type == ceres::FAILURE || !std::isfinite(summary.final_cost)) return out;
  for (size_t i = 0; i < frames.size(); ++i) out[i] = cams.T_wc(i);
  return out;
}

}  // namespace dqo::tracking
