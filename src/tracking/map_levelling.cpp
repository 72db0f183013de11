#include "dqo_map/tracking/map_levelling.h"

#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

namespace dqo::tracking {

std::optional<MapLevel> map_level_from_string(const std::string& text) {
  if (text == "auto") return MapLevel::kAuto;
  if (text == "imu") return MapLevel::kImu;
  if (text == "floor") return MapLevel::kFloor;
  if (text == "none") return MapLevel::kNone;
  return std::nullopt;
}

Eigen::Matrix3d level_rotation(const Eigen::Vector3d& up_b) {
  const Eigen::Vector3d z = up_b.normalized();
  Eigen::Vector3d heading = Eigen::Vector3d::UnitX() - z.x() * z;
  if (heading.norm() < 0.1) heading = Eigen::Vector3d::UnitY() - z.y() * z;  // x nearly vertical
  const Eigen::Vector3d x = heading.normalized();
  const Eigen::Vector3d y = z.cross(x);
  // Rows: the map's axes in body coordinates, so R * up_b = +z and R * x_body lies in the x-z plane.
  Eigen::Matrix3d R;
  R.row(0) = x.transpose();
  R.row(1) = y.transpose();
  R.row(2) = z.transpose();
  return R;
}

void GravityEstimator::add(const Eigen::Vector3d& accel) {
  if (count_ >= wanted_ || !accel.allFinite()) return;
  sum_ += accel;
  ++count_;
}

std::optional<Eigen::Vector3d> GravityEstimator::up(double* g) const {
  if (count_ == 0) return std::nullopt;
  const Eigen::Vector3d mean = sum_ / count_;
  if (!(mean.norm() > 1e-6)) return std::nullopt;
  if (g) *g = mean.norm();
  return mean.normalized();
}

std::optional<FloorPlane> find_floor(const PinholeCamera& camera, const DepthImage& depth,
                                     const Eigen::Vector3d& expected_up_c, const FloorParams& params,
                                     std::string* error) {
  auto fail = [&](const std::string& why) -> std::optional<FloorPlane> {
    if (error) *error = why;
    return std::nullopt;
  };
  if (depth.channels != 1 || !depth.same_size(camera.width, camera.height) || depth.empty()) {
    return fail("the depth image does not match the camera");
  }
  size_t valid = 0;
  for (const float d : depth.data) valid += std::isfinite(d) && d > 0.0f;
  if (valid < 3) return fail("no depth");
  // A regular grid over the valid pixels: every `stride`-th one.
  const size_t stride = std::max<size_t>(1, valid / static_cast<size_t>(std::max(3, params.max_points)));
  std::vector<Eigen::Vector3d> points;
  size_t k = 0;
  for (int v = 0; v < depth.height; ++v) {
    for (int u = 0; u < depth.width; ++u) {
      const float d = depth.at(u, v);
      if (!(std::isfinite(d) && d > 0.0f) || k++ % stride != 0) continue;
      points.push_back(camera.back_project(u, v, d));
    }
  }
  const Eigen::Vector3d prior = expected_up_c.normalized();
  const double min_cos = std::cos(params.max_tilt_deg * M_PI / 180.0);
  std::mt19937 rng(params.seed);
  std::uniform_int_distribution<size_t> pick(0, points.size() - 1);
  int best_inliers = 0;
  Eigen::Vector3d best_n = Eigen::Vector3d::Zero();
  double best_d = 0.0;
  for (int it = 0; it < params.iterations; ++it) {
    const Eigen::Vector3d& a = points[pick(rng)];
    const Eigen::Vector3d& b = points[pick(rng)];
    const Eigen::Vector3d& c = points[pick(rng)];
    Eigen::Vector3d n = (b - a).cross(c - a);
    if (n.norm() < 1e-9) continue;
    n.normalize();
    if (n.dot(prior) < 0.0) n = -n;
    if (n.dot(prior) < min_cos) continue;
    const double d = -n.dot(a);  // plane n·p + d = 0; the camera (origin) is above when d > 0
    if (d <= 0.0) continue;
    int inliers = 0;
    for (const auto& p : points) inliers += std::abs(n.dot(p) + d) < params.inlier_m;
    if (inliers > best_inliers) best_inliers = inliers, best_n = n, best_d = d;
  }
  if (best_inliers < params.min_inlier_fraction * static_cast<double>(points.size()) || best_inliers < 3) {
    return fail("no plane within " + std::to_string(params.max_tilt_deg) + " degrees of the expected up holds " +
                std::to_string(params.min_inlier_fraction * 100.0) + " % of the depth points");
  }
  // Least-squares refit over the inliers (the normal of their smallest spread).
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> inliers;
  for (const auto& p : points) {
    if (std::abs(best_n.dot(p) + best_d) < params.inlier_m) inliers.push_back(p), mean += p;
  }
  mean /= static_cast<double>(inliers.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : inliers) cov += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  Eigen::Vector3d n = eig.eigenvectors().col(0);
  if (n.dot(best_n) < 0.0) n = -n;
  FloorPlane out;
  out.up_c = n;
  out.height = -n.dot(mean);
  out.inliers = static_cast<int>(inliers.size());
  out.points = static_cast<int>(points.size());
  if (!(out.height > 0.0)) return fail("the plane found is not below the camera");
  return out;
}

}  // namespace dqo::tracking
