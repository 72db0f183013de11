#include "box_fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <Eigen/Geometry>

#include "dqo_map/geometry/conic.h"
#include "dqo_map/objects/object_refinement.h"

namespace dqo::objects {
namespace {

template <typename T>
T min_t(const T& a, const T& b) {
  return a < b ? a : b;
}
template <typename T>
T max_t(const T& a, const T& b) {
  return a < b ? b : a;
}

// One view: r = 1 − GIoU(bbox of the projected corners clipped to the image, detection).
// GIoU = I/U − (C − U)/C (C the enclosing box) still has a gradient where the boxes are disjoint.
struct CornerBoxResidual {
  Eigen::Matrix<double, 3, 4> P;
  double det[4];
  double width, height;

  template <typename T>
  bool operator()(const T* centre, const T* q_wxyz, const T* log_half, T* residual) const {
    T R[9];
    ceres::QuaternionToRotation(q_wxyz, R);  // row-major, normalises q
    using std::exp;
    const T h[3] = {exp(log_half[0]), exp(log_half[1]), exp(log_half[2])};
    T box[4] = {T(1e300), T(1e300), T(-1e300), T(-1e300)};
    for (int k = 0; k < 8; ++k) {
      T p[3];
      for (int i = 0; i < 3; ++i) {
        p[i] = centre[i];
        for (int j = 0; j < 3; ++j) p[i] += R[i * 3 + j] * (((k >> j) & 1) ? h[j] : -h[j]);
      }
      T x[3];
      for (int i = 0; i < 3; ++i) x[i] = P(i, 0) * p[0] + P(i, 1) * p[1] + P(i, 2) * p[2] + P(i, 3);
      if (!(x[2] > T(1e-6))) return false;  // a corner behind the camera: reject the step
      const T u = x[0] / x[2], v = x[1] / x[2];
      box[0] = min_t(box[0], u);
      box[1] = min_t(box[1], v);
      box[2] = max_t(box[2], u);
      box[3] = max_t(box[3], v);
    }
    const T zero(0.0);
    box[0] = max_t(box[0], zero);
    box[1] = max_t(box[1], zero);
    box[2] = min_t(box[2], T(width));
    box[3] = min_t(box[3], T(height));
    const T iw = max_t(zero, min_t(box[2], T(det[2])) - max_t(box[0], T(det[0])));
    const T ih = max_t(zero, min_t(box[3], T(det[3])) - max_t(box[1], T(det[1])));
    const T inter = iw * ih;
    const T area_a = max_t(zero, box[2] - box[0]) * max_t(zero, box[3] - box[1]);
    const T area_b = T((det[2] - det[0]) * (det[3] - det[1]));
    const T uni = area_a + area_b - inter;
    const T enclosing = (max_t(box[2], T(det[2])) - min_t(box[0], T(det[0]))) *
                        (max_t(box[3], T(det[3])) - min_t(box[1], T(det[1])));
    if (!(enclosing > zero) || !(uni > zero)) return false;
    residual[0] = T(1.0) - (inter / uni - (enclosing - uni) / enclosing);
    return true;
  }

