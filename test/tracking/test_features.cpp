// The feature side of the tracker: ORB extraction (spread, pyramid, depth, rotation invariance),
// the keypoint grid, matching (projection search, descriptor matching, orientation filter), the
// ID-keyed map store, PnP against a keyframe on a camera rolled about its optical axis, and the
// rolling-shutter compensation of keypoints against a rolling shutter simulated here.
#include <algorithm>
#include <cmath>
#include <random>
#include <set>

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "map_store.h"
#include "matching.h"
#include "orb_frame.h"
#include "relocaliser.h"
#include "rolling_shutter.h"

namespace {

using dqo::DepthImage;
using dqo::PinholeCamera;
using dqo::SE3;
using namespace dqo::tracking;

PinholeCamera test_camera() { return PinholeCamera{525.0, 525.0, 319.5, 239.5, 640, 480}; }

// Blurred noise at two scales: corners everywhere, at every pyramid level.
cv::Mat textured_image(unsigned seed) {
  cv::RNG rng(seed);
  cv::Mat fine(480, 640, CV_8U), coarse(60, 80, CV_8U);
  rng.fill(fine, cv::RNG::UNIFORM, 0, 255);
  rng.fill(coarse, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(fine, fine, cv::Size(0, 0), 1.5);
  cv::resize(coarse, coarse, fine.size(), 0, 0, cv::INTER_CUBIC);
  cv::Mat out;
  cv::addWeighted(fine, 1.5, coarse, 0.6, -100.0, out);
  return out;
}

// A non-planar surface 1.6-2.4 m away.
DepthImage bumpy_depth() {
  DepthImage d(640, 480, 1, 0.0f);
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 640; ++x)
      d.at(x, y) = static_cast<float>(2.0 + 0.3 * std::sin(x / 45.0) * std::cos(y / 55.0) +
                                      0.1 * std::sin((x + y) / 70.0));
  return d;
}

cv::Mat as_mat(const DepthImage& d) {
  return cv::Mat(d.height, d.width, CV_32F, const_cast<float*>(d.data.data())).clone();
}
DepthImage from_mat(const cv::Mat& m) {
  DepthImage d(m.cols, m.rows, 1, 0.0f);
  for (int y = 0; y < m.rows; ++y)
    for (int x = 0; x < m.cols; ++x) d.at(x, y) = m.at<float>(y, x);
  return d;
}

// The image a camera rolled by `deg` about its optical axis sees (T_wB = T_wA R_z(deg)), with its
// depth (a roll keeps z).
void roll(const cv::Mat& grey, const DepthImage& depth, double deg, cv::Mat* grey_out,
          DepthImage* depth_out) {
  const PinholeCamera c = test_camera();
  const cv::Mat M = cv::getRotationMatrix2D(cv::Point2f(c.cx, c.cy), deg, 1.0);
  cv::warpAffine(grey, *grey_out, M, grey.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
  cv::Mat d;
  cv::warpAffine(as_mat(depth), d, M, grey.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, 0.0);
  *depth_out = from_mat(d);
}

TEST(OrbExtractor, SpreadsKeypointsOverImageAndPyramid) {
  OrbParams params;
  OrbExtractor extractor(params);
  DepthImage depth(640, 480, 1, 2.0f);
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 320; ++x) depth.at(x, y) = 0.0f;  // no depth on the left half
  OrbFrame frame;
  extractor.extract_grey(textured_image(1), &depth, &frame);
  ASSERT_EQ(frame.keypoints.size(), frame.descriptors.size());
  EXPECT_GE(frame.size(), 0.8 * params.num_features);
  EXPECT_LE(frame.size(), static_cast<size_t>(params.num_features) + 8);

  std::set<int> levels, blocks;
  for (const Keypoint& k : frame.keypoints) {
    levels.insert(k.octave);
    EXPECT_GE(k.uv.x(), 0.0f);
    EXPECT_LT(k.uv.x(), 640.0f);
    EXPECT_GE(k.uv.y(), 0.0f);
    EXPECT_LT(k.uv.y(), 480.0f);
    EXPECT_GE(k.angle, 0.0f);
    EXPECT_LT(k.angle, 360.0f);
    blocks.insert(static_cast<int>(k.uv.y() / 60) * 8 + static_cast<int>(k.uv.x() / 80));
    if (k.uv.x() < 318.0f) {
      EXPECT_EQ(k.depth, 0.0f);
    } else if (k.uv.x() > 321.0f) {
      EXPECT_FLOAT_EQ(k.depth, 2.0f);
    }
  }
  EXPECT_GE(levels.size(), 6u);
  EXPECT_EQ(blocks.size(), 64u);  // every 80x60 block of the image has keypoints
}

TEST(OrbExtractor, DescriptorsSurviveARollOfTheCamera) {
  OrbExtractor extractor(OrbParams{});
  const cv::Mat a = textured_image(2);
  cv::Mat b;
  DepthImage depth_b;
  roll(a, bumpy_depth(), 30.0, &b, &depth_b);
  OrbFrame fa, fb;
  extractor.extract_grey(a, nullptr, &fa);
  extractor.extract_grey(b, nullptr, &fb);
  const auto matches = match_descriptors(fb.descriptors, fa.descriptors, 0.8f, 64);
  // Where each match should land: the roll's image rotation.
  const PinholeCamera c = test_camera();
  const double t = 30.0 * M_PI / 180.0;
  int right = 0;
  for (const auto& [ib, ia] : matches) {
    const Eigen::Vector2f d = fa.keypoints[ia].uv - Eigen::Vector2f(c.cx, c.cy);
    const Eigen::Vector2f expected(static_cast<float>(std::cos(t) * d.x() + std::sin(t) * d.y()),
                                   static_cast<float>(-std::sin(t) * d.x() + std::cos(t) * d.y()));
    const float tolerance = 2.0f * extractor.scales().scale[fa.keypoints[ia].octave];
    right += (fb.keypoints[ib].uv - Eigen::Vector2f(c.cx, c.cy) - expected).norm() < tolerance;
  }
  EXPECT_GE(right, 200);
  EXPECT_GE(right, 0.9 * matches.size());
}

TEST(KeypointGrid, WindowQueryEqualsBruteForce) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<Keypoint> keypoints(500);
  for (Keypoint& k : keypoints) {
    k.uv = Eigen::Vector2f(640.0f * u(rng), 480.0f * u(rng));
    k.octave = static_cast<int>(8 * u(rng));
  }
  KeypointGrid grid;
  grid.build(keypoints, 640, 480, 16);
  std::vector<int> got;
  for (int trial = 0; trial < 50; ++trial) {
    const Eigen::Vector2f centre(640.0f * u(rng), 480.0f * u(rng));
    const float radius = 3.0f + 40.0f * u(rng);
    const int lo = trial % 4, hi = trial % 3 == 0 ? -1 : lo + 2;
    grid.query(keypoints, centre, radius, lo, hi, &got);
    std::vector<int> expected;
    for (size_t i = 0; i < keypoints.size(); ++i) {
      const Keypoint& k = keypoints[i];
      if (k.octave >= lo && (hi < 0 || k.octave <= hi) &&
          std::abs(k.uv.x() - centre.x()) <= radius && std::abs(k.uv.y() - centre.y()) <= radius)
        expected.push_back(static_cast<int>(i));
    }
    std::sort(got.begin(), got.end());
    EXPECT_EQ(got, expected);
  }
}

