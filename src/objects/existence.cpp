#include "existence.h"

#include <algorithm>
#include <cmath>

namespace dqo::objects {

double logit(double p) {
  const double q = std::clamp(p, 1e-9, 1.0 - 1e-9);
  return std::log(q / (1.0 - q));
}

DepthEvidenceCounts depth_evidence(const DualQuadric& quadric, const Box2d& projected,
                                   const PinholeCamera& camera, const SE3& T_wc,
                                   const DepthView& depth, double tolerance) {
  DepthEvidenceCounts n;
  if (depth.data == nullptr || !quadric.is_valid()) return n;
  // The ellipsoid in the camera frame as x^T A x + 2 b^T x + c = 0 along x = s d (d = (u', v', 1),
  // so s is the camera depth z): A = R S^-2 R^T, origin o = centre in the camera frame.
  const SE3 T_cw = T_wc.inverse();
  const Eigen::Matrix3d R_c = T_cw.rotation() * quadric.rotation();
  const Eigen::Vector3d o = T_cw * quadric.centre();
  const Eigen::Vector3d inv_a2 = quadric.semi_axes().array().square().inverse();
  const Eigen::Matrix3d A = R_c * inv_a2.asDiagonal() * R_c.transpose();
  const Eigen::Vector2d c = projected.centre();
  const double hw = 0.25 * projected.width(), hh = 0.25 * projected.height();
  for (int k = 0; k < 25; ++k) {
    const double u = c.x() + hw * ((k % 5) - 2) / 2.0;
    const double v = c.y() + hh * ((k / 5) - 2) / 2.0;
    const int iu = static_cast<int>(std::lround(u)), iv = static_cast<int>(std::lround(v));
    if (iu < 0 || iv < 0 || iu >= depth.width || iv >= depth.height) continue;
    const Eigen::Vector3d d((iu - camera.cx) / camera.fx, (iv - camera.cy) / camera.fy, 1.0);
    // (s d − o)^T A (s d − o) = 1: a s² − 2 b s + (o^T A o − 1) = 0.
    const double a = d.dot(A * d), b = d.dot(A * o), cc = o.dot(A * o) - 1.0;
    const double disc = b * b - a * cc;
    if (!(a > 0.0) || disc < 0.0) continue;
    const double entry = (b - std::sqrt(disc)) / a, exit = (b + std::sqrt(disc)) / a;
    if (!(exit > 0.0)) continue;
    ++n.rays;
    const float z = depth.at(iu, iv);
    if (!(z > 0.0f) || !std::isfinite(z)) continue;
    ++n.valid;
    const double tol = tolerance + 0.01 * z;
    if (z < entry - tol) {
      ++n.nearer;
    } else if (z <= exit + tol) {
      ++n.surface;
    } else {
      ++n.beyond;
    }
  }
  return n;
}

MissKind classify_miss(const DepthEvidenceCounts& n, const ExistenceParams& params) {
  if (n.valid == 0) return MissKind::kSupported;
  if (2 * n.nearer > n.valid) return MissKind::kOccluded;
  // Thin or open objects (a chair's back, a lamp) let most rays through: a share of the rays on a
  // surface is enough to say something is there.
  if (n.surface >= params.min_surface_fraction * (n.valid - n.nearer)) return MissKind::kSupported;
  return MissKind::kFreeSpace;
}

double after_detection(double log_odds, const std::string& class_name, double score, const ExistenceParams& params) {
  const double s = std::isfinite(score) ? std::clamp(score, 0.0, 1.0) : 0.0;
  const double ratio = std::exp(params.log_odds_detected(class_name));
  return std::clamp(log_odds + std::log(1.0 + s * (ratio - 1.0)), -params.max_log_odds, params.max_log_odds);
}

double after_miss(double log_odds, MissKind kind, const std::string& class_name, const ExistenceParams& params) {
  double step = 0.0;
  switch (kind) {
    case MissKind::kOccluded: return log_odds;
    case MissKind::kSupported: step = params.supported_miss_weight * params.log_odds_missed(class_name); break;
    case MissKind::kFreeSpace: step = params.log_odds_missed(class_name) + params.free_space; break;
    case MissKind::kExplained: step = params.log_odds_missed(class_name); break;
  }
  return std::clamp(log_odds + step, -params.max_log_odds, params.max_log_odds);
}

}  // namespace dqo::objects
