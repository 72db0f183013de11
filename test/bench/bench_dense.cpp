// bench_dense: speed and accuracy of dense RGB-D alignment (tracking/dense_alignment.h).
//
// Renders the first N frames of a scene (default `tabletop`, 640x480, with its sensor noise)
// beforehand, then aligns each frame to the previous one on one thread, timing the new frame's
// pyramid plus align_dense, and compares T_ref_cur with the ground truth. Times are the thread's
// CPU time (CLOCK_THREAD_CPUTIME_ID): wall time on an idle core, and not inflated when other
// processes share the machine. One row per configuration: median and 90th-percentile ms per frame
// (and the pyramid's share), failures, mean and largest translation error and mean rotation error
// per pair, Gauss-Newton steps, and the mean of χ²/6 = eᵀ information e / 6 over the errors e
// (right perturbation): about 1 for an honest information matrix, larger when it is overconfident
// (by as much as PoseOptimiserParams::dense_prior_weight should shrink it).
//
//   bench_dense [--scene PATH] [--frames N] [--every K] [--no-noise] [--guess identity|velocity]
//
// --guess velocity starts each alignment from the previous pair's ground-truth motion (a perfect
// constant-velocity model), as a tracker would from its motion model; use it with --every K > 1.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <string>
#include <utility>
#include <vector>

#include "dqo_map/common/statistics.h"
#include "dqo_map/sim/renderer.h"
#include "dqo_map/sim/scene_loader.h"
#include "dqo_map/tracking/dense_alignment.h"

namespace {

using dqo::percentile;

using dqo::SE3;
using dqo::tracking::DenseParams;
using dqo::tracking::DenseResult;
using dqo::tracking::RgbdPyramid;

double thread_ms() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}

double angle_deg(const SE3& T) {
  return 2.0 * std::acos(std::min(1.0, std::abs(T.quaternion().w()))) * 180.0 / M_PI;
}

struct Row {
  std::string name;
  DenseParams params;
  bool fresh_pyramids = false;  // construct a pyramid per frame instead of rebuild() into one
};

void run(const Row& row, const dqo::PinholeCamera& camera, const std::vector<dqo::Frame>& frames,
         bool velocity_guess) {
  std::vector<double> total_ms, pyramid_ms;
  double sum_t = 0.0, max_t = 0.0, sum_r = 0.0, sum_chi2 = 0.0;
  int ok = 0, failed = 0, iterations = 0;
  // As a tracker would run it: two pyramids, the new frame rebuilt into the older one's buffers.
  RgbdPyramid previous(camera, frames[0].rgb, frames[0].depth, row.params);
  RgbdPyramid current;
  SE3 last_motion;
  for (size_t i = 1; i < frames.size(); ++i) {
    const SE3 truth = frames[i - 1].T_wc.inverse() * frames[i].T_wc;
    const SE3 guess = velocity_guess ? last_motion : SE3::identity();
    const double t0 = thread_ms();
    if (row.fresh_pyramids) {
      current = RgbdPyramid(camera, frames[i].rgb, frames[i].depth, row.params);
    } else {
      current.rebuild(camera, frames[i].rgb, frames[i].depth, row.params);
    }
    const double t1 = thread_ms();
    const DenseResult r = dqo::tracking::align_dense(previous, current, guess, row.params);
    const double t2 = thread_ms();
    pyramid_ms.push_back(t1 - t0);
    total_ms.push_back(t2 - t0);
    if (r.ok) {
      const SE3 error = truth.inverse() * r.T_ref_cur;  // r.T_ref_cur = truth * exp(e)
      const dqo::Vector6d e = error.log();
      sum_t += error.translation().norm();
      max_t = std::max(max_t, error.translation().norm());
      sum_r += angle_deg(error);
      sum_chi2 += e.dot(r.information * e) / 6.0;
      iterations += r.iterations;
      ++ok;
    } else {
      ++failed;
    }
    last_motion = truth;
    std::swap(previous, current);
  }
  const double n = std::max(ok, 1);
  std::printf("| %-28s | %6.2f | %6.2f | %6.2f | %3d/%-3zu | %6.3f | %6.3f | %7.4f | %4.1f "
              "| %6.2f |\n",
              row.name.c_str(), percentile(total_ms, 0.5), percentile(total_ms, 0.9),
              percentile(pyramid_ms, 0.5), failed, frames.size() - 1, 1e3 * sum_t / n,
              1e3 * max_t, sum_r / n, iterations / n, sum_chi2 / n);
}

}  // namespace

int main(int argc, char** argv) {
  std::string scene_path = std::string(DQO_SOURCE_DIR) + "/config/scenes/tabletop.yaml";
  int frames = 60;
  int every = 1;
  bool noise = true;
  bool velocity_guess = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has_value = i + 1 < argc;
    if (a == "--no-noise") {
      noise = false;
    } else if (a == "--scene" && has_value) {
      scene_path = argv[++i];
    } else if (a == "--frames" && has_value) {
      frames = std::max(2, std::atoi(argv[++i]));
    } else if (a == "--every" && has_value) {
      every = std::max(1, std::atoi(argv[++i]));
    } else if (a == "--guess" && has_value) {
      const std::string g = argv[++i];
      if (g != "identity" && g != "velocity") return 2;
      velocity_guess = g == "velocity";
    } else {
      std::fprintf(stderr,
                   "usage: %s [--scene PATH] [--frames N] [--every K] [--no-noise] "
                   "[--guess identity|velocity]\n",
                   argv[0]);
      return 2;
    }
  }
  std::string error;
  const auto scene = dqo::sim::load_scene(scene_path, {}, &error);
  if (!scene) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return 1;
  }
  // Rendering uses every core; the alignment below runs on this thread only.
  const dqo::sim::Renderer renderer(*scene, 0);
  std::vector<dqo::Frame> rendered;
  for (int k = 0; k < frames && k * every < renderer.num_frames(); ++k) {
    rendered.push_back(renderer.render(k * every, noise));
  }
  const dqo::PinholeCamera camera = renderer.info().camera;
  std::printf("bench_dense: %s %dx%d, %zu frames (every %d), noise %s, guess %s, one thread, "
              "CPU ms per frame (pyramid + align)\n",
              scene->name.c_str(), camera.width, camera.height, rendered.size(), every,
              noise ? "on" : "off", velocity_guess ? "previous motion" : "identity");

  std::vector<Row> rows;
  rows.push_back({"default (finest 320x240)", DenseParams()});
  Row geometric{"geometry only", DenseParams()};
  geometric.params.colour_weight = 0.0;
  rows.push_back(geometric);
  Row fresh{"default, new pyramid a frame", DenseParams(), true};
  rows.push_back(fresh);
  Row full{"finest 640x480", DenseParams()};
  full.params.finest_level = 0;
  rows.push_back(full);

  std::printf("| %-28s | %6s | %6s | %6s | %7s | %6s | %6s | %7s | %4s | %6s |\n", "configuration",
              "ms p50", "ms p90", "pyr ms", "failed", "err mm", "max mm", "err deg", "GN",
              "chi2/6");
  std::printf("|------------------------------|--------|--------|--------|---------|--------|"
              "--------|---------|------|--------|\n");
  for (const Row& row : rows) run(row, camera, rendered, velocity_guess);
  return 0;
}
