#pragma once
// The tracking stage as tracking_node, dqo_track and the offline pipeline run it: a Tracker, the
// mapping keyframe policy, and what a live stream needs around them:
//   - time going backwards (a looping bag) resets the tracker and the keyframe policy; a repeated
//     timestamp is skipped (the tracker needs increasing time), and so is a frame out of order (a
//     stamp before the last one by at most StreamParams::out_of_order_s);
//   - a change of camera (another resolution or intrinsics) starts a new tracker;
//   - mapping keyframe IDs count up across resets and are never reused within a session.
// With external poses (`pose_source: tf`, a robot's own SLAM) there is no tracker: add_pose() only
// selects keyframes.
//
// Not thread-safe: one caller thread (the tracker's own BA thread is internal to it).

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"
#include "dqo_map/common/keyframe_selector.h"
#include "dqo_map/tracking/params_yaml.h"
#include "dqo_map/tracking/tracker.h"

namespace dqo::tracking {

struct SessionResult {
  enum class Skip { kNone, kRepeatedTimestamp, kOutOfOrder };
  Skip skipped = Skip::kNone;       // the frame was not tracked (nothing else below but time_jump is set)
  TrackResult track;                // the tracker's result; with external poses: kOk and T_wc
  bool reset = false;               // time went back: everything started over before this frame
  double time_jump = 0.0;           // seconds back (positive) when reset or skipped out of order
  bool new_camera = false;          // a new tracker was started for another camera
  TrackingState previous_state = TrackingState::kNotInitialised;
  bool state_changed = false;       // track.state differs from the previous frame's
  std::optional<uint64_t> keyframe_id;  // this frame became mapping keyframe `id`
};

class TrackingSession {
 public:
  explicit TrackingSession(const TrackingConfig& config);
  ~TrackingSession();
  TrackingSession(const TrackingSession&) = delete;
  TrackingSession& operator=(const TrackingSession&) = delete;

  // Tracks one rectified frame taken with `camera`.
  SessionResult track(const PinholeCamera& camera, const RgbdInput& input);

  // A pose from elsewhere (no tracker runs): only keyframe selection and the time checks.
  SessionResult add_pose(double timestamp, const SE3& T_wc);

  // Poses of mapping keyframes that bundle adjustment moved since the last call.
  std::vector<CorrectedPose> corrected_keyframes();

  // Objects as landmarks (Tracker::set_object_landmarks / add_object_sightings), with mapping
  // keyframe IDs as the frame IDs. Nothing without a tracker (external poses).
  void set_object_landmarks(const std::vector<ObjectLandmark>& objects);
  void add_object_sightings(uint64_t keyframe_id, const std::vector<ObjectSighting>& sightings);

  // Starts over (tracker and keyframe policy); keyframe IDs keep counting.
  void reset();

  TrackingState state() const { return state_; }
  const Tracker* tracker() const { return tracker_.get(); }
  Tracker* tracker() { return tracker_.get(); }  // register_frame, optimise_map (offline tools)
  uint64_t keyframes() const { return next_keyframe_id_ - 1; }

 private:
  // Time checks shared by both inputs; false when the frame is to be skipped.
  bool admit(double timestamp, SessionResult* result);
  void finish(SessionResult* result);

  TrackingConfig config_;
  KeyframeSelector selector_;
  std::unique_ptr<Tracker> tracker_;
  PinholeCamera camera_;
  std::optional<double> last_timestamp_;
  TrackingState state_ = TrackingState::kNotInitialised;
  uint64_t next_keyframe_id_ = 1;
};

}  // namespace dqo::tracking
