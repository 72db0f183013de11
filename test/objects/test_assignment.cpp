// The one-to-one assignment against a brute-force optimum on random score matrices.
#include <algorithm>
#include <functional>
#include <random>
#include <set>
#include <gtest/gtest.h>
#include "../../src/objects/assignment.h"

namespace dqo::objects {
namespace {

// The best summed score over every partial matching (rows in order, each taking a free column or
// none): exponential, for small matrices only.
double brute_force_best(const Eigen::MatrixXd& s) {
  std::vector<bool> used(static_cast<size_t>(s.cols()), false);
  std::function<double(int)> best = [&](int row) -> double {
    if (row == s.rows()) return 0.0;
    double b = best(row + 1);  // row unassigned
    for (int c = 0; c < s.cols(); ++c) {
      if (used[c] || !std::isfinite(s(row, c)) || !(s(row, c) > 0.0)) continue;
      used[c] = true;
      b = std::max(b, s(row, c) + best(row + 1));
      used[c] = false;
    }
    return b;
  };
  return best(0);
}

TEST(Assignment, MatchesBruteForceAndNeverReusesAColumn) {
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> score(0.0, 2.0);
  std::uniform_int_distribution<int> size(0, 6);
  std::bernoulli_distribution forbid(0.4);
  for (int trial = 0; trial < 400; ++trial) {
    const int rows = size(rng), cols = size(rng);
    Eigen::MatrixXd s(rows, cols);
    for (int r = 0; r < rows; ++r) {
      for (int c = 0; c < cols; ++c) s(r, c) = forbid(rng) ? kForbidden : score(rng);
    }
    const std::vector<int> a = solve_assignment(s);
    ASSERT_EQ(static_cast<int>(a.size()), rows);
    std::set<int> columns;
    double total = 0.0;
    for (int r = 0; r < rows; ++r) {
      if (a[r] < 0) continue;
      ASSERT_LT(a[r], cols);
      EXPECT_TRUE(columns.insert(a[r]).second) << "column " << a[r] << " used twice";
      ASSERT_TRUE(std::isfinite(s(r, a[r]))) << "forbidden pair chosen";
      total += s(r, a[r]);
    }
    EXPECT_NEAR(total, brute_force_best(s), 1e-9) << "trial " << trial;
  }
}

TEST(Assignment, PrefersTheGlobalOptimumOverGreedy) {
  // Greedy would take (0, 0) = 0.9 and leave row 1 with nothing; the optimum pairs crosswise.
  Eigen::MatrixXd s(2, 2);
  s << 0.9, 0.8, 0.7, kForbidden;
  const std::vector<int> a = solve_assignment(s);
  EXPECT_EQ(a, std::vector<int>({1, 0}));
}

TEST(Assignment, EmptyAndAllForbidden) {
  EXPECT_TRUE(solve_assignment(Eigen::MatrixXd(0, 3)).empty());
  EXPECT_EQ(solve_assignment(Eigen::MatrixXd(2, 0)), std::vector<int>({-1, -1}));
  const Eigen::MatrixXd s = Eigen::MatrixXd::Constant(3, 3, kForbidden);
  EXPECT_EQ(solve_assignment(s), std::vector<int>({-1, -1, -1}));
}

}  // namespace
}  // namespace dqo::objects
