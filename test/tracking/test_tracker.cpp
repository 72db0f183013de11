// The tracker end to end on the synthetic `tiny` scene (20 frames orbiting a table, 160x120, no
// noise): accuracy, keyframes, bundle adjustment corrections of registered frames, reset,
// relocalisation after a jump and after being lost, bad input.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "dqo_map/sim/renderer.h"
#include "dqo_map/sim/scene_loader.h"
#include "dqo_map/tracking/tracker.h"

namespace {

using dqo::SE3;
using dqo::tracking::RgbdInput;
using dqo::tracking::Tracker;
using dqo::tracking::TrackerParams;
using dqo::tracking::TrackingState;
using dqo::tracking::TrackResult;

class TinyScene : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    std::string error;
    scene_ = dqo::sim::load_scene(std::string(DQO_SOURCE_DIR) + "/config/scenes/tiny.yaml", {},
                                  &error)
                 .value();
    renderer_ = std::make_unique<dqo::sim::Renderer>(*scene_, 2);
    frames_ = std::make_unique<std::vector<dqo::Frame>>();
    for (int i = 0; i < renderer_->num_frames(); ++i) frames_->push_back(renderer_->render(i, false));
  }
  static void TearDownTestSuite() {
    frames_.reset();
    renderer_.reset();
    scene_.reset();
  }

  static const dqo::Frame& frame(int i) { return (*frames_)[i]; }
  static int num_frames() { return static_cast<int>(frames_->size()); }
  static const dqo::PinholeCamera& camera() { return scene_->camera; }
  // At 160x120 (a sixteenth of a 640x480 frame's pixels) a well tracked frame has tens of
  // inliers, not hundreds: the ok threshold scaled down with the image.
  static TrackerParams tiny_params() {
    TrackerParams params;
    params.quality.ok_inliers = 15;
    return params;
  }

  static TrackResult track(Tracker* tracker, const dqo::Frame& f, double timestamp) {
    RgbdInput input;
    input.timestamp = timestamp;
    input.rgb = &f.rgb;
    input.depth = &f.depth;
    return tracker->track(input);
  }
  static TrackResult track(Tracker* tracker, int i) {
    return track(tracker, frame(i), frame(i).timestamp);
  }

  // Ground truth in the tracker's world (the first tracked frame's camera).
  static SE3 truth(int i, int first = 0) { return frame(first).T_wc.inverse() * frame(i).T_wc; }

  static double position_error(const SE3& estimate, const SE3& truth_pose) {
    return (estimate.translation() - truth_pose.translation()).norm();
  }
  static double angle_deg(const SE3& a, const SE3& b) {
    const double w = std::min(1.0, std::abs((a.inverse() * b).quaternion().w()));
    return 2.0 * std::acos(w) * 180.0 / M_PI;
  }

  static inline std::optional<dqo::sim::Scene> scene_;
  static inline std::unique_ptr<dqo::sim::Renderer> renderer_;
  static inline std::unique_ptr<std::vector<dqo::Frame>> frames_;
};

// Tracks the whole scene; returns the RMSE of the positions (the world is the first camera's,
// so no alignment is needed) and checks every frame was tracked.
double track_all(Tracker* tracker, int first, int count,
                 const std::function<TrackResult(Tracker*, int)>& track_one,
                 const std::function<SE3(int)>& truth_of, double* max_angle_deg) {
  double sum = 0.0;
  *max_angle_deg = 0.0;
  for (int i = first; i < first + count; ++i) {
    const TrackResult r = track_one(tracker, i);
    EXPECT_EQ(r.state, TrackingState::kOk) << "frame " << i;
    EXPECT_FALSE(r.predicted) << "frame " << i;
    if (r.state != TrackingState::kOk) return INFINITY;
    const SE3 t = truth_of(i);
    sum += (r.T_wc.translation() - t.translation()).squaredNorm();
    const double w = std::min(1.0, std::abs((r.T_wc.inverse() * t).quaternion().w()));
    *max_angle_deg = std::max(*max_angle_deg, 2.0 * std::acos(w) * 180.0 / M_PI);
  }
  return std::sqrt(sum / count);
}

