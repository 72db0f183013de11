// Local bundle adjustment: perturbed keyframes and points of a synthetic window return to the
// truth, with the fixed keyframe holding the gauge and outliers reported; the worker thread
// delivers results, cancels cleanly and stops in its destructor.
#include <random>

#include <gtest/gtest.h>

#include "local_ba.h"

namespace {

using dqo::PinholeCamera;
using dqo::SE3;
using dqo::Vector6d;
using namespace dqo::tracking;

PinholeCamera test_camera() { return PinholeCamera{525.0, 525.0, 319.5, 239.5, 640, 480}; }

struct Window {
  LocalBaProblem truth;
  LocalBaProblem perturbed;
  std::vector<std::pair<uint64_t, uint64_t>> outliers;
};

// Six keyframes on an arc looking at a cloud of points around (0, 0, 2); keyframe 0 fixed.
Window make_window(int points, int outlier_every, uint64_t seed) {
  std::mt19937 rng(static_cast<unsigned>(seed));
  std::normal_distribution<double> n(0.0, 1.0);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const PinholeCamera camera = test_camera();
  Window w;
  for (int k = 0; k < 6; ++k) {
    const double a = 0.08 * k;
    const Eigen::Vector3d centre(2.0 * std::sin(a), 0.0, 2.0 - 2.0 * std::cos(a));
    const Eigen::Matrix3d R_wc = Eigen::AngleAxisd(a, Eigen::Vector3d::UnitY()).toRotationMatrix();
    w.truth.keyframes.push_back({static_cast<uint64_t>(k + 1),
                                 SE3::from_rotation_translation(R_wc, centre), k == 0});
  }
  for (int i = 0; i < points; ++i)
    w.truth.points.push_back({static_cast<uint64_t>(100 + i),
                              Eigen::Vector3d(0.8 * u(rng), 0.6 * u(rng), 2.0 + 0.5 * u(rng))});
  int count = 0;
  for (size_t k = 0; k < w.truth.keyframes.size(); ++k) {
    const SE3 T_cw = w.truth.keyframes[k].T_wc.inverse();
    for (size_t i = 0; i < w.truth.points.size(); ++i) {
      const Eigen::Vector3d p_c = T_cw * w.truth.points[i].p_w;
      const Eigen::Vector2d uv = camera.project(p_c);
      if (!camera.in_image(uv) || p_c.z() < 0.1) continue;
      BaObservation o;
      o.keyframe = static_cast<int>(k);
      o.point = static_cast<int>(i);
      o.uv = uv + 0.3 * Eigen::Vector2d(n(rng), n(rng));
      o.depth = p_c.z() + 0.001 * n(rng);
      o.inv_sigma = 1.0;
      if (outlier_every > 0 && ++count % outlier_every == 0) {
        o.uv += Eigen::Vector2d(25.0, -30.0);
        w.outliers.emplace_back(w.truth.keyframes[k].id, w.truth.points[i].id);
      }
      w.truth.observations.push_back(o);
    }
  }
  w.perturbed = w.truth;
  for (BaKeyframe& k : w.perturbed.keyframes) {
    if (k.fixed) continue;
    Vector6d xi;
    xi << 0.01 * n(rng), 0.01 * n(rng), 0.01 * n(rng), 0.005 * n(rng), 0.005 * n(rng),
        0.005 * n(rng);
    k.T_wc = k.T_wc * SE3::exp(xi);
  }
  for (BaPoint& p : w.perturbed.points) p.p_w += 0.01 * Eigen::Vector3d(n(rng), n(rng), n(rng));
  return w;
}

TEST(LocalBa, RecoversPerturbedWindowAndFindsOutliers) {
  const Window w = make_window(300, 40, 1);
  LocalBaParams params;
  params.iterations = 20;
  const LocalBaResult r = solve_local_ba(w.perturbed, test_camera(), params, {}, nullptr);
  ASSERT_TRUE(r.ok);
  EXPECT_LT(r.final_cost, r.initial_cost);
  EXPECT_EQ(r.keyframes.size(), 5u);  // the fixed one is not reported
  for (const auto& [id, T_wc] : r.keyframes) {
    const SE3& truth = w.truth.keyframes[id - 1].T_wc;
    EXPECT_LT((T_wc.translation() - truth.translation()).norm(), 2e-3) << "keyframe " << id;
  }
  double point_error = 0.0;
  for (size_t i = 0; i < r.points.size(); ++i)
    point_error += (r.points[i].second - w.truth.points[i].p_w).norm();
  EXPECT_LT(point_error / r.points.size(), 2e-3);
  // Every planted outlier is reported, and little else.
  for (const auto& o : w.outliers)
    EXPECT_NE(std::find(r.outliers.begin(), r.outliers.end(), o), r.outliers.end());
  EXPECT_LT(r.outliers.size(), w.outliers.size() + w.truth.observations.size() / 50);
}

TEST(LocalBa, WorkerDeliversCancelsAndStops) {
  const Window w = make_window(200, 0, 2);
  LocalBaParams params;
  {
    LocalBaWorker worker(test_camera(), params, {});
    worker.submit(w.perturbed);
    worker.wait_idle();
    std::vector<LocalBaResult> results = worker.take_results();
    ASSERT_EQ(results.size(), 1u);
    EXPECT_TRUE(results[0].ok);
    EXPECT_TRUE(worker.take_results().empty());

    // Cancelled work leaves nothing behind, and the worker keeps working afterwards.
    worker.submit(w.perturbed);
    worker.cancel_all();
    EXPECT_FALSE(worker.busy());
    EXPECT_TRUE(worker.take_results().empty());
    worker.submit(w.perturbed);
    worker.wait_idle();
    EXPECT_EQ(worker.take_results().size(), 1u);

    worker.submit(w.perturbed);  // still running or pending when the destructor comes
  }
  SUCCEED();
}

}  // namespace
