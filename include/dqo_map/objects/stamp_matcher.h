#pragma once
// StampMatcher: pairs keyframes with the detection arrays of their images by stamp (the
// association node's input stage, kept free of ROS so it is unit-tested). The detector runs beside
// the tracker, so its arrays come late, early or not at all (frames that are not keyframes):
//  - both streams are buffered; a keyframe matches the array within `stamp_tolerance` of its stamp,
//    the nearer one where two qualify;
//  - keyframes are handed out strictly in stamp order: the oldest waits for its detections (or
//    expires) before any newer one is handed out, so the result does not depend on the latency;
//  - waiting is bounded in message time, not wall time (a bag may play faster or slower):
//    a keyframe expires once a stamp `buffer_seconds` newer has been seen on either stream;
//  - arrays no keyframe can claim any more are dropped and counted;
//  - a keyframe stamp older than the newest keyframe's, or a detection stamp more than
//    `max_reorder_seconds` older than the newest detection's, means a looping bag: everything
//    buffered goes. Smaller steps back of detection arrays are a detector publishing out of order
//    (several worker threads, variable inference time): the array is simply buffered;
//  - while the caller cannot process (no usable camera yet), matched keyframes are held, not lost,
//    until they expire;
//  - pose corrections that arrive for a keyframe still buffered are kept and handed out with it.
// Methods return what happened; the caller logs and publishes.
#include <cstdint>
#include <deque>
#include <iterator>
#include <map>
#include <optional>
#include <utility>
#include <vector>
#include "dqo_map/geometry/se3.h"
#include "dqo_map/objects/object_types.h"

namespace dqo::objects {

struct StampMatcherParams {
  double stamp_tolerance = 0.002;  // seconds between a keyframe's and its detections' stamps
  double buffer_seconds = 5.0;     // how long either side waits for the other (message time)
  double max_reorder_seconds = 1.0;  // detection arrays this much out of order are not a loop
};

// A stream's time went back: both buffers were cleared.
struct StampReset {
  double back_by = 0.0;           // seconds
  size_t dropped_keyframes = 0;
  size_t dropped_detections = 0;
};

// KeyFramePtr, DetectionsPtr: cheap-to-copy handles of the payloads (std::shared_ptr, or the
// boost::shared_ptr of a ROS message), handed back untouched.
template <class KeyFramePtr, class DetectionsPtr>
class StampMatcher {
 public:

  // What happened to one keyframe, in the order it happened.
  struct Step {
    enum class Kind {
      kMatched,  // ready to process: keyframe, detections and any early pose
      kExpired,  // waited buffer_seconds without being processed; it is gone
      kHeld,     // has detections but the caller was not ready; it waits (and blocks newer ones)
    };
    Kind kind = Kind::kMatched;
    KeyFramePtr keyframe;
    KeyFrameId id = 0;
    double stamp = 0.0;
    DetectionsPtr detections;      // kMatched only
    std::optional<SE3> early_pose;  // kMatched: corrected while it waited
    bool had_detections = false;   // kExpired: expired for want of a ready caller, not detections
    uint64_t expired_total = 0;    // kExpired: keyframes expired so far, this one included
  };

  struct MatchResult {
    std::vector<Step> steps;
    uint64_t dropped_detections = 0;        // by this call
    uint64_t dropped_detections_total = 0;  // so far
  };

  explicit StampMatcher(const StampMatcherParams& params) : p_(params) {}

  // Keyframes come in stamp order (one tracker); an older stamp resets (see above).
  std::optional<StampReset> add_keyframe(double stamp, KeyFrameId id, KeyFramePtr keyframe) {
    std::optional<StampReset> reset = check_time(stamp, &last_kf_stamp_, 0.0);
    keyframes_.push_back(Buffered{stamp, id, std::move(keyframe)});
    return reset;
  }

  // A second array with the same stamp replaces the first. Arrays up to max_reorder_seconds out of
  // order are buffered like any other (one that no keyframe can claim is dropped at the next match).
  std::optional<StampReset> add_detections(double stamp, DetectionsPtr detections) {
    std::optional<StampReset> reset = check_time(stamp, &last_det_stamp_, p_.max_reorder_seconds);
    detections_[stamp] = std::move(detections);
    return reset;
  }