TEST_F(TinyScene, TrackedWithAteBelowOneCentimetre) {
  Tracker tracker(camera(), tiny_params());
  double max_angle = 0.0;
  const double ate = track_all(
      &tracker, 0, num_frames(), [](Tracker* t, int i) { return track(t, i); },
      [](int i) { return truth(i); }, &max_angle);
  EXPECT_LT(ate, 0.01);
  EXPECT_LT(max_angle, 1.0);
}

TEST_F(TinyScene, KeyframesAndMapPointsGrowOverTheOrbit) {
  Tracker tracker(camera(), tiny_params());
  int new_keyframes = 0;
  for (int i = 0; i < num_frames(); ++i) new_keyframes += track(&tracker, i).new_keyframe;
  EXPECT_GE(tracker.num_keyframes(), 4u);
  EXPECT_EQ(static_cast<size_t>(new_keyframes), tracker.num_keyframes());
  EXPECT_GT(tracker.num_map_points(), 100u);
}

TEST_F(TinyScene, BundleAdjustmentCorrectsRegisteredFrames) {
  Tracker tracker(camera(), tiny_params());
  std::vector<uint64_t> registered;
  for (int i = 0; i < num_frames(); ++i) {
    if (track(&tracker, i).state != TrackingState::kOk) continue;
    tracker.register_frame(1000 + i);
    registered.push_back(1000 + i);
  }
  tracker.wait_for_mapping();
  EXPECT_GT(tracker.local_ba_runs(), 0u);
  const std::vector<dqo::tracking::CorrectedPose> corrected = tracker.corrected_frames();
  ASSERT_FALSE(corrected.empty());
  for (const auto& c : corrected) {
    ASSERT_GE(c.id, 1000u);
    ASSERT_LT(c.id, 1000u + num_frames());
    EXPECT_LT(position_error(c.T_wc, truth(static_cast<int>(c.id - 1000))), 0.02) << c.id;
  }
  EXPECT_TRUE(tracker.corrected_frames().empty());  // handed over once
}

TEST_F(TinyScene, OptimiseMapRefinesEveryRegisteredFrameAndClosesNoFalseLoop) {
  Tracker tracker(camera(), tiny_params());
  double online = 0.0;
  int registered = 0;
  for (int i = 0; i < num_frames(); ++i) {
    const TrackResult r = track(&tracker, i);
    if (r.state != TrackingState::kOk) continue;
    tracker.register_frame(1000 + i);
    online += (r.T_wc.translation() - truth(i).translation()).squaredNorm();
    ++registered;
  }
  ASSERT_GT(registered, num_frames() / 2);
  tracker.optimise_map();
  const std::vector<dqo::tracking::CorrectedPose> corrected = tracker.corrected_frames();
  // Every frame but those on the first keyframe (the gauge, held by the global adjustment).
  EXPECT_GE(static_cast<int>(corrected.size()), registered - 3);
  double refined = 0.0;
  for (const auto& c : corrected) {
    const int i = static_cast<int>(c.id - 1000);
    EXPECT_LT(position_error(c.T_wc, truth(i)), 0.01) << i;
    refined += (c.T_wc.translation() - truth(i).translation()).squaredNorm();
  }
  // No worse than tracking gave them (a few tenths of a millimetre of slack).
  EXPECT_LT(std::sqrt(refined / registered), std::sqrt(online / registered) + 5e-4);
  // The orbit sees the same table throughout: covisible all along, nothing to close.
  const dqo::tracking::LoopStats loops = tracker.loop_stats();
  EXPECT_GT(loops.queries, 0u);
  EXPECT_EQ(loops.closed, 0u);
}

TEST_F(TinyScene, ResetStartsANewMap) {
  Tracker tracker(camera(), tiny_params());
  for (int i = 0; i < 8; ++i) {
    track(&tracker, i);
    tracker.register_frame(i);
  }
  ASSERT_GT(tracker.num_keyframes(), 0u);
  tracker.reset();
  EXPECT_EQ(tracker.state(), TrackingState::kNotInitialised);
  EXPECT_EQ(tracker.num_keyframes(), 0u);
  EXPECT_EQ(tracker.num_map_points(), 0u);
  tracker.wait_for_mapping();
  EXPECT_TRUE(tracker.corrected_frames().empty());

  // A new world: the first frame after the reset is the origin.
  const TrackResult first = track(&tracker, 10);
  EXPECT_EQ(first.state, TrackingState::kOk);
  EXPECT_LT(first.T_wc.translation().norm(), 1e-9);
  double max_angle = 0.0;
  const double ate = track_all(
      &tracker, 11, num_frames() - 11, [](Tracker* t, int i) { return track(t, i); },
      [](int i) { return truth(i, 10); }, &max_angle);
  EXPECT_LT(ate, 0.01);
}

