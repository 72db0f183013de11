#include "assignment.h"

#include <algorithm>
#include <cmath>

#include "dqo_map/common/min_cost_assignment.h"

namespace dqo::objects {

namespace {

// One dense block: scores turned into the square cost matrix of the shared Hungarian method.
std::vector<int> solve_dense(const Eigen::MatrixXd& scores) {
  const int rows = static_cast<int>(scores.rows());
  const int cols = static_cast<int>(scores.cols());
  std::vector<int> row_to_col(static_cast<size_t>(rows), -1);
  if (rows == 0 || cols == 0) return row_to_col;
  // Square cost matrix: −score for admissible pairs, 0 for inadmissible ones and for the padding.
  // Minimising the cost then maximises the summed score; a row left on a zero entry is unassigned.
  const int n = std::max(rows, cols);
  auto cost = [&](int i, int j) -> double {
    if (i >= rows || j >= cols) return 0.0;
    const double s = scores(i, j);
    return std::isfinite(s) && s > 0.0 ? -s : 0.0;
  };
  Eigen::MatrixXd square(n, n);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) square(i, j) = cost(i, j);
  }
  const std::vector<int> col_of_row = min_cost_assignment(square);
  for (int i = 0; i < rows; ++i) {
    const int c = col_of_row[static_cast<size_t>(i)];
    if (c < cols && cost(i, c) < 0.0) row_to_col[static_cast<size_t>(i)] = c;
  }
  return row_to_col;
}

int find_root(std::vector<int>& parent, int x) {
  while (parent[x] != x) {
    parent[x] = parent[parent[x]];
    x = parent[x];
  }
  return x;
}

}  // namespace

std::vector<int> solve_assignment(const Eigen::MatrixXd& scores) {
  const int rows = static_cast<int>(scores.rows());
  const int cols = static_cast<int>(scores.cols());
  std::vector<int> row_to_col(static_cast<size_t>(rows), -1);
  // Admissible pairs are sparse (an object overlaps few detections), and the optimum decomposes
  // over the connected components of the bipartite graph of admissible pairs: solving each
  // component alone keeps the cubic cost to the size of a component, not of the whole keyframe.
  std::vector<int> parent(static_cast<size_t>(rows + cols));
  for (size_t k = 0; k < parent.size(); ++k) parent[k] = static_cast<int>(k);
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < cols; ++j) {
      const double s = scores(i, j);
      if (std::isfinite(s) && s > 0.0) parent[find_root(parent, i)] = find_root(parent, rows + j);
    }
  }
  std::vector<std::vector<int>> comp_rows(parent.size()), comp_cols(parent.size());
  for (int i = 0; i < rows; ++i) comp_rows[find_root(parent, i)].push_back(i);
  for (int j = 0; j < cols; ++j) comp_cols[find_root(parent, rows + j)].push_back(j);
  for (size_t c = 0; c < parent.size(); ++c) {
    const std::vector<int>& r = comp_rows[c];
    const std::vector<int>& k = comp_cols[c];
    if (r.empty() || k.empty()) continue;
    Eigen::MatrixXd block(static_cast<Eigen::Index>(r.size()), static_cast<Eigen::Index>(k.size()));
    for (size_t a = 0; a < r.size(); ++a) {
      for (size_t b = 0; b < k.size(); ++b) block(a, b) = scores(r[a], k[b]);
    }
    const std::vector<int> sub = solve_dense(block);
    for (size_t a = 0; a < r.size(); ++a) {
      if (sub[a] >= 0) row_to_col[static_cast<size_t>(r[a])] = k[static_cast<size_t>(sub[a])];
    }
  }
  return row_to_col;
}

}  // namespace dqo::objects
