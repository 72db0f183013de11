// The per-frame states file (dqo_track --states): its lines read back to what the tracker said,
// and on a real clip the frame whose pose is centimetres off is not among the ok ones.
#include <cmath>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "dqo_map/io/dataset_reader.h"
#include "dqo_map/tracking/frame_states.h"
#include "dqo_map/tracking/rectified_frame_source.h"
#include "dqo_map/tracking/tracker.h"

namespace {

using dqo::tracking::format_frame_state;
using dqo::tracking::parse_frame_state;
using dqo::tracking::TrackingState;
using dqo::tracking::TrackResult;
namespace reason = dqo::tracking::quality_reason;

TEST(FrameStates, ALineReadsBackAsWritten) {
  TrackResult r;
  r.state = TrackingState::kDegraded;
  r.relocalised = true;
  r.quality.inliers = 231;
  r.quality.depth_inliers = 200;
  r.quality.spread = 0.875;
  r.quality.dense_ok = false;
  r.quality.dense_rms = 1.9;
  r.quality.dense_inlier_ratio = 0.54;
  r.quality.disagreement_m = 0.012;
  r.quality.disagreement_deg = 0.25;
  r.quality.reasons = reason::kDenseFailed | reason::kPoorSpread;
  const std::string line = format_frame_state(1305031465.0957, r);
  const auto back = parse_frame_state(line);
  ASSERT_TRUE(back) << line;
  EXPECT_NEAR(back->timestamp, 1305031465.0957, 1e-6);
  EXPECT_EQ(back->state, TrackingState::kDegraded);
  EXPECT_EQ(back->reasons, "poor_spread+dense_failed");
  EXPECT_EQ(back->quality.inliers, 231);
  EXPECT_EQ(back->quality.depth_inliers, 200);
  EXPECT_NEAR(back->quality.spread, 0.875, 1e-4);
  EXPECT_FALSE(back->quality.dense_ok);
  EXPECT_NEAR(back->quality.dense_rms, 1.9, 1e-4);
  EXPECT_NEAR(back->quality.disagreement_m, 0.012, 1e-5);
  EXPECT_TRUE(back->relocalised);

  r = TrackResult{};
  r.state = TrackingState::kOk;
  const auto ok = parse_frame_state(format_frame_state(2.5, r));
  ASSERT_TRUE(ok);
  EXPECT_EQ(ok->state, TrackingState::kOk);
  EXPECT_EQ(ok->reasons, "");
}

TEST(FrameStates, CommentsAndMalformedLinesAreNotRead) {
  EXPECT_FALSE(parse_frame_state(dqo::tracking::frame_states_header()));
  EXPECT_FALSE(parse_frame_state(""));
  EXPECT_FALSE(parse_frame_state("1.0 ok - 10 10 0.5 1 1.0 0.5 0.01"));  // columns missing
  EXPECT_FALSE(parse_frame_state("1.0 fine - 10 10 0.5 1 1.0 0.5 0.01 0.1 0"));  // no such state
  EXPECT_FALSE(parse_frame_state("1.0 ok - 10 10 0.5 1 1.0 0.5 0.01 0.1 0 extra"));
}

// fr1/desk frames 30-45 (TUM's, ../shared/data/tum_fr1_desk_330): frame 39 is motion-blurred;
// the features alone put it 3-4.5 cm off its neighbours with 231 inliers over the whole image.
class DeskClip : public ::testing::Test {
 protected:
  void SetUp() override {
    std::error_code ec;
    const std::filesystem::path source = std::filesystem::canonical(DQO_SOURCE_DIR, ec);
    const std::string dir = (source / "../shared/data/tum_fr1_desk_330").lexically_normal();
    if (!std::filesystem::exists(dir + "/rgb.txt"))
      GTEST_SKIP() << "real data not found at " << dir << " (../shared/data/tum_fr1_desk_330)";
    std::string error;
    dqo::DatasetReaderParams params;
    params.load_meshes = false;
    params.tum.camera_file = std::string(DQO_SOURCE_DIR) + "/config/cameras/tum_fr1.yaml";
    const std::shared_ptr<const dqo::FrameSource> reader = dqo::open_dataset(dir, params, &error);
    ASSERT_TRUE(reader) << error;
    const auto source_frames = dqo::tracking::rectified(reader, &error);
    ASSERT_TRUE(source_frames) << error;
    camera_ = source_frames->info().camera;
    source_ = source_frames;
    load(30, 45, 1);
  }