TEST_F(TinyScene, RecoversAfterAJumpToAViewSeenBefore) {
  Tracker tracker(camera(), tiny_params());
  for (int i = 0; i < 12; ++i) ASSERT_EQ(track(&tracker, i).state, TrackingState::kOk);
  // Back to the view of frame 3, 144° of orbit away; the motion model still says "keep turning".
  const int target = 3;
  bool recovered = false;
  for (int attempt = 0; attempt < 3 && !recovered; ++attempt) {
    const dqo::Frame view =
        renderer_->render_view(frame(target).T_wc, target, 1.0 + 0.1 * attempt, false);
    const TrackResult r = track(&tracker, view, 1.0 + 0.1 * attempt);
    recovered = r.state == TrackingState::kOk && !r.predicted &&
                position_error(r.T_wc, truth(target)) < 0.02;
  }
  EXPECT_TRUE(recovered);
}

TEST_F(TinyScene, RelocalisesAfterBeingLost) {
  const TrackerParams params = tiny_params();
  Tracker tracker(camera(), params);
  for (int i = 0; i < 10; ++i) ASSERT_EQ(track(&tracker, i).state, TrackingState::kOk);
  // Covered lens: no texture, no depth. Every such frame is lost (no evidence), from the first
  // one on, and none becomes a keyframe.
  dqo::Frame blank = frame(0);
  std::fill(blank.rgb.data.begin(), blank.rgb.data.end(), 128);
  std::fill(blank.depth.data.begin(), blank.depth.data.end(), 0.0f);
  double t = 1.0;
  TrackResult r;
  const size_t keyframes = tracker.num_keyframes();
  for (int i = 0; i < params.frames_to_lost; ++i) {
    r = track(&tracker, blank, t += 0.03);
    EXPECT_EQ(r.state, TrackingState::kLost) << "blank frame " << i;
    EXPECT_FALSE(r.new_keyframe);
    EXPECT_NE(r.quality.reasons & dqo::tracking::quality_reason::kNoEvidence, 0u);
  }
  EXPECT_EQ(tracker.num_keyframes(), keyframes);
  EXPECT_EQ(r.state, TrackingState::kLost);
  EXPECT_EQ(tracker.state(), TrackingState::kLost);
  r = track(&tracker, blank, t += 0.03);
  EXPECT_EQ(r.state, TrackingState::kLost);

  r = track(&tracker, frame(5), t += 0.03);
  EXPECT_EQ(r.state, TrackingState::kOk);
  EXPECT_TRUE(r.relocalised);
  EXPECT_LT(position_error(r.T_wc, truth(5)), 0.02);
  // And it keeps tracking from there.
  r = track(&tracker, frame(6), t += 0.03);
  EXPECT_EQ(r.state, TrackingState::kOk);
  EXPECT_LT(position_error(r.T_wc, truth(6)), 0.02);
}

TEST_F(TinyScene, BadInputIsSkipped) {
  Tracker tracker(camera(), tiny_params());
  RgbdInput none;
  EXPECT_EQ(tracker.track(none).state, TrackingState::kNotInitialised);
  dqo::ImageRgb8 small(10, 10, 3);
  dqo::DepthImage small_depth(10, 10, 1);
  RgbdInput wrong_size;
  wrong_size.rgb = &small;
  wrong_size.depth = &small_depth;
  EXPECT_EQ(tracker.track(wrong_size).state, TrackingState::kNotInitialised);
  ASSERT_EQ(track(&tracker, 0).state, TrackingState::kOk);
  EXPECT_EQ(tracker.track(wrong_size).state, TrackingState::kOk);  // skipped, state kept
  EXPECT_EQ(tracker.track(none).state, TrackingState::kOk);
  const TrackResult r = track(&tracker, 1);
  EXPECT_EQ(r.state, TrackingState::kOk);
  EXPECT_LT(position_error(r.T_wc, truth(1)), 0.01);
}

