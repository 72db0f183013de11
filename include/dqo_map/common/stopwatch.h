#pragma once
// Milliseconds of wall time since a start, for the per-stage timings the stages report.

#include <chrono>

namespace dqo {

inline double ms_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace dqo