TEST(Matching, HammingCountsBits) {
  Descriptor a{}, b{};
  EXPECT_EQ(hamming(a, b), 0);
  b[0] = 0xFF;
  b[3] = 1ull << 63;
  EXPECT_EQ(hamming(a, b), 9);
}

TEST(Matching, OrientationFilterKeepsTheDominantRotation) {
  std::vector<float> rotation;
  for (int i = 0; i < 50; ++i) rotation.push_back(30.0f + (i % 5) * 0.5f);  // consistent
  for (int i = 0; i < 10; ++i) rotation.push_back(36.0f * i);               // scattered
  rotation.push_back(-1.0f);                                                  // no angle
  std::vector<char> keep;
  orientation_filter(rotation, &keep);
  for (int i = 0; i < 50; ++i) EXPECT_TRUE(keep[i]);
  int scattered_kept = 0;
  for (int i = 50; i < 60; ++i) scattered_kept += keep[i];
  EXPECT_LE(scattered_kept, 3);
  EXPECT_TRUE(keep[60]);
}

TEST(Matching, ProjectionSearchFindsPointsFromAPoseGuess) {
  // The frame's own keypoints back-projected are found again from a guess 5 mm off.
  const PinholeCamera camera = test_camera();
  OrbExtractor extractor(OrbParams{});
  const DepthImage depth = bumpy_depth();
  OrbFrame frame;
  extractor.extract_grey(textured_image(3), &depth, &frame);
  std::vector<ProjectionCandidate> candidates;
  for (size_t k = 0; k < frame.size(); ++k) {
    ProjectionCandidate c;
    c.map_point = k + 1;
    c.p_w = frame.point_c(static_cast<int>(k), camera);
    c.descriptor = frame.descriptors[k];
    c.level = frame.keypoints[k].octave;
    c.angle = frame.keypoints[k].angle;
    candidates.push_back(c);
  }
  const SE3 guess(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.005, -0.003, 0.0));
  ProjectionSearch search;
  const std::vector<Match> matches = search_by_projection(
      frame, camera, extractor.scales(), guess, candidates, search, nullptr, nullptr);
  int right = 0;
  for (const Match& m : matches) right += static_cast<size_t>(m.keypoint) == candidates[m.candidate].map_point - 1;
  EXPECT_GE(right, 0.9 * frame.size());
  EXPECT_GE(right, 0.98 * matches.size());
}

