#include "assignment.h"

#include <algorithm>
#include <cmath>

namespace dqo::objects {

namespace {

// The Hungarian method on one dense block.
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
  // Potentials u (rows), v (columns) and the column-to-row matching p, 1-based with 0 a sentinel
  // (the shortest augmenting path formulation of the Hungarian method).
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> u(n + 1, 0.0), v(n + 1, 0.0);
  std::vector<int> p(n + 1, 0), way(n + 1, 0);
  for (int i = 1; i <= n; ++i) {
    p[0] = i;
    int j0 = 0;
    std::vector<double> minv(n + 1, inf);
    std::vector<bool> used(n + 1, false);
    do {
      used[j0] = true;
      const int i0 = p[j0];
      double delta = inf;
      int j1 = 0;
      for (int j = 1; j <= n; ++j) {
        if (used[j]) continue;
        const double cur = cost(i0 - 1, j - 1) - u[i0] - v[j];
        if (cur < minv[j]) {
          minv[j] = cur;
          way[j] = j0;
        }
        if (minv[j] < delta) {
          delta = minv[j];
          j1 = j;
        }
      }
      for (int j = 0; j <= n; ++j) {
        if (used[j]) {
          u[p[j]] += delta;
          v[j] -= delta;
        } else {
          minv[j] -= delta;
        }
      }
      j0 = j1;
    } while (p[j0] != 0);
    do {
      const int j1 = way[j0];
      p[j0] = p[j1];
      j0 = j1;
    } while (j0 != 0);
  }
  for (int j = 1; j <= n; ++j) {
    const int i = p[j] - 1;
    const int c = j - 1;
    if (i < rows && c < cols && cost(i, c) < 0.0) row_to_col[static_cast<size_t>(i)] = c;
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
