#include "dqo_map/tracking/tracking_session.h"

namespace dqo::tracking {
namespace {

bool same_camera(const PinholeCamera& a, const PinholeCamera& b) {
  return a.width == b.width && a.height == b.height && a.fx == b.fx && a.fy == b.fy && a.cx == b.cx &&
         a.cy == b.cy;
}

}  // namespace

TrackingSession::TrackingSession(const TrackingConfig& config)
    : config_(config), selector_(config.mapping_keyframes) {}

TrackingSession::~TrackingSession() = default;

void TrackingSession::reset() {
  if (tracker_) tracker_->reset();
  selector_.reset();
  last_timestamp_.reset();
  state_ = TrackingState::kNotInitialised;
}

bool TrackingSession::admit(double timestamp, SessionResult* result) {
  result->previous_state = state_;
  if (last_timestamp_) {
    if (timestamp < *last_timestamp_) {
      result->time_jump = *last_timestamp_ - timestamp;
      if (result->time_jump <= config_.stream.out_of_order_s) {
        result->skipped = SessionResult::Skip::kOutOfOrder;
        return false;
      }
      result->reset = true;
      reset();
    } else if (timestamp == *last_timestamp_) {
      result->skipped = SessionResult::Skip::kRepeatedTimestamp;
      return false;
    }
  }
  last_timestamp_ = timestamp;
  return true;
}

void TrackingSession::finish(SessionResult* result) {
  state_ = result->track.state;
  result->state_changed = result->track.state != result->previous_state;
  // Mapping keyframes only from ok frames: a degraded pose (one source of evidence, or a
  // monocular one) is published but not built into the map; a lost frame has no pose.
  if (result->track.state == TrackingState::kOk && selector_.consider(result->track.T_wc)) {
    result->keyframe_id = next_keyframe_id_++;
  }
}

SessionResult TrackingSession::track(const PinholeCamera& camera, const RgbdInput& input) {
  SessionResult result;
  if (tracker_ && !same_camera(camera, camera_)) {
    // Another camera: the map of the old one cannot be tracked against. Start over.
    tracker_.reset();
    selector_.reset();
    state_ = TrackingState::kNotInitialised;
    last_timestamp_.reset();
  }
  if (!admit(input.timestamp, &result)) return result;
  if (!tracker_) {
    tracker_ = std::make_unique<Tracker>(camera, config_.tracker);
    camera_ = camera;
    result.new_camera = true;
  }
  result.track = tracker_->track(input);
  finish(&result);
  if (result.keyframe_id) tracker_->register_frame(*result.keyframe_id);
  return result;
}

SessionResult TrackingSession::add_pose(double timestamp, const SE3& T_wc) {
  SessionResult result;
  if (!admit(timestamp, &result)) return result;
  result.track.state = TrackingState::kOk;
  result.track.T_wc = T_wc;
  finish(&result);
  return result;
}

void TrackingSession::set_object_landmarks(const std::vector<ObjectLandmark>& objects) {
  if (tracker_) tracker_->set_object_landmarks(objects);
}

void TrackingSession::add_object_sightings(uint64_t keyframe_id,
                                           const std::vector<ObjectSighting>& sightings) {
  if (tracker_) tracker_->add_object_sightings(keyframe_id, sightings);
}

std::vector<CorrectedPose> TrackingSession::corrected_keyframes() {
  if (!tracker_) return {};
  return tracker_->corrected_frames();
}

}  // namespace dqo::tracking