  static CornerBoxResidual from(const BoxObservation& v) {
    CornerBoxResidual r;
    r.P = v.P;
    r.det[0] = v.box.x_min;
    r.det[1] = v.box.y_min;
    r.det[2] = v.box.x_max;
    r.det[3] = v.box.y_max;
    r.width = v.width;
    r.height = v.height;
    return r;
  }
  static ceres::CostFunction* create(const BoxObservation& v) {
    return new ceres::AutoDiffCostFunction<CornerBoxResidual, 1, 3, 4, 3>(new CornerBoxResidual(from(v)));
  }
};

// The same with the rotation a yaw about the world's z axis (objects standing upright).
struct YawBoxResidual {
  CornerBoxResidual inner;
  template <typename T>
  bool operator()(const T* centre, const T* yaw, const T* log_half, T* residual) const {
    using std::cos;
    using std::sin;
    const T q[4] = {cos(T(0.5) * yaw[0]), T(0.0), T(0.0), sin(T(0.5) * yaw[0])};
    return inner(centre, q, log_half, residual);
  }
  static ceres::CostFunction* create(const BoxObservation& v) {
    return new ceres::AutoDiffCostFunction<YawBoxResidual, 1, 3, 1, 3>(
        new YawBoxResidual{CornerBoxResidual::from(v)});
  }
};

}  // namespace

UprightAxes upright_axes(const Eigen::Matrix3d& R) {
  UprightAxes u;
  u.up = 0;
  for (int j = 1; j < 3; ++j) {
    if (std::abs(R(2, j)) > std::abs(R(2, u.up))) u.up = j;
  }
  const int a = (u.up + 1) % 3, b = (u.up + 2) % 3;
  u.hx = R.col(a).head<2>().norm() >= R.col(b).head<2>().norm() ? a : b;
  u.hy = u.hx == a ? b : a;
  u.yaw = std::atan2(R(1, u.hx), R(0, u.hx));
  return u;
}

OrientedBox upright_box(const OrientedBox& box) {
  const UprightAxes u = upright_axes(box.rotation);
  OrientedBox out;
  out.centre = box.centre;
  out.rotation = Eigen::AngleAxisd(u.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  out.half_extents = Eigen::Vector3d(box.half_extents(u.hx), box.half_extents(u.hy), box.half_extents(u.up));
  return out;
}

BoxFitResult fit_box(const DualQuadric& ellipsoid, const std::vector<BoxObservation>& views,
                     const BoxFitParams& params) {
  const auto t0 = std::chrono::steady_clock::now();
  BoxFitResult result;
  std::vector<BoxObservation> used;
  for (const BoxObservation& v : views) {
    if (!v.P.allFinite() || !v.box.valid() || v.width <= 0 || v.height <= 0) continue;
    BoxObservation w = v;
    // Make the third row of P the camera depth (positive in front): its sign at the centre decides.
    const Eigen::Vector4d c(ellipsoid.centre().x(), ellipsoid.centre().y(), ellipsoid.centre().z(), 1.0);
    if ((w.P.row(2) * c)(0) < 0.0) w.P = -w.P;
    used.push_back(w);
  }
  if (params.max_views > 0 && static_cast<int>(used.size()) > params.max_views) {
    used.erase(used.begin(), used.end() - params.max_views);
  }
  if (static_cast<int>(used.size()) < std::max(1, params.min_views) || !ellipsoid.is_valid()) return result;

  double centre[3] = {ellipsoid.centre().x(), ellipsoid.centre().y(), ellipsoid.centre().z()};
  const Eigen::Quaterniond q0(ellipsoid.rotation());
  double q[4] = {q0.w(), q0.x(), q0.y(), q0.z()};
  double log_half[3];
  for (int i = 0; i < 3; ++i) log_half[i] = std::log(ellipsoid.semi_axes()(i) * params.initial_scale);
  double yaw[1] = {0.0};
  if (params.upright) {
    // The ellipsoid axis nearest the vertical becomes the box's z; the more horizontal of the
    // other two sets the yaw.
    const UprightAxes u = upright_axes(ellipsoid.rotation());
    const int up = u.up, hx = u.hx, hy = u.hy;
    yaw[0] = u.yaw;
    const Eigen::Vector3d& s = ellipsoid.semi_axes();
    log_half[0] = std::log(s(hx) * params.initial_scale);
    log_half[1] = std::log(s(hy) * params.initial_scale);
    log_half[2] = std::log(s(up) * params.initial_scale);
  }
  auto make_cost = [&](const BoxObservation& v) {
    return params.upright ? YawBoxResidual::create(v) : CornerBoxResidual::create(v);
  };
  double* rotation = params.upright ? yaw : q;

  ceres::Problem problem;
  int blocks = 0;
  for (const BoxObservation& v : used) {
    ceres::CostFunction* cost = make_cost(v);
    // Views where the starting box has a corner behind the camera are left out.
    double r = 0.0;
    const double* parameters[3] = {centre, rotation, log_half};
    if (!cost->Evaluate(parameters, &r, nullptr)) {
      delete cost;
      continue;
    }
    result.initial_cost += r;
    problem.AddResidualBlock(cost, new ceres::HuberLoss(params.huber_delta), centre, rotation, log_half);
    ++blocks;
  }
  if (blocks < std::max(1, params.min_views)) return result;
  if (!params.upright) problem.SetManifold(q, new ceres::QuaternionManifold);
  ceres::Solver::Options options;
  options.max_num_iterations = params.max_iterations;
  options.linear_solver_type = ceres::DENSE_QR;
  options.logging_type = ceres::SILENT;
  options.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  if (!summary.IsSolutionUsable()) return result;
  const Eigen::Quaterniond qr = params.upright
                                    ? Eigen::Quaterniond(Eigen::AngleAxisd(yaw[0], Eigen::Vector3d::UnitZ()))
                                    : Eigen::Quaterniond(q[0], q[1], q[2], q[3]);
  result.box.centre = Eigen::Vector3d(centre[0], centre[1], centre[2]);
  result.box.rotation = qr.normalized().toRotationMatrix();
  result.box.half_extents = Eigen::Vector3d(std::exp(log_half[0]), std::exp(log_half[1]), std::exp(log_half[2]));
  result.final_cost = 0.0;
  for (const BoxObservation& v : used) {
    std::unique_ptr<ceres::CostFunction> cost(make_cost(v));
    double r = 0.0;
    const double* parameters[3] = {centre, rotation, log_half};
    if (cost->Evaluate(parameters, &r, nullptr)) result.final_cost += r;
  }
  result.ok = result.box.centre.allFinite() && result.box.half_extents.allFinite();
  for (const BoxObservation& v : used) {
    const Eigen::Vector3d p = v.P.leftCols<3>() * ellipsoid.centre() + v.P.col(3);
    const Eigen::Matrix3d C = project_quadric(ellipsoid, v.P);
    const auto conic = p.z() > 0.0 ? conic_bounding_box(C) : std::nullopt;
    result.ellipsoid_cost += conic ? 1.0 - generalised_iou(conic->clip(v.width, v.height), v.box) : 2.0;
  }
  result.better_than_ellipsoid = result.ok && result.final_cost < result.ellipsoid_cost;
  result.time_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

}  // namespace dqo::objects