  // Corrections (e.g. bundle adjustment) for keyframes still buffered; others are ignored, as
  // the caller applies those to what it has already processed.
  void correct_poses(const std::map<KeyFrameId, SE3>& T_wc_by_id) {
    for (const Buffered& kf : keyframes_) {
      const auto it = T_wc_by_id.find(kf.id);
      if (it != T_wc_by_id.end()) early_poses_[kf.id] = it->second;
    }
  }

  // Hands out what can be decided now. `ready`: the caller can process a keyframe (false holds
  // matched keyframes, e.g. while no camera model is usable).
  MatchResult match(bool ready) {
    MatchResult result;
    const double tol = p_.stamp_tolerance, keep = p_.buffer_seconds;
    while (!keyframes_.empty()) {
      const Buffered kf = keyframes_.front();
      const double t = kf.stamp;
      auto it = detections_.lower_bound(t - tol);
      const bool found = it != detections_.end() && it->first <= t + tol;
      Step step;
      step.keyframe = kf.keyframe;
      step.id = kf.id;
      step.stamp = t;
      if (found && ready) {
        auto next = std::next(it);  // the nearer of two candidates within the tolerance
        if (next != detections_.end() && next->first <= t + tol && next->first - t < t - it->first) it = next;
        step.detections = it->second;
        const auto early = early_poses_.find(kf.id);
        if (early != early_poses_.end()) step.early_pose = early->second;
        result.steps.push_back(std::move(step));
        detections_.erase(it);
        early_poses_.erase(kf.id);
        keyframes_.pop_front();
        continue;
      }
      if (newest_ - t <= keep) {
        if (found) {
          step.kind = Step::Kind::kHeld;
          result.steps.push_back(std::move(step));
        }
        break;
      }
      step.kind = Step::Kind::kExpired;
      step.had_detections = found;
      step.expired_total = ++expired_keyframes_;
      result.steps.push_back(std::move(step));
      early_poses_.erase(kf.id);
      keyframes_.pop_front();
    }
    // Detections no keyframe can claim any more: older than the oldest waiting keyframe (keyframes
    // come in stamp order), or than the buffer. Most are of frames that were not keyframes.
    const double oldest_kf = keyframes_.empty() ? last_kf_stamp_.value_or(0.0) : keyframes_.front().stamp;
    while (!detections_.empty()) {
      const double d = detections_.begin()->first;
      if (!(d + tol < oldest_kf) && !(newest_ - d > keep)) break;
      detections_.erase(detections_.begin());
      ++result.dropped_detections;
      ++dropped_detections_;
    }
    result.dropped_detections_total = dropped_detections_;
    return result;
  }

  size_t buffered_keyframes() const { return keyframes_.size(); }
  size_t buffered_detections() const { return detections_.size(); }
  uint64_t expired_keyframes() const { return expired_keyframes_; }
  uint64_t dropped_detections() const { return dropped_detections_; }

 private:
  struct Buffered {
    double stamp;
    KeyFrameId id;
    KeyFramePtr keyframe;
  };

  // `*last` is the newest stamp of the stream; a step back of more than `slack` is a loop.
  std::optional<StampReset> check_time(double stamp, std::optional<double>* last, double slack) {
    std::optional<StampReset> reset;
    if (*last && stamp < **last - slack) {
      reset = StampReset{**last - stamp, keyframes_.size(), detections_.size()};
      keyframes_.clear();
      detections_.clear();
      early_poses_.clear();
      last_kf_stamp_.reset();
      last_det_stamp_.reset();
      newest_ = 0.0;
    }
    if (!*last || stamp > **last) *last = stamp;
    if (stamp > newest_) newest_ = stamp;
    return reset;
  }

  StampMatcherParams p_;
  std::deque<Buffered> keyframes_;                   // waiting for detections, ascending stamps
  std::map<double, DetectionsPtr> detections_;
  std::map<KeyFrameId, SE3> early_poses_;            // corrections of keyframes still buffered
  std::optional<double> last_kf_stamp_, last_det_stamp_;  // newest stamp per stream, none yet
  double newest_ = 0.0;                               // newest stamp of either stream
  uint64_t expired_keyframes_ = 0, dropped_detections_ = 0;
};

}  // namespace dqo::objects
