#pragma once
// The Tracker's private state and its stages. Split over tracker.cpp (the per-frame pipeline:
// dense alignment, feature tracking, relocalisation) and tracker_map.cpp (the tracker's own map:
// keyframe policy, map points, local BA hand-over, registered frames).

#include <atomic>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "dqo_map/tracking/dense_alignment.h"
#include "dqo_map/tracking/tracker.h"
#include "local_ba.h"
#include "map_store.h"
#include "matching.h"
#include "object_factors.h"
#include "orb_frame.h"
#include "pose_optimiser.h"
#include "tracking_quality.h"

namespace dqo::tracking {

// One frame as tracking sees it.
struct TrackedFrame {
  uint64_t number = 0;  // the tracker's frame counter
  double timestamp = 0.0;
  OrbFrame features;
  std::vector<uint64_t> map_points;  // per keypoint: its matched map point (inliers), or kNoId
  SE3 T_wc;
  uint64_t reference_keyframe = kNoId;
  SE3 T_ref_frame;  // the pose relative to the reference keyframe, kept across BA corrections
};

// How the features of one frame came out.
struct FeatureOutcome {
  bool ran = false;     // the optimiser had something to work on
  bool ok = false;      // enough inliers: the features hold by themselves
  SE3 T_wc;
  int inliers = 0;
  bool used_prior = false;  // T_wc is the fused solution (features plus the dense prior)
  // The features alone contradicted the dense alignment and were too few to be believed over it
  // (ok is false): their own pose and inliers, for the quality check.
  bool contradicted_dense = false;
  SE3 T_wc_alone;
  int inliers_alone = 0;
};

// A pose optimisation over a frame's matches, with the keypoint of each observation (-1 for
// the temporary points of the last frame, which never enter the map).
struct Refinement {
  PoseOptimisationResult pose;
  std::vector<int> keypoints;  // parallel to the observations
  int map_inliers = 0;         // inliers that are map points
};

struct RegisteredFrame {
  uint64_t reference_keyframe = kNoId;
  SE3 T_ref_frame;
  // For the final refinement (RefineParams, tracker_loop.cpp).
  uint64_t number = 0;
  double timestamp = 0.0;
  bool degraded = false;
  // Its depth was captured apart from its colour: the features alone gave its pose (no dense
  // support), which the final refinement re-estimates; other frames follow their keyframe.
  bool features_only = false;
  std::vector<std::pair<uint64_t, PoseObservation>> observations;  // (map point, its keypoint)
};

struct Tracker::Impl {
  Impl(const PinholeCamera& camera, const TrackerParams& params);
  ~Impl();

  // ---- tracker.cpp: the pipeline
  TrackResult track(const RgbdInput& input);
  TrackResult initialise(TrackedFrame* frame, const RgbdPyramid* pyramid);
  TrackResult track_frame(TrackedFrame* frame, const RgbdPyramid* pyramid);
  TrackResult track_lost(TrackedFrame* frame, const RgbdPyramid* pyramid);
  bool relocalise_frame(TrackedFrame* frame, SE3* T_wc, int* inliers);
  std::optional<DensePrior> align_to_last(const RgbdPyramid* pyramid, DenseResult* dense);
  std::optional<DensePrior> realign(const RgbdPyramid* pyramid, const SE3& T_wc_guess,
                                    DenseResult* dense, bool* to_last) const;
  std::optional<SE3> confirm_features(const RgbdPyramid* pyramid, const SE3& T_wc_features,
                                      bool to_anchor, DenseResult* result) const;
  bool fuse_realigned(TrackedFrame* frame, const RgbdPyramid* pyramid, SE3* T_wc, int* inliers,
                      DenseResult* dense, std::optional<DensePrior>* prior, bool* to_last);
  FeatureOutcome track_features(TrackedFrame* frame, const DensePrior* prior, const SE3& T_wc_mm);
  bool track_motion_model(TrackedFrame* frame, const SE3& T_wc_mm, SE3* T_wc);
  int match_last_frame(TrackedFrame* frame, const SE3& T_wc_guess, double radius,
                       std::vector<PoseObservation>* temporary);
  int match_with_pnp(TrackedFrame* frame, SE3* T_wc);
  int search_local_map(TrackedFrame* frame, const SE3& T_wc, double radius);
  void update_local_map(const TrackedFrame& frame);
  Refinement refine(const TrackedFrame& frame, const SE3& T_wc_guess, const DensePrior* prior,
                    const std::vector<PoseObservation>& extra) const;
  void keep_inliers(TrackedFrame* frame, const Refinement& refinement) const;
  std::vector<uint64_t> relocalisation_candidates();
  void finish_frame(TrackedFrame* frame, const SE3& T_wc, bool update_velocity);
  void mark_asynchronous_depth(TrackedFrame* frame) const;
  void accumulate_odometry(const DensePrior* prior, const SE3& T_wc);
  void accept(TrackedFrame* frame, const SE3& T_wc, int inliers, bool features_ok,
              bool update_velocity, TrackResult* result, bool keyframe_allowed = true);
  QualityEvidence evidence_base() const;
  double spread_of(const TrackedFrame& frame) const;
  int depth_inliers_of(const TrackedFrame& frame) const;