  void load(int first, int last, int step) {
    frames_.clear();
    std::string error;
    for (int i = first; i <= last && i < source_->num_frames(); i += step) {
      auto f = source_->read_frame(i, &error);
      ASSERT_TRUE(f) << error;
      frames_.push_back(std::move(*f));
    }
  }

  std::vector<TrackResult> track(const dqo::tracking::TrackerParams& base) {
    dqo::tracking::TrackerParams params = base;
    params.local_ba.deterministic = true;
    dqo::tracking::Tracker tracker(camera_, params);
    std::vector<TrackResult> out;
    for (const dqo::Frame& f : frames_) {
      out.push_back(tracker.track({f.timestamp, &f.rgb, &f.depth, f.depth_timestamp}));
    }
    tracker.wait_for_mapping();
    return out;
  }

  std::shared_ptr<const dqo::FrameSource> source_;
  dqo::PinholeCamera camera_;
  std::vector<dqo::Frame> frames_;
};

TEST_F(DeskClip, TheBlurredFrameIsNotOkAndTheStatesFileSaysWhatTheTrackerSaid) {
  const std::vector<TrackResult> results = track({});
  ASSERT_EQ(results.size(), frames_.size());
  const TrackResult& blurred = results[39 - 30];
  EXPECT_TRUE(dqo::tracking::has_pose(blurred.state));
  EXPECT_NE(blurred.state, TrackingState::kOk) << "a pose 3-4.5 cm off its neighbours reported ok";
  // Dense alignment from the features' pose failed to fit, or fitted 3-4 cm away from them.
  EXPECT_NE(blurred.quality.reasons & (reason::kDenseFailed | reason::kDisagreement), 0u)
      << dqo::tracking::reasons_to_string(blurred.quality.reasons);
  // Its step from the frame before against the ground truth's: the reason it must not be ok.
  const dqo::SE3 step = results[8].T_wc.inverse() * blurred.T_wc;
  const dqo::SE3 step_gt = frames_[8].T_wc.inverse() * frames_[9].T_wc;
  EXPECT_GT((step.translation() - step_gt.translation()).norm(), 0.02);

  for (size_t i = 0; i < results.size(); ++i) {
    const auto line = parse_frame_state(format_frame_state(frames_[i].timestamp, results[i]));
    ASSERT_TRUE(line);
    EXPECT_EQ(line->state, results[i].state) << "frame " << 30 + i;
    EXPECT_EQ(line->reasons, dqo::tracking::reasons_to_string(results[i].quality.reasons));
    EXPECT_EQ(line->quality.inliers, results[i].quality.inliers);
  }

  // Without the check the same pose is reported ok: the test above can fail.
  dqo::tracking::TrackerParams unchecked;
  unchecked.quality.confirm_features = false;
  EXPECT_EQ(track(unchecked)[39 - 30].state, TrackingState::kOk);
}

TEST_F(DeskClip, EveryTenthFrameIsPosedWithKeyframesByDistance) {
  // 15-30 cm and 5-24 degrees between frames: the map must keep up with the view.
  load(0, 149, 10);
  ASSERT_EQ(frames_.size(), 15u);
  auto posed = [](const std::vector<TrackResult>& results) {
    int n = 0;
    for (const TrackResult& r : results) n += dqo::tracking::has_pose(r.state);
    return n;
  };
  const std::vector<TrackResult> results = track({});
  EXPECT_GE(posed(results), 14);
  // Between two frames reported ok, the step within 5 cm of the ground truth's. (Frame 40, after
  // the largest turn, 24 degrees, is 5.4 cm off; it is reported degraded.)
  int ok_steps = 0;
  for (size_t i = 1; i < results.size(); ++i) {
    if (results[i].state != TrackingState::kOk || results[i - 1].state != TrackingState::kOk)
      continue;
    ++ok_steps;
    const dqo::SE3 step = results[i - 1].T_wc.inverse() * results[i].T_wc;
    const dqo::SE3 step_gt = frames_[i - 1].T_wc.inverse() * frames_[i].T_wc;
    EXPECT_LT((step.translation() - step_gt.translation()).norm(), 0.05) << "frame " << 10 * i;
  }
  EXPECT_GE(ok_steps, 3);
  // Keyframes only when mapping is idle (by frames, not metres), as before: most frames lost.
  dqo::tracking::TrackerParams by_frames;
  by_frames.keyframes.far_translation_m = 1e9;
  by_frames.keyframes.far_rotation_deg = 180.0;
  EXPECT_LT(posed(track(by_frames)), 10);
}

}  // namespace