TEST(MapStore, ObservationsErasureAndCovisibility) {
  MapStore map;
  auto make_kf = [](int n) {
    KeyFrame kf;
    kf.features.keypoints.resize(n);
    kf.features.descriptors.resize(n);
    kf.map_points.assign(n, kNoId);
    return kf;
  };
  const uint64_t a = map.add_keyframe(make_kf(40));
  const uint64_t b = map.add_keyframe(make_kf(40));
  const uint64_t c = map.add_keyframe(make_kf(40));
  std::vector<uint64_t> points;
  for (int i = 0; i < 30; ++i) {
    const uint64_t p = map.add_map_point(MapPoint{});
    points.push_back(p);
    map.add_observation(p, a, i);
    if (i < 20) map.add_observation(p, b, i);
    if (i < 16) map.add_observation(p, c, i + 10);
  }
  for (const uint64_t kf : {a, b, c}) map.update_covisibility(kf);
  EXPECT_EQ(map.keyframe(a)->covisibility.at(b), 20);
  EXPECT_EQ(map.keyframe(b)->covisibility.at(a), 20);
  EXPECT_EQ(map.keyframe(c)->covisibility.at(a), 16);
  EXPECT_EQ(map.covisible(a, 1), std::vector<uint64_t>{b});
  EXPECT_EQ(map.tracked_points(a, 2), 20);

  // Erasing a point unlinks it everywhere; losing the last observation erases the point.
  map.erase_map_point(points[0]);
  EXPECT_EQ(map.map_point(points[0]), nullptr);
  EXPECT_EQ(map.keyframe(a)->map_points[0], kNoId);
  EXPECT_EQ(map.keyframe(b)->map_points[0], kNoId);
  map.erase_observation(points[25], a);
  EXPECT_EQ(map.map_point(points[25]), nullptr);
  map.erase_observation(points[5], a);  // seen by a, b and c
  ASSERT_NE(map.map_point(points[5]), nullptr);
  EXPECT_EQ(map.map_point(points[5])->observations.size(), 2u);
  EXPECT_EQ(map.map_point(points[5])->observation_of(a), -1);

  // A second keypoint of the same keyframe replaces the first.
  map.add_observation(points[6], a, 35);
  EXPECT_EQ(map.keyframe(a)->map_points[6], kNoId);
  EXPECT_EQ(map.keyframe(a)->map_points[35], points[6]);
  EXPECT_EQ(map.map_point(points[6])->observation_of(a), 35);

  map.clear();
  EXPECT_EQ(map.num_keyframes(), 0u);
  EXPECT_EQ(map.num_map_points(), 0u);
  EXPECT_EQ(map.add_keyframe(make_kf(1)), 1u);
}