// The first second of `tabletop` (640x480, sensor noise on): each half of the fusion holds on
// its own, so neither hides a broken other.
class TabletopStart : public ::testing::Test {
 protected:
  static constexpr int kFrames = 30;
  static void SetUpTestSuite() {
    std::string error;
    scene_ = dqo::sim::load_scene(std::string(DQO_SOURCE_DIR) + "/config/scenes/tabletop.yaml",
                                  {}, &error)
                 .value();
    const dqo::sim::Renderer renderer(*scene_, 2);
    frames_ = std::make_unique<std::vector<dqo::Frame>>();
    for (int i = 0; i < kFrames; ++i) frames_->push_back(renderer.render(i, true));
  }
  static void TearDownTestSuite() {
    frames_.reset();
    scene_.reset();
  }

  // These tests compare runs with each other through tight ratios, so the local BA runs inside
  // track() (LocalBaParams::synchronous): its corrections enter at once, as the live worker's do
  // on an idle machine, but never later. With the worker they land whenever its thread finishes:
  // CI failed the asynchronous-depth test once, and corrections entering three frames late move
  // its told run from 0.25 to 0.34 cm (0.45 not told).
  static TrackerParams tabletop_params() {
    TrackerParams params;
    params.local_ba.synchronous = true;
    return params;
  }

  // RMS position error over the frames; every frame must be tracked.
  static double track_all(const TrackerParams& params) {
    Tracker tracker(scene_->camera, params);
    double sum = 0.0;
    for (const dqo::Frame& f : *frames_) {
      RgbdInput input;
      input.timestamp = f.timestamp;
      input.rgb = &f.rgb;
      input.depth = &f.depth;
      const TrackResult r = tracker.track(input);
      EXPECT_EQ(r.state, TrackingState::kOk) << "frame " << f.index;
      EXPECT_FALSE(r.predicted) << "frame " << f.index;
      if (r.state != TrackingState::kOk) return INFINITY;
      const SE3 truth = (*frames_)[0].T_wc.inverse() * f.T_wc;
      sum += (r.T_wc.translation() - truth.translation()).squaredNorm();
    }
    return std::sqrt(sum / kFrames);
  }

  static inline std::optional<dqo::sim::Scene> scene_;
  static inline std::unique_ptr<std::vector<dqo::Frame>> frames_;
};

TEST_F(TabletopStart, FeaturesAloneTrack) {
  TrackerParams params = tabletop_params();
  params.use_dense = false;
  EXPECT_LT(track_all(params), 0.01);
}

TEST_F(TabletopStart, DenseAloneTracks) {
  TrackerParams params = tabletop_params();
  params.use_features = false;
  EXPECT_LT(track_all(params), 0.01);
}

TEST_F(TabletopStart, FusedTracks) { EXPECT_LT(track_all(tabletop_params()), 0.005); }

// Depth captured a frame (33 ms) before the colour, as a Kinect v1's (TUM fr1: 15 ms by the
// stamps, more by the data): told so through depth_timestamp, the tracker keeps the pose at the
// colour image's instant; not told, the dense alignment pulls it towards the depth's.
TEST_F(TabletopStart, DepthCapturedBeforeTheColourKeepsTheColoursInstant) {
  auto run = [](bool tell) -> double {
    Tracker tracker(scene_->camera, tabletop_params());
    double sum = 0.0;
    for (int i = 0; i < kFrames; ++i) {
      const dqo::Frame& f = (*frames_)[i];
      const dqo::Frame& d = (*frames_)[std::max(0, i - 1)];
      RgbdInput input;
      input.timestamp = f.timestamp;
      input.rgb = &f.rgb;
      input.depth = &d.depth;
      if (tell && i > 0) input.depth_timestamp = d.timestamp;
      const TrackResult r = tracker.track(input);
      EXPECT_EQ(r.state, TrackingState::kOk) << "frame " << i << (tell ? " (told)" : "");
      if (!dqo::tracking::has_pose(r.state)) return INFINITY;
      const SE3 truth = (*frames_)[0].T_wc.inverse() * f.T_wc;
      sum += (r.T_wc.translation() - truth.translation()).squaredNorm();
    }
    return std::sqrt(sum / kFrames);
  };
  const double told = run(true);
  const double not_told = run(false);
  std::printf("asynchronous depth: RMS %.4f m told, %.4f m not told\n", told, not_told);
  EXPECT_LT(told, 0.01);
  EXPECT_LT(told, 0.8 * not_told);  // measured 0.25 against 0.46 cm
}

