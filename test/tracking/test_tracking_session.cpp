// The tracking stage's stream handling, with external poses (pose_source: tf) so that no tracker
// runs: keyframe IDs count up and survive resets, time going back resets, repeated stamps are
// skipped.
#include <gtest/gtest.h>

#include "dqo_map/tracking/tracking_session.h"

namespace {

using dqo::SE3;
using dqo::tracking::SessionResult;
using dqo::tracking::TrackingConfig;
using dqo::tracking::TrackingSession;
using dqo::tracking::TrackingState;

SE3 at_x(double x) { return SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(x, 0, 0)); }

TEST(TrackingSession, KeyframesFromExternalPoses) {
  TrackingConfig config;
  config.mapping_keyframes.max_translation_m = 0.1;
  config.mapping_keyframes.max_frames = 0;
  TrackingSession session(config);
  // 4 cm per frame: the first frame, then every third (12 cm > 10 cm).
  std::vector<uint64_t> ids;
  std::vector<int> frames;
  for (int i = 0; i < 10; ++i) {
    const SessionResult r = session.add_pose(100.0 + 0.1 * i, at_x(0.04 * i));
    EXPECT_EQ(r.track.state, TrackingState::kOk);
    EXPECT_EQ(r.state_changed, i == 0);
    EXPECT_FALSE(r.reset);
    if (r.keyframe_id) {
      ids.push_back(*r.keyframe_id);
      frames.push_back(i);
    }
  }
  EXPECT_EQ(frames, (std::vector<int>{0, 3, 6, 9}));
  EXPECT_EQ(ids, (std::vector<uint64_t>{1, 2, 3, 4}));
  EXPECT_EQ(session.keyframes(), 4u);
  EXPECT_EQ(session.tracker(), nullptr);
  EXPECT_TRUE(session.corrected_keyframes().empty());
}

TEST(TrackingSession, TimeGoingBackResetsAndIdsAreNotReused) {
  TrackingConfig config;
  config.stream.out_of_order_s = 1.0;
  TrackingSession session(config);
  ASSERT_TRUE(session.add_pose(10.0, at_x(0.0)).keyframe_id);
  EXPECT_FALSE(session.add_pose(11.5, at_x(0.01)).keyframe_id);

  // The same stamp again: skipped, nothing else happens.
  const SessionResult repeated = session.add_pose(11.5, at_x(5.0));
  EXPECT_EQ(repeated.skipped, SessionResult::Skip::kRepeatedTimestamp);
  EXPECT_FALSE(repeated.keyframe_id);

  // A frame out of order (0.3 s before the last, within out_of_order_s): skipped, no reset; the
  // next one in order goes on from the last.
  const SessionResult late = session.add_pose(11.2, at_x(5.0));
  EXPECT_EQ(late.skipped, SessionResult::Skip::kOutOfOrder);
  EXPECT_FALSE(late.reset);
  EXPECT_NEAR(late.time_jump, 0.3, 1e-12);
  EXPECT_FALSE(late.keyframe_id);
  const SessionResult next = session.add_pose(11.6, at_x(0.02));
  EXPECT_EQ(next.skipped, SessionResult::Skip::kNone);
  EXPECT_FALSE(next.reset);
  EXPECT_FALSE(next.state_changed);

  // A looping bag: back to the start (1.6 s, beyond out_of_order_s). Reset, and the first frame
  // after it is a keyframe with a new ID.
  const SessionResult looped = session.add_pose(10.0, at_x(0.0));
  EXPECT_TRUE(looped.reset);
  EXPECT_NEAR(looped.time_jump, 1.6, 1e-12);
  ASSERT_TRUE(looped.keyframe_id);
  EXPECT_EQ(*looped.keyframe_id, 2u);
  EXPECT_FALSE(session.add_pose(10.1, at_x(0.01)).reset);
}

}  // namespace
