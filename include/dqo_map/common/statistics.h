#pragma once
// Order statistics for reports (tools and benchmarks): one definition, so that a "median" or a
// "p90" means the same in every table of BENCHMARKS.md.
#include <algorithm>
#include <cmath>
#include <vector>

namespace dqo {

// The q-quantile (q in [0, 1]) with linear interpolation between the two nearest ranks (numpy's
// default), so percentile(v, 0.5) is the median. NaN for an empty sample.
inline double percentile(std::vector<double> v, double q) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const double pos = std::clamp(q, 0.0, 1.0) * static_cast<double>(v.size() - 1);
  const size_t i = static_cast<size_t>(pos);
  const double f = pos - static_cast<double>(i);
  return i + 1 < v.size() ? v[i] * (1.0 - f) + v[i + 1] * f : v[i];
}

inline double median(std::vector<double> v) { return percentile(std::move(v), 0.5); }

}  // namespace dqo
