#include "dqo_map/objects/object_refinement.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>
#include <memory>
#include <string>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <ceres/autodiff_cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/rotation.h>
#include <ceres/manifold.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include "box_fit.h"
#include "conic_box_cost.h"

namespace dqo::objects {
namespace {

using internal::ConicBoxGiouCost;

// A view checked once and reduced to what the cost functor needs.
struct PreparedView {
  Eigen::Matrix<double, 3, 4> P;
  // P's third row is the camera depth times a scale λ; for P = λ K [R|t] with positive focal
  // lengths det(P₃ₓ₃) = λ³ fx fy det(R) has the sign of λ, so this recovers "in front" for any λ.
  double depth_sign = 1.0;
  double detection[4];  // clipped to inner
  double inner[4];      // the image less the border margin
};

std::optional<PreparedView> prepare_view(const BoxObservation& view, double margin) {
  if (!view.P.allFinite() || !view.box.valid() || view.width <= 0 || view.height <= 0) {
    return std::nullopt;
  }
  if (!std::isfinite(margin) || margin < 0.0) return std::nullopt;
  PreparedView out;
  out.P = view.P;
  const double det = view.P.leftCols<3>().determinant();
  if (!std::isfinite(det) || det == 0.0) return std::nullopt;
  out.depth_sign = det > 0.0 ? 1.0 : -1.0;
  out.inner[0] = margin;
  out.inner[1] = margin;
  out.inner[2] = static_cast<double>(view.width) - margin;
  out.inner[3] = static_cast<double>(view.height) - margin;
  if (!(out.inner[2] > out.inner[0]) || !(out.inner[3] > out.inner[1])) return std::nullopt;
  out.detection[0] = std::clamp(view.box.x_min, out.inner[0], out.inner[2]);
  out.detection[1] = std::clamp(view.box.y_min, out.inner[1], out.inner[3]);
  out.detection[2] = std::clamp(view.box.x_max, out.inner[0], out.inner[2]);
  out.detection[3] = std::clamp(view.box.y_max, out.inner[1], out.inner[3]);
  if (!(out.detection[2] > out.detection[0]) || !(out.detection[3] > out.detection[1])) {
    return std::nullopt;  // the detection lies wholly in the border band
  }
  return out;
}

// in_front_of_camera (conic.h) from P alone: the camera plane is P's third row n·X + d (scaled
// depth), the ellipsoid's smallest depth is depth(centre) − sqrt(nᵀ S n) / |n|.
bool wholly_in_front(const PreparedView& view, const DualQuadric& quadric) {
  const Eigen::Vector3d n = view.P.block<1, 3>(2, 0).transpose();
  const double norm = n.norm();
  if (!(norm > 0.0)) return false;
  const double depth = view.depth_sign * (n.dot(quadric.centre()) + view.P(2, 3)) / norm;
  const double half_extent = std::sqrt(std::max(0.0, n.dot(quadric.shape_matrix() * n))) / norm;
  return depth - half_extent > 0.0;
}

// Parameter blocks in the solver's layout.
struct BlockState {
  double centre[3];
  double q_wxyz[4];
  double log_axes[3];
};

BlockState to_blocks(const DualQuadric& q) {
  BlockState s;
  const Eigen::Quaterniond quat = Eigen::Quaterniond(q.rotation()).normalized();
  for (int i = 0; i < 3; ++i) {
    s.centre[i] = q.centre()[i];
    s.log_axes[i] = std::log(q.semi_axes()[i]);
  }
  s.q_wxyz[0] = quat.w();
  s.q_wxyz[1] = quat.x();
  s.q_wxyz[2] = quat.y();
  s.q_wxyz[3] = quat.z();
  return s;
}

std::optional<DualQuadric> from_blocks(const BlockState& s) {
  const Eigen::Quaterniond quat(s.q_wxyz[0], s.q_wxyz[1], s.q_wxyz[2], s.q_wxyz[3]);
  if (!quat.coeffs().allFinite() || !(quat.norm() > 0.0)) return std::nullopt;
  const Eigen::Vector3d centre(s.centre[0], s.centre[1], s.centre[2]);
  const Eigen::Vector3d axes(std::exp(s.log_axes[0]), std::exp(s.log_axes[1]),
                             std::exp(s.log_axes[2]));
  const DualQuadric q = DualQuadric::from_params(centre, quat.normalized().toRotationMatrix(), axes);
  if (!q.is_valid()) return std::nullopt;
  return q;
}

// Σ r over the views at a state, in double through the same functor the solver uses.
// A view whose box does not exist counts as the worst residual, 2.
double total_residual(const std::vector<PreparedView>& views, const BlockState& s) {
  double sum = 0.0;
  for (const PreparedView& v : views) {
    const ConicBoxGiouCost cost(v.P, v.depth_sign, v.detection, v.inner);
    double r = 2.0;
    if (!cost(s.centre, s.q_wxyz, s.log_axes, &r) || !std::isfinite(r)) r = 2.0;
    sum += r;
  }
  return sum;
}

// Upright prior: the rotation's column `axis` (an ellipsoid axis in the world) has no horizontal
// part. R = rotation of q (row-major from Ceres), column j = (R[j], R[3 + j], R[6 + j]).
struct UprightPrior {
  int axis;
  double weight;
  template <typename T>
  bool operator()(const T* q_wxyz, T* residual) const {
    T R[9];
    ceres::QuaternionToRotation(q_wxyz, R);
    residual[0] = T(weight) * R[axis];
    residual[1] = T(weight) * R[3 + axis];
    return true;
  }
  static ceres::CostFunction* Create(int axis, double weight) {
    return new ceres::AutoDiffCostFunction<UprightPrior, 2, 4>(new UprightPrior{axis, weight});
  }
};

// Support prior: the ellipsoid's lowest point, centre_z − sqrt(Σ_j a_j² R(2, j)²), on support_z.
struct SupportPrior {
  double support_z, weight, scale;
  template <typename T>
  bool operator()(const T* centre, const T* q_wxyz, const T* log_axes, T* residual) const {
    T R[9];
    ceres::QuaternionToRotation(q_wxyz, R);
    using std::exp;
    using std::sqrt;
    T half = T(0.0);
    for (int j = 0; j < 3; ++j) half += exp(T(2.0) * log_axes[j]) * R[6 + j] * R[6 + j];
    residual[0] = T(weight / scale) * (centre[2] - sqrt(half) - T(support_z));
    return true;
  }
  static ceres::CostFunction* Create(double support_z, double weight, double scale) {
    return new ceres::AutoDiffCostFunction<SupportPrior, 1, 3, 4, 3>(new SupportPrior{support_z, weight, scale});
  }
};

void refine_impl(const DualQuadric& initial, const std::vector<BoxObservation>& views,
                 const RefinementParams& params, const RefinementPriors& priors, RefinementResult& result) {
  if (!initial.is_valid()) {
    result.error = "initial quadric is not a valid ellipsoid";
    return;
  }
  if (!(params.min_semi_axis > 0.0) || !(params.max_semi_axis > params.min_semi_axis) ||
      !std::isfinite(params.max_semi_axis) || params.max_views < 1 || params.max_iterations < 0 ||
      !(params.huber_delta > 0.0)) {
    result.error = "invalid refinement parameters";
    return;
  }

  // Newest first, so that max_views keeps the most recent usable views.
  std::vector<PreparedView> used;
  for (auto it = views.rbegin(); it != views.rend() && static_cast<int>(used.size()) < params.max_views;
       ++it) {
    std::optional<PreparedView> v = prepare_view(*it, params.border_margin_px);
    if (v && wholly_in_front(*v, initial)) {
      // The box must exist at the start too: the solver cannot begin from a failed evaluation.
      const ConicBoxGiouCost cost(v->P, v->depth_sign, v->detection, v->inner);
      const BlockState s = to_blocks(initial);
      double r = 0.0;
      if (cost(s.centre, s.q_wxyz, s.log_axes, &r) && std::isfinite(r)) {
        used.push_back(*v);
        continue;
      }
    }
    ++result.views_skipped;
  }
  result.views_used = static_cast<int>(used.size());
  if (result.views_used < params.min_views || result.views_used == 0) {
    result.error = "too few usable views: " + std::to_string(result.views_used) + " of " +
                   std::to_string(views.size()) + ", need " + std::to_string(params.min_views);
    return;
  }

  BlockState state = to_blocks(initial);
  const double log_min = std::log(params.min_semi_axis);
  const double log_max = std::log(params.max_semi_axis);
  for (double& l : state.log_axes) l = std::clamp(l, log_min, log_max);
  result.initial_cost = total_residual(used, state);

  ceres::Problem problem;
  for (const PreparedView& v : used) {
    problem.AddResidualBlock(ConicBoxGiouCost::Create(v.P, v.depth_sign, v.detection, v.inner),
                             new ceres::HuberLoss(params.huber_delta), state.centre, state.q_wxyz,
                             state.log_axes);
  }
  if (priors.upright && priors.upright_weight > 0.0) {
    problem.AddResidualBlock(UprightPrior::Create(upright_axes(initial.rotation()).up, priors.upright_weight),
                             nullptr, state.q_wxyz);
  }
  if (priors.on_support && priors.support_weight > 0.0 && priors.support_scale > 0.0) {
    problem.AddResidualBlock(SupportPrior::Create(priors.support_z, priors.support_weight, priors.support_scale),
                             new ceres::HuberLoss(1.0), state.centre, state.q_wxyz, state.log_axes);
  }
  // The quaternion moves on the sphere (SO(3)); the functor normalises it anyway, so the manifold
  // only removes the scale direction, which would otherwise leave the normal equations singular.
  problem.SetManifold(state.q_wxyz, new ceres::QuaternionManifold());
  for (int i = 0; i < 3; ++i) {
    problem.SetParameterLowerBound(state.log_axes, i, log_min);
    problem.SetParameterUpperBound(state.log_axes, i, log_max);
  }

  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = params.max_iterations;
  options.num_threads = 1;
  options.logging_type = ceres::SILENT;
  options.minimizer_progress_to_stdout = false;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  result.iterations = std::max(0, static_cast<int>(summary.iterations.size()) - 1);
  if (!summary.IsSolutionUsable()) {
    result.error = "solver failed: " + summary.message;
    return;
  }
  const std::optional<DualQuadric> refined = from_blocks(state);
  if (!refined) {
    result.error = "solver returned an invalid ellipsoid";
    return;
  }
  result.final_cost = total_residual(used, state);
  if (!std::isfinite(result.final_cost)) {
    result.error = "non-finite cost after refinement";
    return;
  }
  result.quadric = *refined;
  result.ok = true;
}

}  // namespace

double generalised_iou(const Box2d& a, const Box2d& b) {
  const double pa[4] = {a.x_min, a.y_min, a.x_max, a.y_max};
  const double pb[4] = {b.x_min, b.y_min, b.x_max, b.y_max};
  for (int k = 0; k < 4; ++k) {
    if (!std::isfinite(pa[k]) || !std::isfinite(pb[k])) return std::nan("");
  }
  return internal::generalised_iou_t(pa, pb);
}

RefinementResult refine_quadric(const DualQuadric& initial, const std::vector<BoxObservation>& views,
                                const RefinementParams& params, const RefinementPriors& priors) {
  const auto start = std::chrono::steady_clock::now();
  RefinementResult result;
  result.quadric = initial;
  try {
    refine_impl(initial, views, params, priors, result);
  } catch (const std::exception& e) {
    result.ok = false;
    result.error = std::string("refinement failed: ") + e.what();
  } catch (...) {
    result.ok = false;
    result.error = "refinement failed: unknown exception";
  }
  if (!result.ok) result.quadric = initial;
  result.time_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return result;
}

std::optional<ViewResidual> evaluate_view_residual(const BoxObservation& view,
                                                   const Eigen::Vector3d& centre,
                                                   const Eigen::Vector4d& q_wxyz,
                                                   const Eigen::Vector3d& log_axes,
                                                   double border_margin_px) {
  if (!centre.allFinite() || !q_wxyz.allFinite() || !log_axes.allFinite() ||
      !(q_wxyz.norm() > 0.0)) {
    return std::nullopt;
  }
  const std::optional<PreparedView> v = prepare_view(view, border_margin_px);
  if (!v) return std::nullopt;
  const std::unique_ptr<ceres::CostFunction> cost(
      ConicBoxGiouCost::Create(v->P, v->depth_sign, v->detection, v->inner));
  const double* parameters[3] = {centre.data(), q_wxyz.data(), log_axes.data()};
  double residual = 0.0;
  double j_centre[3], j_q[4], j_axes[3];
  double* jacobians[3] = {j_centre, j_q, j_axes};
  if (!cost->Evaluate(parameters, &residual, jacobians) || !std::isfinite(residual)) {
    return std::nullopt;
  }
  ViewResidual out;
  out.value = residual;
  for (int i = 0; i < 3; ++i) out.jacobian(i) = j_centre[i];
  for (int i = 0; i < 4; ++i) out.jacobian(3 + i) = j_q[i];
  for (int i = 0; i < 3; ++i) out.jacobian(7 + i) = j_axes[i];
  if (!out.jacobian.allFinite()) return std::nullopt;
  return out;
}

}  // namespace dqo::objects
