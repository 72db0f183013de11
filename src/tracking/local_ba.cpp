#include "local_ba.h"

#include <chrono>
#include <cmath>
#include <memory>

#include <ceres/iteration_callback.h>
#include <ceres/loss_function.h>
#include <ceres/manifold.h>
#include <ceres/ordered_groups.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include "object_factors.h"
#include "pose_optimiser.h"
#include "residuals.h"

namespace dqo::tracking {
namespace {

// Stops the solver between iterations when the tracker asks (a reset, the destructor).
class AbortCallback : public ceres::IterationCallback {
 public:
  explicit AbortCallback(const std::atomic<bool>* abort) : abort_(abort) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
    return abort_ != nullptr && abort_->load() ? ceres::SOLVER_ABORT : ceres::SOLVER_CONTINUE;
  }

 private:
  const std::atomic<bool>* abort_;
};

struct KeyframeBlock {
  Eigen::Quaterniond q_cw;
  Eigen::Vector3d t_cw;
};

// Whitened squared error of an observation at the current estimates.
double chi2_of(const BaObservation& o, const KeyframeBlock& kf, const Eigen::Vector3d& p_w,
               const PinholeCamera& camera, const PoseOptimiserParams& pose_params) {
  const Eigen::Vector3d p_c = kf.q_cw * p_w + kf.t_cw;
  if (p_c.z() <= 1e-6) return std::numeric_limits<double>::infinity();
  const Eigen::Vector2d e(camera.fx * p_c.x() / p_c.z() + camera.cx - o.uv.x(),
                          camera.fy * p_c.y() / p_c.z() + camera.cy - o.uv.y());
  double chi2 = (e * o.inv_sigma).squaredNorm();
  if (o.depth > 0.0) {
    const double sigma = o.depth_sigma > 0.0 ? o.depth_sigma : depth_sigma(o.depth, pose_params);
    const double ez = (p_c.z() - o.depth) / sigma;
    chi2 += ez * ez;
  }
  return chi2;
}

}  // namespace