  // ---- tracker_map.cpp: the map
  bool need_keyframe(const TrackedFrame& frame, int inliers, bool features_ok) const;
  void create_keyframe(TrackedFrame* frame);
  void create_points(uint64_t keyframe_id, TrackedFrame* frame);
  void cull_recent_points();
  void count_found(const TrackedFrame& frame);
  LocalBaProblem local_ba_problem(uint64_t keyframe_id) const;
  void run_local_ba(uint64_t keyframe_id);
  void submit_local_ba();
  void apply_ba_results();
  void apply_ba_result(const LocalBaResult& result);
  // The last frame and the registered frames follow their reference keyframes' new poses.
  void follow_keyframes(const std::unordered_map<uint64_t, SE3>& moved);
  void register_frame(uint64_t id);
  std::vector<CorrectedPose> corrected_frames();
  void reset();
  void wait_for_mapping();

  PinholeCamera camera_;
  TrackerParams params_;
  OrbExtractor extractor_;
  MapStore map_;
  std::unique_ptr<LocalBaWorker> ba_;
  uint64_t generation_ = 1;  // bumped by reset(): results of an older map are dropped

  // The tracker's mode: kNotInitialised, kOk (tracking frame to frame) or kLost (relocalising).
  std::atomic<TrackingState> state_{TrackingState::kNotInitialised};
  // What the last frame was reported as (kDegraded too, and kLost for a single lost frame).
  std::atomic<TrackingState> reported_state_{TrackingState::kNotInitialised};
  int failures_ = 0;  // consecutive frames where neither features nor dense held
  // This frame's depth and colour were not captured together (PoseOptimiserParams::max_depth_gap_s).
  bool depth_asynchronous_ = false;
  uint64_t frame_counter_ = 0;
  std::optional<TrackedFrame> last_;
  RgbdPyramid current_pyramid_;
  RgbdPyramid last_pyramid_;  // the last frame's
  bool has_last_pyramid_ = false;
  // Whether the last frame can serve as a dense reference: tracked ok, with depth.
  bool last_dense_ready_ = false;
  // The last such frame before one that could not (TrackerParams::realign_dense): kept apart from
  // the two above, by swapping, until the next such break.
  RgbdPyramid anchor_pyramid_;
  SE3 anchor_T_wc_;
  bool has_anchor_ = false;
  uint64_t anchor_frame_ = 0;  // its frame number
  // The dense odometry from the last keyframe to the anchor (see odometry_covariance_ below), so
  // that a frame aligned to the anchor continues it: the keyframe made there is tied to the map
  // before the break in bundle adjustment, not by its features alone.
  Eigen::Matrix<double, 6, 6> anchor_odometry_covariance_ = Eigen::Matrix<double, 6, 6>::Zero();
  bool anchor_odometry_valid_ = false;
  uint64_t anchor_keyframe_ = 0;
  SE3 velocity_;  // T_last_cur of the last tracked step
  double velocity_dt_ = 0.0;  // its duration (s)
  bool has_velocity_ = false;

  uint64_t first_keyframe_ = kNoId;  // the world frame: fixed in every adjustment
  uint64_t reference_keyframe_ = kNoId;
  uint64_t last_keyframe_ = kNoId;
  uint64_t last_keyframe_frame_ = 0;
  uint64_t last_relocalised_frame_ = 0;
  std::vector<uint64_t> local_keyframes_;
  std::vector<uint64_t> local_points_;
  std::vector<uint64_t> recent_points_;  // created lately: culled unless re-found
  size_t reloc_cursor_ = 0;
  uint64_t ba_wanted_ = kNoId;  // keyframe whose adjustment waits for the worker
  // Deterministic mode (LocalBaParams::deterministic): one adjustment outstanding at a time, its
  // result applied at the start of frame `ba_due_frame_`.
  bool ba_outstanding_ = false;
  uint64_t ba_due_frame_ = 0;
  bool mapping_idle() const;
  void apply_due_ba_result(uint64_t frame_number);
  // Covariance of the dense odometry since the last keyframe (right perturbation of the current
  // frame relative to it); invalid once a frame went without dense alignment.
  Eigen::Matrix<double, 6, 6> odometry_covariance_ = Eigen::Matrix<double, 6, 6>::Zero();
  bool odometry_valid_ = false;

  ObjectLandmarkStore objects_;  // objects as landmarks (object_factors.h)

  std::mutex registry_mutex_;  // guards the two below (corrected_frames() is thread-safe)
  std::unordered_map<uint64_t, RegisteredFrame> registered_;
  std::map<uint64_t, SE3> corrections_;  // frame ID -> corrected T_wc, the latest wins
  std::atomic<uint64_t> ba_runs_{0};       // adjustments applied to the map

  // ---- tracker_loop.cpp: loop closing (loop_closing.h) and the global adjustment
  void close_pending_loop();
  void run_global_ba(int iterations);
  void optimise_map();
  void refine_registered_frames();
  uint64_t loop_query_ = kNoId;  // the newest keyframe, for place recognition on the next frame
  std::atomic<uint64_t> loops_closed_{0};
  std::atomic<uint64_t> loop_queries_{0};
  double loop_milliseconds_ = 0.0;  // place recognition and corrections, in total
  uint64_t object_costs_ = 0;              // object-landmark costs in those adjustments
};

}  // namespace dqo::tracking
