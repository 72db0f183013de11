#pragma once
// The identity of the map the tracker's poses are in (tracking_node's latched `map_id`). A tracker
// run anchors a map of its own at its first pose; whenever tracking re-anchors — time going back (a
// bag played again, a restarted recording), another camera — the poses that follow are in another
// frame, which nothing relates to the old one. Such a map gets a new identity, so that mapping and
// association keep the old map apart (they save or drop it and start empty) instead of fusing two
// frames into one (issue 26: a ghost table, rotated). A loss is not a re-anchor: the tracker stays
// lost until it relocalises into the same map (it starts no second map), so the identity stays.
// A map that holds no keyframe yet is re-anchored freely: nothing was built in it.
// External poses (pose_source tf) are one map whatever happens: whoever publishes them keeps it.
//
// The policy alone, without ROS: tracking_node asks it after every tracked frame.

#include <cstdint>
#include <string>

#include "dqo_map/tracking/tracking_session.h"

namespace dqo::tracking {

class MapIdentity {
 public:
  // base: the first map's ID, unique to this run (tracking_node: map frame, host, pid, start time);
  // later maps append ":run<n>". external: poses from elsewhere (one map, never renewed).
  MapIdentity(std::string base, bool external) : base_(std::move(base)), external_(external) {}

  const std::string& id() const { return id_.empty() ? base_ : id_; }
  int run() const { return run_; }                        // 1 for the first map
  uint64_t keyframes() const { return keyframes_; }        // keyframes made in the current map

  // After each frame's SessionResult (skipped frames included: they change nothing). True when
  // this frame begins a new map (id() changed): publish it before this frame's keyframe.
  bool update(const SessionResult& r) {
    bool renewed = false;
    if (!external_ && (r.reset || r.new_camera) && keyframes_ > 0) {
      ++run_;
      id_ = base_ + ":run" + std::to_string(run_);
      keyframes_ = 0;
      renewed = true;
    }
    if (r.keyframe_id) ++keyframes_;
    return renewed;
  }

 private:
  std::string base_, id_;
  bool external_ = false;
  int run_ = 1;
  uint64_t keyframes_ = 0;
};

}  // namespace dqo::tracking