// A covered lens for 8 frames (a quarter second, the camera moving on), then the view again:
// every covered frame lost and no keyframe made, relocalised within a few frames, and no frame
// reported ok with a wrong pose.
TEST_F(TabletopStart, RelocalisesAfterACoveredLens) {
  Tracker tracker(scene_->camera, tabletop_params());
  const dqo::SE3 T_0 = (*frames_)[0].T_wc;
  dqo::Frame covered = (*frames_)[0];
  std::fill(covered.rgb.data.begin(), covered.rgb.data.end(), 0);
  std::fill(covered.depth.data.begin(), covered.depth.data.end(), 0.0f);
  int first_ok_after = -1;
  bool relocalised = false;
  for (int i = 0; i < kFrames; ++i) {
    const dqo::Frame& f = (*frames_)[i];
    const bool cover = i >= 10 && i < 18;
    RgbdInput input;
    input.timestamp = f.timestamp;
    input.rgb = cover ? &covered.rgb : &f.rgb;
    input.depth = cover ? &covered.depth : &f.depth;
    const size_t keyframes = tracker.num_keyframes();
    const TrackResult r = tracker.track(input);
    if (cover) {
      EXPECT_EQ(r.state, TrackingState::kLost) << "covered frame " << i;
      EXPECT_EQ(tracker.num_keyframes(), keyframes) << "covered frame " << i;
      continue;
    }
    relocalised = relocalised || r.relocalised;
    if (r.state == TrackingState::kOk) {
      const dqo::SE3 truth = T_0.inverse() * f.T_wc;
      EXPECT_LT((r.T_wc.translation() - truth.translation()).norm(), 0.02) << "frame " << i;
      if (i >= 18 && first_ok_after < 0) first_ok_after = i;
    }
  }
  EXPECT_TRUE(relocalised);
  ASSERT_GE(first_ok_after, 18) << "never ok again after the cover";
  EXPECT_LE(first_ok_after, 22);
}

// After the covered lens the relocalised pose carries the features' error (~1 cm on this scene)
// and the dense alignment that follows chains from it. Aligned again to the last good frame before
// the cover, from the relocalised pose (TrackerParams::realign_dense), the frames after it are as
// accurate as the fault-free run's.
TEST_F(TabletopStart, RealignedAfterACoveredLensAsAccurateAsWithout) {
  dqo::Frame covered = (*frames_)[0];
  std::fill(covered.rgb.data.begin(), covered.rgb.data.end(), 0);
  std::fill(covered.depth.data.begin(), covered.depth.data.end(), 0.0f);
  // RMS position error over the frames after the cover (all must have a pose).
  auto after_cover = [&](bool realign, bool cover) -> double {
    TrackerParams params = tabletop_params();
    params.realign_dense = realign;
    Tracker tracker(scene_->camera, params);
    double sum = 0.0;
    int n = 0;
    for (int i = 0; i < kFrames; ++i) {
      const dqo::Frame& f = (*frames_)[i];
      const bool hidden = cover && i >= 10 && i < 18;
      RgbdInput input;
      input.timestamp = f.timestamp;
      input.rgb = hidden ? &covered.rgb : &f.rgb;
      input.depth = hidden ? &covered.depth : &f.depth;
      const TrackResult r = tracker.track(input);
      if (i < 18) continue;
      EXPECT_TRUE(dqo::tracking::has_pose(r.state)) << "frame " << i;
      if (!dqo::tracking::has_pose(r.state)) return INFINITY;
      const SE3 truth = (*frames_)[0].T_wc.inverse() * f.T_wc;
      sum += (r.T_wc.translation() - truth.translation()).squaredNorm();
      ++n;
    }
    return std::sqrt(sum / n);
  };
  const double realigned = after_cover(true, true);
  const double chained = after_cover(false, true);
  const double fault_free = after_cover(true, false);
  std::printf("after a covered lens: RMS %.4f m realigned, %.4f m not, %.4f m fault-free\n",
              realigned, chained, fault_free);
  EXPECT_LT(realigned, 2.0 * fault_free + 0.0005);
  EXPECT_LT(realigned, 0.5 * chained);
}

}  // namespace
