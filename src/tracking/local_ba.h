#pragma once
// Local bundle adjustment over a keyframe and its covisible keyframes (Ceres, Schur complement),
// and the worker thread that runs it. The worker never sees the map: the tracker hands it a
// self-contained snapshot (LocalBaProblem) and later takes the result back on its own thread, so
// the map has one owner and no lock.

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>
#include <vector>

#include <array>

#include <Eigen/Core>

#include "dqo_map/geometry/box2d.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"
#include "dqo_map/tracking/tracker_params.h"

namespace dqo::tracking {

struct BaKeyframe {
  uint64_t id = 0;
  SE3 T_wc;
  bool fixed = false;  // seen by the local points but outside the window, or the gauge
};

struct BaPoint {
  uint64_t id = 0;
  Eigen::Vector3d p_w = Eigen::Vector3d::Zero();
};

struct BaObservation {
  int keyframe = 0;  // index into LocalBaProblem::keyframes
  int point = 0;     // index into LocalBaProblem::points
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();
  double depth = 0.0;  // 0: none
  double inv_sigma = 1.0;
  double depth_sigma = 0.0;  // σ of the depth residual; 0: depth_sigma(depth)
};

// Dense odometry between two keyframes of the problem (OdometryCost).
struct BaOdometry {
  int from = 0;  // indices into LocalBaProblem::keyframes
  int to = 0;
  SE3 T_from_to;
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
};

// A detection of an object landmark by a frame that follows keyframe `keyframe` (ObjectBoxCost in
// object_box_cost.h; built by ObjectLandmarkStore, object_factors.h). The object is held fixed.
struct BaObjectObservation {
  int keyframe = 0;         // index into LocalBaProblem::keyframes
  uint64_t object_id = 0;
  SE3 T_frame_kf;           // the sighting frame in the keyframe's
  Eigen::Vector3d centre_w = Eigen::Vector3d::Zero();
  Eigen::Matrix3d L_w = Eigen::Matrix3d::Identity();  // R diag(semi-axes), world
  Box2d box;
  std::array<bool, 4> use_edge{{true, true, true, true}};  // x_min, y_min, x_max, y_max
  double scale = 0.1;       // inv_sigma · sqrt(confidence)
  double huber = 2.0;       // whitened units
};

struct LocalBaProblem {
  uint64_t generation = 0;  // the tracker's map generation (a reset starts a new one)
  std::vector<BaKeyframe> keyframes;
  std::vector<BaPoint> points;
  std::vector<BaObservation> observations;
  std::vector<BaOdometry> odometry;
  std::vector<BaObjectObservation> objects;  // empty unless objects are landmarks
};

struct LocalBaResult {
  uint64_t generation = 0;
  bool ok = false;
  std::vector<std::pair<uint64_t, SE3>> keyframes;  // the free ones, T_wc after adjustment
  std::vector<std::pair<uint64_t, Eigen::Vector3d>> points;
  std::vector<std::pair<uint64_t, uint64_t>> outliers;  // (keyframe ID, point ID) to unlink
  double initial_cost = 0.0;
  double final_cost = 0.0;
  int object_costs = 0;  // object-landmark residual blocks in the last pass
  double milliseconds = 0.0;
};

// Solves the problem in place of the caller (tests, or a synchronous tracker). `abort` (may be
// null) is polled between iterations.
LocalBaResult solve_local_ba(const LocalBaProblem& problem, const PinholeCamera& camera,
                             const LocalBaParams& params, const PoseOptimiserParams& pose_params,
                             const std::atomic<bool>* abort);

// One worker thread, woken by a condition variable. A problem submitted while another waits
// replaces it (the newer window covers the same keyframes and more).
class LocalBaWorker {
 public:
  LocalBaWorker(const PinholeCamera& camera, const LocalBaParams& params,
                const PoseOptimiserParams& pose_params);
  ~LocalBaWorker();  // aborts a running adjustment and joins
  LocalBaWorker(const LocalBaWorker&) = delete;
  LocalBaWorker& operator=(const LocalBaWorker&) = delete;

  void submit(LocalBaProblem problem);
  // Finished results, oldest first (thread-safe).
  std::vector<LocalBaResult> take_results();
  // Blocks until nothing is pending or running.
  void wait_idle();
  // Drops the pending problem, aborts the running one and discards every result; returns when
  // the worker is idle. The thread keeps running.
  void cancel_all();
  bool busy() const { return busy_.load(); }

 private:
  void run();

  PinholeCamera camera_;
  LocalBaParams params_;
  PoseOptimiserParams pose_params_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable idle_;
  std::optional<LocalBaProblem> pending_;
  std::deque<LocalBaResult> results_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> abort_{false};
  std::atomic<bool> busy_{false};
  std::thread thread_;
};

}  // namespace dqo::tracking
