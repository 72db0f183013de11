#pragma once
// Minimum-cost perfect assignment of a square cost matrix: the Hungarian method with potentials
// (shortest augmenting paths, O(n³)). One implementation for the association of detections to map
// objects (objects/assignment.h) and the matching of estimates to ground truth (eval/).
#include <vector>
#include <Eigen/Core>

namespace dqo {

// cost: n x n, finite. Returns col_of_row: row i is assigned column col_of_row[i]; every row and
// every column is used exactly once. Callers express "no pair" by padding rows/columns and by
// costs that make a pair never worth taking.
std::vector<int> min_cost_assignment(const Eigen::MatrixXd& cost);

}  // namespace dqo
