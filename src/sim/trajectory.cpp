#include "dqo_map/sim/trajectory.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "catmull_rom.h"

namespace dqo::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Portable uniform in [0, 1): std::uniform_real_distribution differs between standard libraries,
// mt19937_64's raw output does not.
double uniform01(std::mt19937_64& rng) {
  return static_cast<double>(rng() >> 11) * (1.0 / 9007199254740992.0);
}

// Point on the spline through `pts` in segment k at u; the ends use reflected phantom points so
// that the curve starts and stops along its first and last segments.
Eigen::Vector3d spline_at(const std::vector<Eigen::Vector3d>& pts, int k, double u) {
  const int n = static_cast<int>(pts.size());
  const Eigen::Vector3d& p1 = pts[k];
  const Eigen::Vector3d& p2 = pts[k + 1];
  const Eigen::Vector3d p0 = k > 0 ? pts[k - 1] : 2.0 * p1 - p2;
  const Eigen::Vector3d p3 = k + 2 < n ? pts[k + 2] : 2.0 * p2 - p1;
  if ((p2 - p1).norm() < 1e-12) return p1;
  return detail::catmull_rom(p0, p1, p2, p3, u);
}

// A smooth random signal: three slow sinusoids (0.1 to 1.2 Hz, the band of a walking hand).
struct Shake {
  double freq[3], phase[3];
  double at(double t) const {
    const double w[3] = {0.6, 0.3, 0.15};
    double s = 0.0;
    for (int i = 0; i < 3; ++i) s += w[i] * std::sin(2.0 * kPi * freq[i] * t + phase[i]);
    return s;
  }
};

}  // namespace

SE3 look_at(const Eigen::Vector3d& position, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - position).normalized();
  Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ());
  if (x.norm() < 1e-9) x = z.cross(Eigen::Vector3d::UnitX());  // looking straight up or down
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);  // image down: world -z for a level camera
  Eigen::Matrix3d R;
  R.col(0) = x;
  R.col(1) = y;
  R.col(2) = z;
  return SE3::from_rotation_translation(R, position);
}

std::vector<TrajectoryPose> make_orbit(const OrbitParams& params, int frames, double fps) {
  std::vector<TrajectoryPose> poses;
  const bool closed = std::abs(params.arc_deg) >= 360.0;
  for (int i = 0; i < frames; ++i) {
    // A closed orbit stops one step short of its start; an arc reaches both of its ends.
    const double f = closed ? static_cast<double>(i) / frames
                            : (frames > 1 ? static_cast<double>(i) / (frames - 1) : 0.0);
    const double a = (params.start_deg + f * params.arc_deg) * kPi / 180.0;
    const Eigen::Vector3d position(
        params.target.x() + params.radius * std::cos(a),
        params.target.y() + params.radius * std::sin(a),
        params.height + params.height_amplitude * std::sin(4.0 * kPi * f));
    poses.push_back({i / fps, look_at(position, params.target)});
  }
  return poses;
}

std::vector<TrajectoryPose> make_walk(const WalkParams& params, int frames, double fps) {
  std::vector<TrajectoryPose> poses;
  const int n = static_cast<int>(params.waypoints.size());
  if (n < 2 || params.look_at.size() != params.waypoints.size() || frames <= 0) return poses;
  // Arc-length table, so that the camera walks at a constant speed whatever the spacing of the
  // waypoints.
  constexpr int kSamples = 256;
  std::vector<double> length{0.0};
  std::vector<std::pair<int, double>> where{{0, 0.0}};
  Eigen::Vector3d prev = params.waypoints[0];
  for (int k = 0; k + 1 < n; ++k) {
    for (int s = 1; s <= kSamples; ++s) {
      const double u = static_cast<double>(s) / kSamples;
      const Eigen::Vector3d p = spline_at(params.waypoints, k, u);
      length.push_back(length.back() + (p - prev).norm());
      where.emplace_back(k, u);
      prev = p;
    }
  }
  std::mt19937_64 rng(params.seed ^ 0x3a1c5e7d9b2f4861ULL);
  Shake shake[6];
  for (auto& s : shake) {
    for (int i = 0; i < 3; ++i) {
      s.freq[i] = 0.1 + 1.1 * uniform01(rng);
      s.phase[i] = 2.0 * kPi * uniform01(rng);
    }
  }
  const double total = length.back();
  for (int i = 0; i < frames; ++i) {
    const double s = frames > 1 ? total * i / (frames - 1) : 0.0;
    const size_t j = std::min<size_t>(
        std::lower_bound(length.begin(), length.end(), s) - length.begin(), length.size() - 1);
    int k;
    double u;
    if (j == 0) {
      k = 0;
      u = 0.0;
    } else {
      // Between table entries j - 1 and j (same segment unless j opens a new one).
      const double span = length[j] - length[j - 1];
      const double w = span > 0.0 ? (s - length[j - 1]) / span : 0.0;
      k = where[j].first;
      const double u0 = where[j - 1].first == k ? where[j - 1].second : 0.0;
      u = u0 + w * (where[j].second - u0);
    }
    const double t = i / fps;
    Eigen::Vector3d position = spline_at(params.waypoints, k, u);
    const Eigen::Vector3d target = spline_at(params.look_at, k, u);
    position +=
        params.jitter_position * Eigen::Vector3d(shake[0].at(t), shake[1].at(t), shake[2].at(t));
    const SE3 T = look_at(position, target);
    const Eigen::Vector3d phi = params.jitter_rotation_deg * kPi / 180.0 *
                                Eigen::Vector3d(shake[3].at(t), shake[4].at(t), shake[5].at(t));
    const Eigen::Quaterniond dq(
        Eigen::AngleAxisd(phi.norm(), phi.norm() > 0.0 ? Eigen::Vector3d(phi.normalized())
                                                       : Eigen::Vector3d::UnitZ()));
    poses.push_back({t, SE3(T.quaternion() * dq, position)});
  }
  return poses;
}

}  // namespace dqo::sim
