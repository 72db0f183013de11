#pragma once
// SE(3) pose-graph optimisation over keyframes (Ceres): the correction of a loop. Each edge holds
// a measured relative pose T̂_ab (keyframe b in keyframe a's frame) with a 6x6 information for
// the right perturbation T_ab = T̂_ab exp(δ), δ = [ρ; φ] (OdometryCost in residuals.h). Fixed
// nodes hold the gauge.

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "dqo_map/geometry/se3.h"

namespace dqo::tracking {

struct PoseGraphNode {
  uint64_t id = 0;
  SE3 T_wc;
  bool fixed = false;
};

struct PoseGraphEdge {
  int from = 0;  // indices into the node list
  int to = 0;
  SE3 T_from_to;
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Identity();
};

struct PoseGraphResult {
  bool ok = false;
  std::vector<SE3> T_wc;  // per node, after optimisation (fixed nodes unchanged)
  double initial_cost = 0.0;
  double final_cost = 0.0;
};

// Whitened residual r = S [t_E; 2 vec(q_E)] of one edge at the given poses, SᵀS = information,
// E = T̂_ab⁻¹ T_wa⁻¹ T_wb (what the optimiser minimises; for tests and diagnostics).
Eigen::Matrix<double, 6, 1> pose_graph_residual(const SE3& T_wa, const SE3& T_wb,
                                                const PoseGraphEdge& edge);

// Minimises Σ ‖r‖² over the free nodes (no robust kernel: the edges are verified). Needs one
// fixed node at least (else the first is held).
PoseGraphResult optimise_pose_graph(const std::vector<PoseGraphNode>& nodes,
                                    const std::vector<PoseGraphEdge>& edges, int iterations);

// The information of an edge: σ_t (m) and σ_r (rad) isotropic, scaled by `weight`.
Eigen::Matrix<double, 6, 6> isotropic_information(double sigma_t, double sigma_r, double weight);

}  // namespace dqo::tracking
