#include "pose_graph.h"

#include <algorithm>
#include <cmath>

#include <ceres/manifold.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include "ceres_poses.h"
#include "residuals.h"

namespace dqo::tracking {

Eigen::Matrix<double, 6, 1> pose_graph_residual(const SE3& T_wa, const SE3& T_wb,
                                                const PoseGraphEdge& edge) {
  const SE3 T_aw = T_wa.inverse(), T_bw = T_wb.inverse();
  Eigen::Quaterniond q_a = T_aw.quaternion(), q_b = T_bw.quaternion();
  Eigen::Vector3d t_a = T_aw.translation(), t_b = T_bw.translation();
  const OdometryCost cost(edge.T_from_to, sqrt_information(edge.information));
  Eigen::Matrix<double, 6, 1> r;
  cost(q_a.coeffs().data(), t_a.data(), q_b.coeffs().data(), t_b.data(), r.data());
  return r;
}

Eigen::Matrix<double, 6, 6> isotropic_information(double sigma_t, double sigma_r, double weight) {
  Eigen::Matrix<double, 6, 6> info = Eigen::Matrix<double, 6, 6>::Zero();
  info.topLeftCorner<3, 3>().diagonal().setConstant(weight / (sigma_t * sigma_t));
  info.bottomRightCorner<3, 3>().diagonal().setConstant(weight / (sigma_r * sigma_r));
  return info;
}

PoseGraphResult optimise_pose_graph(const std::vector<PoseGraphNode>& nodes,
                                    const std::vector<PoseGraphEdge>& edges, int iterations) {
  PoseGraphResult result;
  for (const PoseGraphNode& n : nodes) result.T_wc.push_back(n.T_wc);
  if (nodes.empty() || edges.empty()) return result;
  // Ceres works on T_cw (q, t), as bundle adjustment does.
  CameraBlocks cams(result.T_wc);
  auto& q = cams.q;
  auto& t = cams.t;
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::EigenQuaternionManifold quaternion_manifold;
  ceres::Problem problem(problem_options);
  std::vector<char> used(nodes.size(), 0);
  for (const PoseGraphEdge& e : edges) {
    if (e.from < 0 || e.to < 0 || e.from >= static_cast<int>(nodes.size()) ||
        e.to >= static_cast<int>(nodes.size()) || e.from == e.to)
      continue;
    for (const int k : {e.from, e.to}) {
      if (used[k]) continue;
      used[k] = 1;
      cams.add_to(&problem, static_cast<size_t>(k), &quaternion_manifold);
    }
    problem.AddResidualBlock(OdometryCost::Create(e.T_from_to, sqrt_information(e.information)),
                             nullptr, q[e.from].coeffs().data(), t[e.from].data(),
                             q[e.to].coeffs().data(), t[e.to].data());
  }
  bool any_fixed = false;
  for (size_t i = 0; i < nodes.size(); ++i) {
    if (!used[i] || !nodes[i].fixed) continue;
    problem.SetParameterBlockConstant(q[i].coeffs().data());
    problem.SetParameterBlockConstant(t[i].data());
    any_fixed = true;
  }
  if (!any_fixed) {
    for (size_t i = 0; i < nodes.size(); ++i) {
      if (!used[i]) continue;
      problem.SetParameterBlockConstant(q[i].coeffs().data());
      problem.SetParameterBlockConstant(t[i].data());
      break;
    }
  }
  const ceres::Solver::Summary summary = solve_pose_problem(&problem, iterations);
  result.initial_cost = summary.initial_cost;
  result.final_cost = summary.final_cost;
  if (summary.termination_type == ceres::FAILURE || !std::isfinite(summary.final_cost))
    return result;
  for (size_t i = 0; i < nodes.size(); ++i)
    if (used[i] && !nodes[i].fixed) result.T_wc[i] = cams.T_wc(i);
  result.ok = true;
  return result;
}

}  // namespace dqo::tracking