TEST(MapStore, DistinctiveDescriptorIsTheMedianOne) {
  MapStore map;
  ScalePyramid scales(1.2f, 8);
  const Descriptor centre{0x0F0F, 0, 0, 0};
  std::vector<uint64_t> kfs;
  MapPoint point;
  point.p_w = Eigen::Vector3d(0, 0, 2);
  const uint64_t p = map.add_map_point(point);
  for (int i = 0; i < 5; ++i) {
    KeyFrame kf;
    kf.T_wc = SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.1 * i, 0, 0));
    kf.features.keypoints.resize(1);
    kf.features.keypoints[0].octave = 1;
    Descriptor d = centre;
    if (i > 0) d[1] = 1ull << i;  // one bit away from the centre, two from each other
    if (i == 4) d[2] = ~0ull;     // far from everything
    kf.features.descriptors = {d};
    kf.map_points = {kNoId};
    const uint64_t id = map.add_keyframe(std::move(kf));
    map.add_observation(p, id, 0);
  }
  map.map_point(p)->first_keyframe = 1;
  map.update_point_appearance(p, scales);
  const MapPoint* mp = map.map_point(p);
  EXPECT_EQ(mp->descriptor, centre);
  EXPECT_NEAR(mp->max_distance, 2.0 * 1.2, 1e-5);
  EXPECT_GT(mp->normal.z(), 0.9);
}

TEST(Relocaliser, PnpRecoversARolledCamera) {
  const PinholeCamera camera = test_camera();
  OrbExtractor extractor(OrbParams{});
  const cv::Mat grey_a = textured_image(5);
  const DepthImage depth_a = bumpy_depth();
  cv::Mat grey_b;
  DepthImage depth_b;
  const double roll_deg = 12.0;
  roll(grey_a, depth_a, roll_deg, &grey_b, &depth_b);

  // A keyframe at the origin whose keypoints with depth are map points.
  MapStore map;
  KeyFrame kf;
  extractor.extract_grey(grey_a, &depth_a, &kf.features);
  kf.map_points.assign(kf.features.size(), kNoId);
  const uint64_t kf_id = map.add_keyframe(std::move(kf));
  const KeyFrame& stored = *map.keyframe(kf_id);
  for (size_t k = 0; k < stored.features.size(); ++k) {
    if (!stored.features.has_depth(static_cast<int>(k))) continue;
    MapPoint p;
    p.p_w = stored.features.point_c(static_cast<int>(k), camera);
    p.descriptor = stored.features.descriptors[k];
    const uint64_t id = map.add_map_point(p);
    map.add_observation(id, kf_id, static_cast<int>(k));
  }

  OrbFrame frame;
  extractor.extract_grey(grey_b, &depth_b, &frame);
  const SE3 expected = SE3(Eigen::Quaterniond(Eigen::AngleAxisd(roll_deg * M_PI / 180.0,
                                                                Eigen::Vector3d::UnitZ())),
                           Eigen::Vector3d::Zero());
  for (const bool through_relocalise : {false, true}) {
    const PnpResult r =
        through_relocalise
            ? relocalise(frame, map, {kf_id}, camera, extractor.scales(), {}, RelocParams{})
            : pnp_against_keyframe(frame, *map.keyframe(kf_id), map, camera, extractor.scales(),
                                   {}, 30);
    ASSERT_TRUE(r.ok);
    EXPECT_EQ(r.keyframe, kf_id);
    EXPECT_GE(r.matches.size(), 100u);
    EXPECT_LT(r.T_wc.translation().norm(), 0.01);
    const double w = std::min(1.0, std::abs((expected.inverse() * r.T_wc).quaternion().w()));
    EXPECT_LT(2.0 * std::acos(w) * 180.0 / M_PI, 0.3);
  }
}

