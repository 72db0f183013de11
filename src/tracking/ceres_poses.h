#pragma once
// What the small pose problems over whole trajectories share (the loop's pose graph, the final
// smoother): camera poses as Ceres parameters, the way bundle adjustment keeps them (T_cw as a
// unit quaternion on Eigen's quaternion manifold, and a translation), and one solver setting.
// Internal to src/tracking (Ceres stays out of the public headers).

#include <algorithm>
#include <vector>

#include <Eigen/Geometry>
#include <ceres/manifold.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include "dqo_map/geometry/se3.h"

namespace dqo::tracking {

struct CameraBlocks {
  explicit CameraBlocks(const std::vector<SE3>& T_wc) : q(T_wc.size()), t(T_wc.size()) {
    for (size_t i = 0; i < T_wc.size(); ++i) {
      const SE3 T_cw = T_wc[i].inverse();
      q[i] = T_cw.quaternion();
      t[i] = T_cw.translation();
    }
  }
  void add_to(ceres::Problem* problem, size_t i, ceres::Manifold* quaternion_manifold) {
    problem->AddParameterBlock(q[i].coeffs().data(), 4, quaternion_manifold);
    problem->AddParameterBlock(t[i].data(), 3);
  }
  SE3 T_wc(size_t i) const { return SE3(q[i], t[i]).inverse(); }

  std::vector<Eigen::Quaterniond> q;
  std::vector<Eigen::Vector3d> t;
};

// Sparse normal Cholesky on one thread, silent: the same answer on any machine load.
inline ceres::Solver::Summary solve_pose_problem(ceres::Problem* problem, int iterations) {
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  options.max_num_iterations = std::max(1, iterations);
  options.num_threads = 1;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(options, problem, &summary);
  return summary;
}

}  // namespace dqo::tracking