LocalBaResult solve_local_ba(const LocalBaProblem& input, const PinholeCamera& camera,
                             const LocalBaParams& params, const PoseOptimiserParams& pose_params,
                             const std::atomic<bool>* abort) {
  const auto start = std::chrono::steady_clock::now();
  LocalBaResult result;
  result.generation = input.generation;
  if (input.keyframes.empty() || input.points.empty()) return result;

  std::vector<KeyframeBlock> kfs(input.keyframes.size());
  for (size_t i = 0; i < kfs.size(); ++i) {
    const SE3 T_cw = input.keyframes[i].T_wc.inverse();
    kfs[i].q_cw = T_cw.quaternion();
    kfs[i].t_cw = T_cw.translation();
  }
  std::vector<Eigen::Vector3d> points(input.points.size());
  for (size_t i = 0; i < points.size(); ++i) points[i] = input.points[i].p_w;

  const Intrinsics K(camera);
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::EigenQuaternionManifold quaternion_manifold;
  ceres::HuberLoss reprojection_loss(pose_params.huber_reprojection_px);
  std::vector<std::unique_ptr<ceres::LossFunction>> depth_losses;
  std::vector<std::unique_ptr<ceres::LossFunction>> object_losses;

  std::vector<char> outlier(input.observations.size(), 0);
  AbortCallback abort_callback(abort);
  double first_cost = -1.0;

  // Two passes (ORB-SLAM2): robust, then without the kernel on the inliers of the first.
  for (int pass = 0; pass < 2; ++pass) {
    const bool robust = pass == 0;
    ceres::Problem problem(problem_options);
    auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
    std::vector<char> point_used(points.size(), 0);
    std::vector<char> keyframe_used(kfs.size(), 0);
    int residuals = 0;
    for (size_t i = 0; i < input.observations.size(); ++i) {
      if (outlier[i]) continue;
      const BaObservation& o = input.observations[i];
      double* q = kfs[o.keyframe].q_cw.coeffs().data();
      double* t = kfs[o.keyframe].t_cw.data();
      double* p = points[o.point].data();
      if (!keyframe_used[o.keyframe]) {
        keyframe_used[o.keyframe] = 1;
        problem.AddParameterBlock(q, 4, &quaternion_manifold);
        problem.AddParameterBlock(t, 3);
        // Points are eliminated first (group 0): the Schur complement leaves the poses.
        ordering->AddElementToGroup(q, 1);
        ordering->AddElementToGroup(t, 1);
        if (input.keyframes[o.keyframe].fixed) {
          problem.SetParameterBlockConstant(q);
          problem.SetParameterBlockConstant(t);
        }
      }
      problem.AddResidualBlock(BaReprojectionCost::Create(K, o.uv, o.inv_sigma),
                               robust ? &reprojection_loss : nullptr, q, t, p);
      if (o.depth > 0.0) {
        const double sigma =
            o.depth_sigma > 0.0 ? o.depth_sigma : depth_sigma(o.depth, pose_params);
        ceres::LossFunction* loss = nullptr;
        if (robust) {
          depth_losses.push_back(std::make_unique<ceres::HuberLoss>(pose_params.huber_depth_m /
                                                                    sigma));
          loss = depth_losses.back().get();
        }
        problem.AddResidualBlock(BaDepthCost::Create(o.depth, 1.0 / sigma), loss, q, t, p);
      }
      if (!point_used[o.point]) {
        point_used[o.point] = 1;
        ordering->AddElementToGroup(p, 0);
      }
      ++residuals;
    }
    // Dense odometry ties consecutive keyframes as tightly as it tied the frames between them,
    // so the adjustment cannot trade the dense precision for the features' (weaker) geometry.
    for (const BaOdometry& o : input.odometry) {
      for (const int k : {o.from, o.to}) {
        if (keyframe_used[k]) continue;
        keyframe_used[k] = 1;
        double* q = kfs[k].q_cw.coeffs().data();
        double* t = kfs[k].t_cw.data();
        problem.AddParameterBlock(q, 4, &quaternion_manifold);
        problem.AddParameterBlock(t, 3);
        ordering->AddElementToGroup(q, 1);
        ordering->AddElementToGroup(t, 1);
        if (input.keyframes[k].fixed) {
          problem.SetParameterBlockConstant(q);
          problem.SetParameterBlockConstant(t);
        }
      }
      problem.AddResidualBlock(OdometryCost::Create(o.T_from_to, sqrt_information(o.information)),
                               nullptr, kfs[o.from].q_cw.coeffs().data(), kfs[o.from].t_cw.data(),
                               kfs[o.to].q_cw.coeffs().data(), kfs[o.to].t_cw.data());
    }
    // Objects as landmarks (object_factors.h), robust in both passes: the box model is coarse.
    // Only on free keyframes the features or the odometry put in the problem.
    if (!input.objects.empty()) {
      std::vector<std::pair<double*, double*>> blocks(kfs.size(), {nullptr, nullptr});
      for (size_t k = 0; k < kfs.size(); ++k) {
        if (keyframe_used[k] && !input.keyframes[k].fixed)
          blocks[k] = {kfs[k].q_cw.coeffs().data(), kfs[k].t_cw.data()};
      }
      result.object_costs = add_object_costs(input.objects, camera, blocks, &problem, &object_losses);
    }
    if (residuals == 0) return result;
    // Gauge: the fixed keyframes (at least one, the tracker makes sure) hold the map in place;
    // without one the whole window could drift freely.

    ceres::Solver::Options options;
    options.linear_solver_type =
        kfs.size() <= 40 ? ceres::DENSE_SCHUR : ceres::SPARSE_SCHUR;
    options.linear_solver_ordering = ordering;
    options.max_num_iterations = std::max(1, params.iterations / (robust ? 2 : 1));
    options.num_threads = 1;
    options.logging_type = ceres::SILENT;
    options.minimizer_progress_to_stdout = false;
    options.callbacks.push_back(&abort_callback);
    ceres::Solver::Summary summary;
    ceres::Solve(options, &problem, &summary);
    if (first_cost < 0.0) first_cost = summary.initial_cost;
    result.final_cost = summary.final_cost;
    if (summary.termination_type == ceres::USER_FAILURE || summary.termination_type == ceres::FAILURE ||
        !std::isfinite(summary.final_cost))
      return result;

    for (size_t i = 0; i < input.observations.size(); ++i) {
      const BaObservation& o = input.observations[i];
      const double limit = o.depth > 0.0 ? kChi2Rgbd : kChi2Mono;
      outlier[i] = chi2_of(o, kfs[o.keyframe], points[o.point], camera, pose_params) > limit;
    }
  }

  result.ok = true;
  result.initial_cost = first_cost;
  for (size_t i = 0; i < kfs.size(); ++i) {
    if (input.keyframes[i].fixed) continue;
    result.keyframes.emplace_back(input.keyframes[i].id, SE3(kfs[i].q_cw, kfs[i].t_cw).inverse());
  }
  for (size_t i = 0; i < points.size(); ++i) result.points.emplace_back(input.points[i].id, points[i]);
  for (size_t i = 0; i < input.observations.size(); ++i) {
    if (!outlier[i]) continue;
    const BaObservation& o = input.observations[i];
    result.outliers.emplace_back(input.keyframes[o.keyframe].id, input.points[o.point].id);
  }
  result.milliseconds =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return result;
}

// ---------------------------------------------------------------- worker

LocalBaWorker::LocalBaWorker(const PinholeCamera& camera, const LocalBaParams& params,
                             const PoseOptimiserParams& pose_params)
    : camera_(camera), params_(params), pose_params_(pose_params) {
  thread_ = std::thread([this] { run(); });
}

LocalBaWorker::~LocalBaWorker() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
    abort_ = true;
    pending_.reset();
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void LocalBaWorker::submit(LocalBaProblem problem) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    pending_ = std::move(problem);
  }
  wake_.notify_one();
}

std::vector<LocalBaResult> LocalBaWorker::take_results() {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<LocalBaResult> out(std::make_move_iterator(results_.begin()),
                                 std::make_move_iterator(results_.end()));
  results_.clear();
  return out;
}

void LocalBaWorker::wait_idle() {
  std::unique_lock<std::mutex> lock(mutex_);
  idle_.wait(lock, [this] { return !pending_ && !busy_.load(); });
}

void LocalBaWorker::cancel_all() {
  std::unique_lock<std::mutex> lock(mutex_);
  pending_.reset();
  abort_ = true;
  idle_.wait(lock, [this] { return !busy_.load(); });
  results_.clear();
  abort_ = false;
}

void LocalBaWorker::run() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (true) {
    wake_.wait(lock, [this] { return stop_.load() || pending_.has_value(); });
    if (stop_) break;
    LocalBaProblem problem = std::move(*pending_);
    pending_.reset();
    busy_ = true;
    abort_ = false;
    lock.unlock();
    LocalBaResult result = solve_local_ba(problem, camera_, params_, pose_params_, &abort_);
    lock.lock();
    if (!abort_ && result.ok) results_.push_back(std::move(result));
    busy_ = false;
    idle_.notify_all();
  }
  busy_ = false;
  idle_.notify_all();
}

}  // namespace dqo::tracking
