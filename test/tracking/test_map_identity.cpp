// The map identity policy (issue 26): a new map_id whenever tracking re-anchors a map that holds
// keyframes (time going back, another camera), never for a loss, a skipped frame or external poses.
#include <gtest/gtest.h>

#include "dqo_map/tracking/map_identity.h"

namespace {

using dqo::tracking::MapIdentity;
using dqo::tracking::SessionResult;
using dqo::tracking::TrackingState;

SessionResult frame(TrackingState state, bool keyframe, bool reset = false, bool new_camera = false) {
  static uint64_t next_id = 1;
  SessionResult r;
  r.track.state = state;
  if (keyframe) r.keyframe_id = next_id++;
  r.reset = reset;
  r.new_camera = new_camera;
  return r;
}

TEST(MapIdentity, NewMapWhenTrackingReanchorsAMapWithKeyframes) {
  MapIdentity map("tracker:map:host:42:1000", /*external=*/false);
  EXPECT_EQ(map.id(), "tracker:map:host:42:1000");
  // The first tracker run's first frame reports new_camera: the map is still empty, no new map.
  EXPECT_FALSE(map.update(frame(TrackingState::kOk, true, false, true)));
  EXPECT_EQ(map.run(), 1);
  EXPECT_FALSE(map.update(frame(TrackingState::kOk, false)));
  EXPECT_FALSE(map.update(frame(TrackingState::kOk, true)));
  EXPECT_EQ(map.keyframes(), 2u);
  // Lost, degraded, relocalised: the same map (the tracker starts no second one).
  EXPECT_FALSE(map.update(frame(TrackingState::kDegraded, false)));
  EXPECT_FALSE(map.update(frame(TrackingState::kLost, false)));
  EXPECT_FALSE(map.update(frame(TrackingState::kOk, true)));
  EXPECT_EQ(map.id(), "tracker:map:host:42:1000");
  // A skipped frame (out of order) changes nothing.
  SessionResult skipped;
  skipped.skipped = SessionResult::Skip::kOutOfOrder;
  EXPECT_FALSE(map.update(skipped));
  // Time went back (a bag played again): a new map, whose first keyframe is this frame's.
  EXPECT_TRUE(map.update(frame(TrackingState::kOk, true, /*reset=*/true)));
  EXPECT_EQ(map.id(), "tracker:map:host:42:1000:run2");
  EXPECT_EQ(map.run(), 2);
  EXPECT_EQ(map.keyframes(), 1u);
  // Another camera: a third map.
  EXPECT_TRUE(map.update(frame(TrackingState::kNotInitialised, false, false, /*new_camera=*/true)));
  EXPECT_EQ(map.id(), "tracker:map:host:42:1000:run3");
  // A reset before the new map held any keyframe: nothing built in it, it stays.
  EXPECT_FALSE(map.update(frame(TrackingState::kNotInitialised, false, /*reset=*/true)));
  EXPECT_EQ(map.id(), "tracker:map:host:42:1000:run3");
}

TEST(MapIdentity, ExternalPosesAreOneMap) {
  MapIdentity map("tf:map", /*external=*/true);
  EXPECT_FALSE(map.update(frame(TrackingState::kOk, true)));
  EXPECT_FALSE(map.update(frame(TrackingState::kOk, true, /*reset=*/true)));
  EXPECT_EQ(map.id(), "tf:map");
  EXPECT_EQ(map.run(), 1);
}

}  // namespace
