// StampMatcher: pairing keyframes with detection arrays by stamp, in stamp order, waiting for the
// detector in message time, and what it reports when things expire, get dropped or time goes back.
#include <memory>
#include <vector>
#include <gtest/gtest.h>
#include "dqo_map/objects/stamp_matcher.h"

namespace dqo::objects {
namespace {

struct FakeKeyFrame {
  int n = 0;
};
struct FakeDetections {
  int n = 0;
};
using Matcher = StampMatcher<std::shared_ptr<const FakeKeyFrame>, std::shared_ptr<const FakeDetections>>;
using Kind = Matcher::Step::Kind;

constexpr double kTol = 0.002;
constexpr double kKeep = 5.0;

Matcher make_matcher() { return Matcher(StampMatcherParams{kTol, kKeep}); }

// Keyframe `id` at `stamp`; its payload carries the id so steps can be checked against it.
std::optional<StampReset> add_kf(Matcher& m, double stamp, KeyFrameId id) {
  return m.add_keyframe(stamp, id, std::make_shared<const FakeKeyFrame>(FakeKeyFrame{static_cast<int>(id)}));
}
std::optional<StampReset> add_det(Matcher& m, double stamp, int n) {
  return m.add_detections(stamp, std::make_shared<const FakeDetections>(FakeDetections{n}));
}

// (keyframe id, detections n) of the matched steps, in order.
std::vector<std::pair<KeyFrameId, int>> matched(const Matcher::MatchResult& r) {
  std::vector<std::pair<KeyFrameId, int>> out;
  for (const auto& s : r.steps) {
    if (s.kind == Kind::kMatched) out.emplace_back(s.id, s.detections->n);
  }
  return out;
}

using Pairs = std::vector<std::pair<KeyFrameId, int>>;

TEST(StampMatcher, ExactStampMatches) {
  Matcher m = make_matcher();
  add_kf(m, 10.0, 1);
  add_det(m, 10.0, 7);
  const auto r = m.match(true);
  ASSERT_EQ(r.steps.size(), 1u);
  EXPECT_EQ(r.steps[0].kind, Kind::kMatched);
  EXPECT_EQ(r.steps[0].keyframe->n, 1);
  EXPECT_EQ(r.steps[0].detections->n, 7);
  EXPECT_DOUBLE_EQ(r.steps[0].stamp, 10.0);
  EXPECT_FALSE(r.steps[0].early_pose);
  EXPECT_EQ(m.buffered_keyframes(), 0u);
  EXPECT_EQ(m.buffered_detections(), 0u);
  EXPECT_EQ(r.dropped_detections_total, 0u);
}

TEST(StampMatcher, WithinToleranceMatchesOutsideDoesNot) {
  Matcher m = make_matcher();
  add_kf(m, 10.0, 1);
  add_det(m, 10.0025, 1);  // beyond the tolerance: not this keyframe's
  EXPECT_TRUE(m.match(true).steps.empty());
  EXPECT_EQ(m.buffered_keyframes(), 1u);

  Matcher early = make_matcher();
  add_kf(early, 10.0, 1);
  add_det(early, 9.9985, 2);  // 1.5 ms early: within
  EXPECT_EQ(matched(early.match(true)), (Pairs{{1, 2}}));
  Matcher late = make_matcher();
  add_kf(late, 10.0, 1);
  add_det(late, 10.0015, 3);  // 1.5 ms late: within
  EXPECT_EQ(matched(late.match(true)), (Pairs{{1, 3}}));
}

TEST(StampMatcher, NearerOfTwoCandidates) {
  {
    Matcher m = make_matcher();
    add_det(m, 9.9995, 1);   // 0.5 ms before
    add_det(m, 10.0008, 2);  // 0.8 ms after
    add_kf(m, 10.0, 1);
    const auto r = m.match(true);
    EXPECT_EQ(matched(r), (Pairs{{1, 1}}));
  }
  {
    Matcher m = make_matcher();
    add_det(m, 9.999, 1);    // 1 ms before
    add_det(m, 10.0003, 2);  // 0.3 ms after
    add_kf(m, 10.0, 1);
    const auto r = m.match(true);
    EXPECT_EQ(matched(r), (Pairs{{1, 2}}));
    EXPECT_EQ(m.buffered_detections(), 1u);  // the farther one stays, a later keyframe may be nearer
  }
}

TEST(StampMatcher, LateDetectionsAreWaitedFor) {
  Matcher m = make_matcher();
  add_kf(m, 10.0, 1);
  EXPECT_TRUE(m.match(true).steps.empty());
  add_kf(m, 12.0, 2);  // newer keyframes within buffer_seconds do not expire the first
  EXPECT_TRUE(m.match(true).steps.empty());
  add_det(m, 10.0, 5);  // the detector's latency: 2 s
  EXPECT_EQ(matched(m.match(true)), (Pairs{{1, 5}}));
  EXPECT_EQ(m.buffered_keyframes(), 1u);
}

TEST(StampMatcher, EarlyDetectionsWaitForTheirKeyframe) {
  Matcher m = make_matcher();
  add_det(m, 10.0, 5);
  add_det(m, 10.1, 6);
  const auto r0 = m.match(true);
  EXPECT_TRUE(r0.steps.empty());
  EXPECT_EQ(r0.dropped_detections, 0u);  // no keyframe yet: kept for one
  add_kf(m, 10.1, 1);
  const auto r1 = m.match(true);
  EXPECT_EQ(matched(r1), (Pairs{{1, 6}}));
  EXPECT_EQ(r1.dropped_detections, 1u);  // 10.0 is older than any keyframe to come
}

TEST(StampMatcher, KeyframesInStampOrderWhenNewerDetectionsComeFirst) {
  Matcher m = make_matcher();
  add_kf(m, 10.0, 1);
  add_kf(m, 10.1, 2);
  add_det(m, 10.1, 20);  // the second keyframe's detections come; the first's have not (yet)
  EXPECT_TRUE(m.match(true).steps.empty());  // the first keyframe still waits: nothing handed out
  EXPECT_EQ(m.buffered_detections(), 1u);
  add_det(m, 14.95, 30);
  EXPECT_TRUE(m.match(true).steps.empty());  // 4.95 s newer: the first has not expired yet
  add_det(m, 15.2, 40);  // the first expires; only then is the second handed out, beyond its own wait
  const auto r = m.match(true);
  ASSERT_EQ(r.steps.size(), 2u);
  EXPECT_EQ(r.steps[0].kind, Kind::kExpired);
  EXPECT_EQ(r.steps[0].id, 1u);
  EXPECT_EQ(matched(r), (Pairs{{2, 20}}));
}

TEST(StampMatcher, DetectionsSlightlyOutOfOrderAreBuffered) {
  // A detector with several workers publishes out of order: within max_reorder_seconds (1 s by
  // default) that is no loop, and each keyframe still gets its own array.
  Matcher m = make_matcher();
  add_kf(m, 10.0, 1);
  add_kf(m, 10.1, 2);
  EXPECT_FALSE(add_det(m, 10.1, 20));
  EXPECT_FALSE(add_det(m, 10.0, 10));
  EXPECT_EQ(matched(m.match(true)), (Pairs{{1, 10}, {2, 20}}));
  // The stream's newest stamp stays 10.1: 9.2 is 0.9 s behind it (buffered, and dropped as
  // unclaimable since no keyframe waits that early), 9.0 is 1.1 s behind it (a loop).
  EXPECT_FALSE(add_det(m, 9.2, 30));
  EXPECT_EQ(m.match(true).dropped_detections, 1u);
  const auto reset = add_det(m, 9.0, 40);
  ASSERT_TRUE(reset);
  EXPECT_NEAR(reset->back_by, 1.1, 1e-12);
}

TEST(StampMatcher, DetectionsFarOutOfOrderAreTimeGoingBack) {
  Matcher m = make_matcher();
  add_kf(m, 10.0, 1);
  add_kf(m, 12.0, 2);
  EXPECT_FALSE(add_det(m, 12.0, 20));
  const auto reset = add_det(m, 10.0, 10);  // 2 s back: the bag looped
  ASSERT_TRUE(reset);
  EXPECT_EQ(reset->dropped_keyframes, 2u);
  EXPECT_EQ(reset->dropped_detections, 1u);
  EXPECT_TRUE(m.match(true).steps.empty());
}

TEST(StampMatcher, ExpiresAfterBufferSecondsOfMessageTime) {
  Matcher m = make_matcher();
  add_kf(m, 10.0, 1);
  // No new stamps: however often (or late in wall time) it is asked, nothing expires.
  for (int i = 0; i < 10; ++i) EXPECT_TRUE(m.match(true).steps.empty());
  add_det(m, 14.5, 1);
  EXPECT_TRUE(m.match(true).steps.empty());
  add_det(m, 15.0, 2);  // exactly buffer_seconds newer: still waits
  EXPECT_TRUE(m.match(true).steps.empty());
  add_det(m, 15.1, 3);
  const auto r = m.match(true);
  ASSERT_EQ(r.steps.size(), 1u);
  EXPECT_EQ(r.steps[0].kind, Kind::kExpired);
  EXPECT_EQ(r.steps[0].id, 1u);
  EXPECT_DOUBLE_EQ(r.steps[0].stamp, 10.0);
  EXPECT_FALSE(r.steps[0].had_detections);
  EXPECT_EQ(r.steps[0].expired_total, 1u);
  EXPECT_EQ(m.buffered_keyframes(), 0u);
  // A newer keyframe expires on a newer keyframe's stamp too, and the count goes on.
  add_kf(m, 16.0, 2);
  add_kf(m, 21.5, 3);
  const auto r2 = m.match(true);
  ASSERT_EQ(r2.steps.size(), 1u);
  EXPECT_EQ(r2.steps[0].id, 2u);
  EXPECT_EQ(r2.steps[0].expired_total, 2u);
  EXPECT_EQ(m.expired_keyframes(), 2u);
}

TEST(StampMatcher, UnmatchedDetectionsAreDroppedAndCounted) {
  Matcher m = make_matcher();
  add_det(m, 9.5, 1);
  add_det(m, 9.9, 2);
  add_det(m, 10.0, 3);
  add_kf(m, 10.0, 1);
  const auto r = m.match(true);
  EXPECT_EQ(matched(r), (Pairs{{1, 3}}));
  EXPECT_EQ(r.dropped_detections, 2u);  // older than the keyframe: no later keyframe claims them
  EXPECT_EQ(r.dropped_detections_total, 2u);
  // Newer than every keyframe: kept for one to come, until buffer_seconds have passed.
  add_det(m, 10.5, 4);
  EXPECT_EQ(m.match(true).dropped_detections, 0u);
  EXPECT_EQ(m.buffered_detections(), 1u);
  add_det(m, 16.0, 5);
  const auto r2 = m.match(true);
  EXPECT_EQ(r2.dropped_detections, 1u);
  EXPECT_EQ(r2.dropped_detections_total, 3u);
  EXPECT_EQ(m.dropped_detections(), 3u);
  EXPECT_EQ(m.buffered_detections(), 1u);
}

TEST(StampMatcher, TimeGoingBackClearsBothBuffers) {
  Matcher m = make_matcher();
  EXPECT_FALSE(add_kf(m, 100.0, 1));
  EXPECT_FALSE(add_det(m, 101.0, 1));
  m.correct_poses({{1, SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 2, 3))}});
  EXPECT_TRUE(m.match(true).steps.empty());
  const auto reset = add_kf(m, 50.0, 1);  // the bag looped: keyframe IDs may repeat
  ASSERT_TRUE(reset);
  EXPECT_DOUBLE_EQ(reset->back_by, 50.0);
  EXPECT_EQ(reset->dropped_keyframes, 1u);
  EXPECT_EQ(reset->dropped_detections, 1u);
  EXPECT_EQ(m.buffered_keyframes(), 1u);  // the new keyframe only
  EXPECT_EQ(m.buffered_detections(), 0u);
  // The newest stamp went back too: the new keyframe is not expired by the old 101 s.
  EXPECT_TRUE(m.match(true).steps.empty());
  // The detection stream's own last stamp was forgotten: 50 s is no jump back for it.
  EXPECT_FALSE(add_det(m, 50.0, 2));
  const auto r = m.match(true);
  EXPECT_EQ(matched(r), (Pairs{{1, 2}}));
  EXPECT_FALSE(r.steps[0].early_pose);  // the correction of the old keyframe 1 went with the reset

