#pragma once
// RGB-D camera tracking: the RGB-D path of ORB-SLAM2 written anew (ORB features, motion model and
// projection search, PnP RANSAC against the last keyframe, pose-only refinement, local-map
// tracking, keyframes, local bundle adjustment on its own thread, relocalisation) fused with dense
// depth alignment so that it holds where features are few or motion is large.
//
// Threads: track() runs on the caller's thread; local BA runs on a worker owned by the Tracker and
// hands corrected poses back through corrected_frames(). No global state; the map lives in
// ID-keyed stores owned by the Tracker.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "dqo_map/common/image.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"
#include "dqo_map/tracking/object_landmarks.h"
#include "dqo_map/tracking/tracker_params.h"

namespace dqo::tracking {

enum class TrackingState {
  kNotInitialised,  // no frame with enough valid depth yet
  kOk,              // the evidence supports the pose (TrackQuality says how well)
  kDegraded,        // a pose, supported by one source only or with weak evidence (reasons say which)
  // This frame has no pose the evidence supports (reported T_wc is not valid). After
  // frames_to_lost such frames in a row, relocalisation is tried on every frame until it succeeds.
  kLost,
};
const char* to_string(TrackingState state);
// kOk or kDegraded: T_wc is valid.
inline bool has_pose(TrackingState state) {
  return state == TrackingState::kOk || state == TrackingState::kDegraded;
}

// Why a frame is degraded or lost: bit flags of TrackQuality::reasons.
namespace quality_reason {
constexpr uint32_t kFewInliers = 1u << 0;    // feature inliers below QualityParams::ok_inliers
constexpr uint32_t kPoorSpread = 1u << 1;    // inliers cover too little of the image
constexpr uint32_t kDenseFailed = 1u << 2;   // dense alignment did not converge (or no depth)
constexpr uint32_t kDenseResidual = 1u << 3; // it converged to a poor fit (residual, inliers)
constexpr uint32_t kDisagreement = 1u << 4;  // features and dense alignment give different poses
constexpr uint32_t kNoEvidence = 1u << 5;    // neither held: the motion model's guess only
constexpr uint32_t kRelocalising = 1u << 6;  // lost, relocalisation failed on this frame
constexpr uint32_t kNoDepth = 1u << 7;       // few inliers with depth: a monocular pose only
}  // namespace quality_reason
// "few_inliers+poor_spread"; "" for none.
std::string reasons_to_string(uint32_t reasons);

// The evidence behind a frame's state (what diagnostics show).
struct TrackQuality {
  int inliers = 0;               // feature inliers (map points) of the reported pose
  int depth_inliers = 0;         // ... of them with a depth measurement
  double spread = 0.0;           // fraction of the image's 4x4 cells holding one of them
  bool dense_tried = false;      // dense alignment ran on this frame
  bool dense_ok = false;         // ... and converged
  double dense_rms = 0.0;        // its whitened RMS (sigma units)
  double dense_inlier_ratio = 0.0;
  // Between the dense alignment's pose and the feature pose (when both exist).
  double disagreement_m = 0.0;
  double disagreement_deg = 0.0;
  uint32_t reasons = 0;          // quality_reason flags
};

// One rectified RGB-D capture (pinhole camera, depth registered to colour).
struct RgbdInput {
  double timestamp = 0.0;  // seconds; must increase (a jump back is the caller's reset)
  const ImageRgb8* rgb = nullptr;   // 3 channels
  const DepthImage* depth = nullptr;  // metres, 0/NaN = none
  // The depth image's capture stamp where it differs from the colour image's (a sensor that does
  // not capture the two together, e.g. a Kinect v1); unset: captured with the colour image.
  std::optional<double> depth_timestamp;
};

struct TrackResult {
  TrackingState state = TrackingState::kNotInitialised;
  SE3 T_wc;                  // valid when has_pose(state)
  bool new_keyframe = false; // the tracker's own keyframe was created from this frame
  int features = 0;          // ORB keypoints extracted
  int inliers = 0;           // map point matches kept by the pose optimisation
  bool relocalised = false;  // this frame ended a lost spell
  // Neither features nor dense alignment held on this frame: the state is kLost (reason
  // kNoEvidence); the tracker carries the constant-velocity prediction to the next frame, and
  // starts relocalising after frames_to_lost such frames in a row.
  bool predicted = false;
  TrackQuality quality;
  double milliseconds = 0.0; // time spent in track()
};

// A pose corrected by local bundle adjustment, for a frame registered with register_frame().
struct CorrectedPose {
  uint64_t id = 0;
  SE3 T_wc;
};

// Loop closing so far (TrackerParams::loop).
struct LoopStats {
  uint64_t queries = 0;        // keyframes checked for a loop
  uint64_t closed = 0;         // loops found, verified and corrected
  double milliseconds = 0.0;   // spent in place recognition and corrections, in total
};

class Tracker {
 public:
  Tracker(const PinholeCamera& camera, const TrackerParams& params);
  ~Tracker();  // stops and joins the local BA thread
  Tracker(const Tracker&) = delete;
  Tracker& operator=(const Tracker&) = delete;

  // Input that does not fit the camera (a missing image, another size, not 3 channels) is
  // skipped: nothing changes and the result carries the current state (and the last pose).
  TrackResult track(const RgbdInput& input);

  // Forgets the map and starts over (a looping bag, a time jump backwards).
  void reset();

  // Remembers the last tracked frame under `id` (a mapping keyframe chosen by the caller): its pose
  // is kept relative to the tracker's reference keyframe, so that later bundle adjustments move it
  // too. Call right after a track() that returned kOk.
  void register_frame(uint64_t id);

  // The registered frames whose poses bundle adjustment changed since the last call (thread-safe).
  // The worker's results enter the map on the tracker's thread, at the start of the next track()
  // (or in wait_for_mapping()); a frame corrected twice in between is reported once, latest pose.
  std::vector<CorrectedPose> corrected_frames();

  // Blocks until the local BA worker is idle and applies what it finished (tests, the end of an
  // offline run). Call on the thread that calls track().
  void wait_for_mapping();

  // The end of a run (offline): waits for local BA, then one global bundle adjustment over every
  // keyframe and map point (LoopParams::final_global_ba); registered frames follow their reference
  // keyframes (corrected_frames()). On the thread that calls track().
  void optimise_map();
  LoopStats loop_stats() const;  // on the tracker's thread
  // Objects as landmarks (object_landmarks.h; local BA uses them when params.objects.enabled).
  // The object stage's newest objects, in the tracker's world frame, replacing the last set.
  // On the tracker's thread; a reset() forgets them.
  void set_object_landmarks(const std::vector<ObjectLandmark>& objects);
  // The detections of registered frame `frame_id` (register_frame) associated with objects; they
  // join the next adjustments of the frame's reference keyframe. Unknown frames are ignored.
  void add_object_sightings(uint64_t frame_id, const std::vector<ObjectSighting>& sightings);
  size_t num_object_landmarks() const;  // on the tracker's thread
  // Object-landmark costs (keyframe, object) in the adjustments applied so far; tracker's thread.
  uint64_t object_costs_applied() const;

  TrackingState state() const;  // any thread
  // The tracker's own map (not the mapping keyframes); on the tracker's thread.
  size_t num_keyframes() const;
  size_t num_map_points() const;
  uint64_t local_ba_runs() const;  // bundle adjustments applied to the map since construction

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dqo::tracking