// ---------------------------------------------------------------- rolling shutter

using Twist = Eigen::Matrix<double, 6, 1>;

// Where a rolling shutter sees p_w: on the row v whose own instant, (v - H/2) / H * readout after
// the stamp, has the camera (moving with the body twist from T_wc at the stamp) project p_w onto
// row v itself: a fixed point, found by iterating. Also the point's depth in that row's camera.
struct RowObservation {
  Eigen::Vector2d uv;
  double z;
};
RowObservation observe_rolling(const PinholeCamera& c, const SE3& T_wc, const Twist& twist,
                               double readout, const Eigen::Vector3d& p_w) {
  double v = c.cy;
  Eigen::Vector3d p = T_wc.inverse() * p_w;
  for (int i = 0; i < 100; ++i) {
    const double t = (v - 0.5 * c.height) / c.height * readout;
    p = (T_wc * SE3::exp(t * twist)).inverse() * p_w;
    v = c.fy * p.y() / p.z() + c.cy;
  }
  return {{c.fx * p.x() / p.z() + c.cx, v}, p.z()};
}

Eigen::Vector2d project(const PinholeCamera& c, const SE3& T_wc, const Eigen::Vector3d& p_w) {
  const Eigen::Vector3d p = T_wc.inverse() * p_w;
  return {c.fx * p.x() / p.z() + c.cx, c.fy * p.y() / p.z() + c.cy};
}

// Random points 1-3 m in front of a camera at T_wc, inside its image.
std::vector<Eigen::Vector3d> points_in_view(const PinholeCamera& c, const SE3& T_wc, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(40.0, 600.0), v(40.0, 440.0), z(1.0, 3.0);
  std::vector<Eigen::Vector3d> out;
  for (int i = 0; i < 200; ++i) out.push_back(T_wc * c.back_project(u(rng), v(rng), z(rng)));
  return out;
}

TEST(RollingShutter, KeypointsWithDepthMoveToTheGlobalShutterProjection) {
  const PinholeCamera camera = test_camera();
  const SE3 T_wc = SE3::exp((Twist() << 0.2, -0.1, 0.3, 0.05, -0.1, 0.02).finished());
  // About 0.5 m/s and 45 deg/s (fr1/xyz's fastest), 30 ms from the top row to the bottom one.
  const Twist twist = (Twist() << 0.3, -0.2, 0.35, 0.4, -0.6, 0.3).finished();
  const double readout = 0.03;
  OrbFrame frame;
  std::vector<Eigen::Vector2d> global;
  for (const Eigen::Vector3d& p_w : points_in_view(camera, T_wc, 7)) {
    const RowObservation seen = observe_rolling(camera, T_wc, twist, readout, p_w);
    Keypoint k;
    k.uv = seen.uv.cast<float>();
    k.depth = static_cast<float>(seen.z);
    frame.keypoints.push_back(k);
    global.push_back(project(camera, T_wc, p_w));
  }
  double before = 0.0, after = 0.0;
  for (size_t i = 0; i < global.size(); ++i)
    before = std::max(before, (frame.keypoints[i].uv.cast<double>() - global[i]).norm());
  const std::vector<Keypoint> raw = frame.keypoints;
  compensate_rolling_shutter(camera, twist, readout, &frame);
  for (size_t i = 0; i < global.size(); ++i) {
    after = std::max(after, (frame.keypoints[i].uv.cast<double>() - global[i]).norm());
    EXPECT_EQ(frame.keypoints[i].depth, raw[i].depth);  // the depth camera has no rows
  }
  EXPECT_GT(before, 5.0);  // the shutter matters at this speed ...
  EXPECT_LT(after, 2e-3);  // ... and is undone exactly where the depth is known
  // The grid follows the moved keypoints.
  std::vector<int> found;
  frame.grid.query(frame.keypoints, frame.keypoints[0].uv, 0.5f, 0, -1, &found);
  EXPECT_NE(std::find(found.begin(), found.end(), 0), found.end());
}