  // Detections going back reset as well.
  EXPECT_FALSE(add_kf(m, 60.0, 3));
  EXPECT_FALSE(add_det(m, 70.0, 3));
  const auto reset2 = add_det(m, 1.0, 4);
  ASSERT_TRUE(reset2);
  EXPECT_DOUBLE_EQ(reset2->back_by, 69.0);
  EXPECT_EQ(reset2->dropped_keyframes, 1u);
  EXPECT_EQ(reset2->dropped_detections, 1u);
  EXPECT_EQ(m.buffered_keyframes(), 0u);
  EXPECT_EQ(m.buffered_detections(), 1u);
  // Equal stamps are not going back.
  EXPECT_FALSE(add_det(m, 1.0, 5));
}

TEST(StampMatcher, HoldsWhileNotReadyThenReleases) {
  Matcher m = make_matcher();
  add_kf(m, 10.0, 1);
  add_det(m, 10.0, 1);
  add_kf(m, 11.0, 2);
  add_det(m, 11.0, 2);
  const auto held = m.match(false);
  ASSERT_EQ(held.steps.size(), 1u);  // the oldest is held; the newer ones wait behind it
  EXPECT_EQ(held.steps[0].kind, Kind::kHeld);
  EXPECT_EQ(held.steps[0].id, 1u);
  EXPECT_EQ(held.dropped_detections, 0u);  // their detections are kept
  EXPECT_EQ(m.buffered_keyframes(), 2u);
  EXPECT_EQ(m.buffered_detections(), 2u);
  EXPECT_EQ(matched(m.match(true)), (Pairs{{1, 1}, {2, 2}}));  // a camera came
}

