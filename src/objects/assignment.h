#pragma once
// One-to-one assignment of rows (map objects) to columns (detections) that maximises the summed
// score of the chosen pairs (Hungarian method with potentials, O(n³) in the size n of the largest
// connected component of the admissible pairs: the problem splits along those components).
// Only admissible pairs may be chosen: an entry that is not finite (use kForbidden) is not a pair.
// No row and no column is used twice, by construction of the method.
#include <limits>
#include <vector>
#include <Eigen/Core>

namespace dqo::objects {

constexpr double kForbidden = -std::numeric_limits<double>::infinity();

// scores: rows x cols; admissible entries finite and > 0 (a pair worth nothing is not worth
// taking). Returns, per row, the chosen column or -1.
std::vector<int> solve_assignment(const Eigen::MatrixXd& scores);

}  // namespace dqo::objects
