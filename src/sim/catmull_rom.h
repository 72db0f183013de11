#pragma once
// Centripetal Catmull-Rom interpolation, shared by the camera walks (3D) and the lathe profiles of
// procedural meshes (2D). Private to sim/.

#include <Eigen/Core>
#include <algorithm>
#include <cmath>

namespace dqo::sim::detail {

// Centripetal Catmull-Rom point between p1 and p2 at u in [0, 1] (Barry–Goldman pyramid).
template <int N>
Eigen::Matrix<double, N, 1> catmull_rom(const Eigen::Matrix<double, N, 1>& p0,
                                        const Eigen::Matrix<double, N, 1>& p1,
                                        const Eigen::Matrix<double, N, 1>& p2,
                                        const Eigen::Matrix<double, N, 1>& p3, double u) {
  using Vector = Eigen::Matrix<double, N, 1>;
  auto knot = [](const Vector& a, const Vector& b) {
    return std::max(std::sqrt((b - a).norm()), 1e-9);
  };
  const double t0 = 0.0;
  const double t1 = t0 + knot(p0, p1);
  const double t2 = t1 + knot(p1, p2);
  const double t3 = t2 + knot(p2, p3);
  const double t = t1 + u * (t2 - t1);
  const Vector a1 = (t1 - t) / (t1 - t0) * p0 + (t - t0) / (t1 - t0) * p1;
  const Vector a2 = (t2 - t) / (t2 - t1) * p1 + (t - t1) / (t2 - t1) * p2;
  const Vector a3 = (t3 - t) / (t3 - t2) * p2 + (t - t2) / (t3 - t2) * p3;
  const Vector b1 = (t2 - t) / (t2 - t0) * a1 + (t - t0) / (t2 - t0) * a2;
  const Vector b2 = (t3 - t) / (t3 - t1) * a2 + (t - t1) / (t3 - t1) * a3;
  return (t2 - t) / (t2 - t1) * b1 + (t - t1) / (t2 - t1) * b2;
}

}  // namespace dqo::sim::detail