TEST(StampMatcher, HeldKeyframeExpiresWithItsDetections) {
  Matcher m = make_matcher();
  add_kf(m, 10.0, 1);
  add_det(m, 10.0, 1);
  add_det(m, 15.5, 2);
  const auto r = m.match(false);
  ASSERT_EQ(r.steps.size(), 1u);
  EXPECT_EQ(r.steps[0].kind, Kind::kExpired);
  EXPECT_TRUE(r.steps[0].had_detections);  // expired for want of a camera, not of detections
  EXPECT_EQ(r.dropped_detections, 1u);     // its detections go with it (too old)
}

TEST(StampMatcher, NoDetectionsNotReadyIsNotHeld) {
  Matcher m = make_matcher();
  add_kf(m, 10.0, 1);
  EXPECT_TRUE(m.match(false).steps.empty());  // waits for detections, nothing to report
}

TEST(StampMatcher, StampsNearZero) {
  Matcher m = make_matcher();
  EXPECT_FALSE(add_det(m, 0.0, 1));
  EXPECT_FALSE(add_kf(m, 0.001, 1));  // window reaches below zero
  EXPECT_EQ(matched(m.match(true)), (Pairs{{1, 1}}));
  EXPECT_FALSE(add_kf(m, 0.0015, 2));
  EXPECT_FALSE(add_det(m, 0.0015, 2));
  EXPECT_EQ(matched(m.match(true)), (Pairs{{2, 2}}));

  Matcher z = make_matcher();
  EXPECT_FALSE(add_kf(z, 0.0, 1));
  EXPECT_FALSE(add_kf(z, 0.0, 2));  // a repeated zero stamp is no jump back
  EXPECT_FALSE(add_det(z, 0.0, 1));
  EXPECT_EQ(matched(z.match(true)), (Pairs{{1, 1}}));
  EXPECT_TRUE(z.match(true).steps.empty());  // its detections went to the first
  EXPECT_EQ(z.buffered_keyframes(), 1u);
}

TEST(StampMatcher, EarlyPoseCorrectionsOfBufferedKeyframes) {
  Matcher m = make_matcher();
  add_kf(m, 10.0, 1);
  add_kf(m, 11.0, 2);
  const SE3 corrected(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1.0, 2.0, 3.0));
  m.correct_poses({{2, corrected}, {99, SE3()}});  // 99 is not buffered: ignored
  add_det(m, 10.0, 1);
  add_det(m, 11.0, 2);
  const auto r = m.match(true);
  ASSERT_EQ(r.steps.size(), 2u);
  EXPECT_FALSE(r.steps[0].early_pose);
  ASSERT_TRUE(r.steps[1].early_pose);
  EXPECT_TRUE(r.steps[1].early_pose->translation().isApprox(corrected.translation()));
  // Handed out once: a later keyframe with the same ID does not inherit it.
  add_kf(m, 12.0, 2);
  add_det(m, 12.0, 3);
  const auto r2 = m.match(true);
  ASSERT_EQ(r2.steps.size(), 1u);
  EXPECT_FALSE(r2.steps[0].early_pose);
}

}  // namespace
}  // namespace dqo::objects
