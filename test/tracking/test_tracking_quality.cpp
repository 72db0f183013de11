// The per-frame quality rules (ok / degraded / lost and why) on constructed evidence: every
// combination of what the features and the dense alignment said that the tracker meets.
#include <vector>

#include <gtest/gtest.h>

#include "tracking_quality.h"

namespace {

using dqo::tracking::assess_quality;
using dqo::tracking::QualityEvidence;
using dqo::tracking::QualityParams;
using dqo::tracking::TrackingState;
namespace reason = dqo::tracking::quality_reason;

// Strong features (200 inliers over the whole image), dense converged with a good fit, both
// agreeing to a millimetre.
QualityEvidence good() {
  QualityEvidence e;
  e.inliers = 200;
  e.depth_inliers = 180;
  e.spread = 0.9;
  e.dense_tried = true;
  e.dense_ok = true;
  e.dense_rms = 0.8;
  e.dense_inlier_ratio = 0.8;
  e.compared = true;
  e.disagreement_m = 0.001;
  e.disagreement_deg = 0.05;
  return e;
}

TEST(TrackingQuality, AgreeingSourcesAreOk) {
  const auto v = assess_quality(good(), QualityParams{});
  EXPECT_EQ(v.state, TrackingState::kOk);
  EXPECT_EQ(v.quality.reasons, 0u);
  EXPECT_EQ(v.quality.inliers, 200);
}

TEST(TrackingQuality, StrongFeaturesAreOkWhereDenseFailedToConverge) {
  QualityEvidence e = good();
  e.dense_ok = false;  // a step beyond its basin: no evidence against the features
  e.compared = false;
  EXPECT_EQ(assess_quality(e, QualityParams{}).state, TrackingState::kOk);
}

TEST(TrackingQuality, FeaturesThatDenseFromTheirOwnPoseCannotFitAreDegraded) {
  // The motion-blurred frames of fr1/desk: 231 inliers over the image, dense alignment started
  // at the features' pose ends at a whitened RMS of 1.9 (failed).
  QualityEvidence e = good();
  e.compared = false;
  e.dense_ok = false;
  e.dense_rms = 1.9;
  e.dense_from_features = true;
  auto v = assess_quality(e, QualityParams{});
  EXPECT_EQ(v.state, TrackingState::kDegraded);
  EXPECT_EQ(v.quality.reasons, reason::kDenseFailed);
  // The same failure from the motion model's guess says nothing about the features.
  e.dense_from_features = false;
  EXPECT_EQ(assess_quality(e, QualityParams{}).state, TrackingState::kOk);
  // Switched off: the features holding suffice.
  e.dense_from_features = true;
  QualityParams off;
  off.confirm_features = false;
  EXPECT_EQ(assess_quality(e, off).state, TrackingState::kOk);
  // Confirmed: ok, with the check's looser fit (fast steps fit worse whatever the pose)...
  e = good();
  e.dense_from_features = true;
  e.dense_rms = 1.9;
  EXPECT_EQ(assess_quality(e, QualityParams{}).state, TrackingState::kOk);
  // ... but its tighter agreement: frame 39 of fr1/desk, 4 cm from the features' pose.
  e.disagreement_m = 0.04;
  v = assess_quality(e, QualityParams{});
  EXPECT_EQ(v.state, TrackingState::kDegraded);
  EXPECT_EQ(v.quality.reasons, reason::kDisagreement);
  e.disagreement_m = 0.01;
  e.disagreement_deg = 2.0;
  EXPECT_EQ(assess_quality(e, QualityParams{}).state, TrackingState::kDegraded);
  // The same fit from the motion model's guess is too poor to count (dense_max_rms 1.5), and then
  // no evidence against the features either.
  e = good();
  e.dense_rms = 1.9;
  e.disagreement_m = 0.04;
  EXPECT_EQ(assess_quality(e, QualityParams{}).state, TrackingState::kDegraded);
  e.disagreement_m = 0.01;
  EXPECT_EQ(assess_quality(e, QualityParams{}).state, TrackingState::kOk);
}

TEST(TrackingQuality, DisagreementDegradesStrongFeaturesAndLosesWeakOnes) {
  QualityEvidence e = good();
  e.disagreement_m = 0.10;  // 10 cm apart
  auto v = assess_quality(e, QualityParams{});
  EXPECT_EQ(v.state, TrackingState::kDegraded);
  EXPECT_EQ(v.quality.reasons, reason::kDisagreement);

  e.disagreement_m = 0.001;
  e.disagreement_deg = 5.0;  // rotation alone disagrees
  EXPECT_EQ(assess_quality(e, QualityParams{}).state, TrackingState::kDegraded);

  e.inliers = 25;  // features too few to be believed over the dense pose
  e.depth_inliers = 25;
  v = assess_quality(e, QualityParams{});
  EXPECT_EQ(v.state, TrackingState::kLost);
  EXPECT_EQ(v.quality.reasons, reason::kDisagreement | reason::kFewInliers);
}

TEST(TrackingQuality, DenseAloneIsNeverOk) {
  // A low-texture view: no feature inliers, dense converged well. It can still be a wrong
  // translation with the right rotation (issue 14): degraded at best.
  QualityEvidence e = good();
  e.inliers = 0;
  e.depth_inliers = 0;
  e.spread = 0.0;
  e.compared = false;
  auto v = assess_quality(e, QualityParams{});
  EXPECT_EQ(v.state, TrackingState::kDegraded);
  EXPECT_EQ(v.quality.reasons, reason::kFewInliers | reason::kPoorSpread | reason::kNoDepth);

  e.dense_rms = 3.0;  // and with a poor fit nothing supports the pose
  v = assess_quality(e, QualityParams{});
  EXPECT_EQ(v.state, TrackingState::kLost);
  EXPECT_NE(v.quality.reasons & reason::kDenseResidual, 0u);

  e.dense_rms = 0.8;
  e.dense_inlier_ratio = 0.1;  // a fit over a tenth of the points
  EXPECT_EQ(assess_quality(e, QualityParams{}).state, TrackingState::kLost);
}

TEST(TrackingQuality, DenseAloneByConfigurationIsOkWhenItHolds) {
  QualityEvidence e = good();
  e.use_features = false;
  e.inliers = 0;
  e.spread = 0.0;
  e.compared = false;
  EXPECT_EQ(assess_quality(e, QualityParams{}).state, TrackingState::kOk);
  e.dense_ok = false;
  EXPECT_EQ(assess_quality(e, QualityParams{}).state, TrackingState::kLost);
}

TEST(TrackingQuality, BunchedOrFewInliersAreDegraded) {
  QualityEvidence e = good();
  e.spread = 1.0 / 16.0;  // every inlier in one corner
  e.dense_ok = false;
  e.compared = false;
  auto v = assess_quality(e, QualityParams{});
  EXPECT_EQ(v.state, TrackingState::kDegraded);
  EXPECT_EQ(v.quality.reasons, reason::kPoorSpread | reason::kDenseFailed);

  e.spread = 0.9;
  e.inliers = 20;  // above min_inliers (15), below ok_inliers (50)
  e.depth_inliers = 20;
  EXPECT_EQ(assess_quality(e, QualityParams{}).state, TrackingState::kDegraded);
  e.inliers = 10;  // below min_inliers and no dense: nothing holds
  e.depth_inliers = 10;
  EXPECT_EQ(assess_quality(e, QualityParams{}).state, TrackingState::kLost);
}

TEST(TrackingQuality, FeaturesWithoutDepthAreDegraded) {
  // Depth dropped: the features still match the map by reprojection alone (a monocular pose)
  // and dense alignment has nothing to align.
  QualityEvidence e = good();
  e.depth_inliers = 3;
  e.dense_ok = false;
  e.compared = false;
  const auto v = assess_quality(e, QualityParams{});
  EXPECT_EQ(v.state, TrackingState::kDegraded);
  EXPECT_EQ(v.quality.reasons, reason::kNoDepth | reason::kDenseFailed);
}

TEST(TrackingQuality, APredictionIsLost) {
  QualityEvidence e;
  e.predicted = true;
  const auto v = assess_quality(e, QualityParams{});
  EXPECT_EQ(v.state, TrackingState::kLost);
  EXPECT_EQ(v.quality.reasons, reason::kNoEvidence);
}

TEST(TrackingQuality, RelocalisationIsJudgedOnTheFeatures) {
  // Dense alignment does not run when relocalising: its absence is no reason.
  QualityEvidence e;
  e.inliers = 120;
  e.depth_inliers = 100;
  e.spread = 0.6;
  auto v = assess_quality(e, QualityParams{});
  EXPECT_EQ(v.state, TrackingState::kOk);
  e.inliers = 35;
  e.depth_inliers = 30;
  v = assess_quality(e, QualityParams{});
  EXPECT_EQ(v.state, TrackingState::kDegraded);
  EXPECT_EQ(v.quality.reasons, reason::kFewInliers);
}

TEST(TrackingQuality, ReasonsReadAsWords) {
  EXPECT_EQ(dqo::tracking::reasons_to_string(0), "");
  EXPECT_EQ(dqo::tracking::reasons_to_string(reason::kFewInliers | reason::kDisagreement),
            "few_inliers+features_dense_disagree");
}

TEST(InlierSpread, CountsTheCellsOfA4x4Grid) {
  dqo::PinholeCamera camera;
  camera.width = 640;
  camera.height = 480;
  std::vector<Eigen::Vector2f> corner = {{10, 10}, {100, 50}, {150, 110}, {-5, 3}, {700, 10}};
  EXPECT_DOUBLE_EQ(dqo::tracking::inlier_spread(corner, camera), 1.0 / 16.0);  // outside: ignored
  std::vector<Eigen::Vector2f> grid;
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 4; ++x) grid.emplace_back(80.0f + 160.0f * x, 60.0f + 120.0f * y);
  EXPECT_DOUBLE_EQ(dqo::tracking::inlier_spread(grid, camera), 1.0);
  EXPECT_DOUBLE_EQ(dqo::tracking::inlier_spread({}, camera), 0.0);
}

}  // namespace