TEST(RollingShutter, WithoutDepthARotationIsUndoneAndNoReadoutChangesNothing) {
  const PinholeCamera camera = test_camera();
  const SE3 T_wc;
  const Twist turn = (Twist() << 0.0, 0.0, 0.0, 0.5, 0.7, -0.2).finished();  // rotation alone
  OrbFrame frame;
  std::vector<Eigen::Vector2d> global;
  for (const Eigen::Vector3d& p_w : points_in_view(camera, T_wc, 11)) {
    Keypoint k;  // depth 0: none
    k.uv = observe_rolling(camera, T_wc, turn, 0.03, p_w).uv.cast<float>();
    frame.keypoints.push_back(k);
    global.push_back(project(camera, T_wc, p_w));
  }
  OrbFrame unchanged = frame;
  compensate_rolling_shutter(camera, turn, 0.0, &unchanged);
  for (size_t i = 0; i < global.size(); ++i)
    EXPECT_EQ(unchanged.keypoints[i].uv, frame.keypoints[i].uv);
  compensate_rolling_shutter(camera, turn, 0.03, &frame);
  for (size_t i = 0; i < global.size(); ++i)
    EXPECT_LT((frame.keypoints[i].uv.cast<double>() - global[i]).norm(), 2e-3) << i;
}

}  // namespace

namespace dqo::tracking {
namespace {

// match_descriptors' own brute force against OpenCV's matcher (what it replaced) with the same
// ratio and distance tests: random descriptors, near-copies of some (small distances, ties among
// copies of one), on several seeds; the same matches, pair for pair.
TEST(MatchDescriptors, SameMatchesAsOpenCvsBruteForceMatcher) {
  for (uint32_t seed = 1; seed <= 5; ++seed) {
    std::mt19937_64 rng(seed);
    // 403: not a multiple of the vector popcount's blocks of eight (matching.cpp).
    std::vector<Descriptor> train(403), query(300);
    for (auto& d : train) d = {rng(), rng(), rng(), rng()};
    for (size_t i = 0; i < query.size(); ++i) {
      if (i % 3 == 0) {
        query[i] = {rng(), rng(), rng(), rng()};  // unrelated: mostly rejected
      } else {
        query[i] = train[(i * 7) % train.size()];
        for (int flips = static_cast<int>(rng() % 12); flips > 0; --flips) query[i][rng() % 4] ^= 1ull << (rng() % 64);
      }
    }
    for (size_t i = 0; i < 20; ++i) train[200 + i] = train[i];  // exact duplicates: ties
    const float ratio = 0.8f;
    const int max_distance = 64;
    // Reference: cv::BFMatcher knnMatch(k = 2), then the same tests and one query per train.
    const cv::Mat q(static_cast<int>(query.size()), 32, CV_8U, query.front().data());
    const cv::Mat t(static_cast<int>(train.size()), 32, CV_8U, train.front().data());
    std::vector<std::vector<cv::DMatch>> knn;
    cv::BFMatcher(cv::NORM_HAMMING, false).knnMatch(q, t, knn, 2);
    std::vector<int> best_query(train.size(), -1);
    std::vector<float> best_distance(train.size(), 1e9f);
    for (const auto& m : knn) {
      if (m.empty() || m[0].distance > max_distance || (m.size() > 1 && m[0].distance > ratio * m[1].distance)) continue;
      if (m[0].distance < best_distance[m[0].trainIdx]) {
        best_distance[m[0].trainIdx] = m[0].distance;
        best_query[m[0].trainIdx] = m[0].queryIdx;
      }
    }
    std::vector<std::pair<int, int>> want;
    for (size_t k = 0; k < train.size(); ++k)
      if (best_query[k] >= 0) want.emplace_back(best_query[k], static_cast<int>(k));
    const auto got = match_descriptors(query, train, ratio, max_distance);
    EXPECT_GT(want.size(), 50u) << "seed " << seed;
    EXPECT_EQ(got, want) << "seed " << seed;
  }
}

}  // namespace
}  // namespace dqo::tracking
