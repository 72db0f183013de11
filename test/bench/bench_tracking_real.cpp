// bench_tracking --real: the tracker on real data and under injected faults (issue 14, item 5).
//   - TUM fr1/xyz (../shared/data/tum_fr1_xyz, undistorted with config/cameras/tum_fr1.yaml) at
//     every frame and at every 5th, 10th and 20th;
//   - TUM fr1/desk, 150 frames of fast motion (../shared/data/tum_fr1_desk_330, the same camera)
//     at every frame and at every 10th (issue 25);
//   - faults injected into TUM fr1/xyz and into the synthetic tabletop (sensor noise on): a covered
//     lens for 1 s (black image, no depth), depth dropped for 1 s, a 30 degree jump between two
//     frames (tabletop: the frames of the turn in between left out), a frame repeated (the same
//     images again with a later stamp).
// Per run: ATE over the frames given a pose (ok and degraded; Umeyama-aligned to the ground
// truth, as dqo_eval_ate), frames per state, wrong poses (after that alignment more than 5 cm off,
// or more than 5 degrees off after the rotation that best aligns the orientations) reported ok and
// reported degraded, the seconds of input from the end of the fault
// to the first ok frame, the ATE of the frames after the fault, and the median time per frame
// (wall and the tracking thread's CPU time: what a frame costs on one core). Offline runs are
// deterministic: the same figures on any machine load.
#include "bench_tracking_real.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <initializer_list>
#include <string>
#include <vector>

#include <Eigen/SVD>

#include "dqo_map/common/statistics.h"
#include "dqo_map/eval/ate.h"
#include "dqo_map/io/dataset_reader.h"
#include "dqo_map/sim/renderer.h"
#include "dqo_map/sim/scene_loader.h"
#include "dqo_map/tracking/rectified_frame_source.h"
#include "dqo_map/tracking/tracker.h"

namespace {

using dqo::SE3;
using dqo::tracking::TrackingState;

struct BenchFrame {
  double t = 0.0;
  std::optional<double> depth_t;  // the depth image's own stamp (TUM)
  SE3 T_wc;  // ground truth
  bool has_gt = false;
  std::shared_ptr<const dqo::ImageRgb8> rgb;
  std::shared_ptr<const dqo::DepthImage> depth;
};

struct Sequence {
  std::string name;
  dqo::PinholeCamera camera;
  double rolling_shutter_s = 0.0;  // the camera file's (0: a global shutter, the simulator)
  std::vector<BenchFrame> frames;
};

struct Fault {
  std::string name = "none";
  double start = NAN;  // seconds of input from the sequence's start
  double end = NAN;    // the first frame at or after this is past the fault
};

struct Stats {
  std::string label;
  double base_after_cm = NAN;  // the fault-free run's ATE over the same span after the fault
  int frames = 0, ok = 0, degraded = 0, lost = 0, not_initialised = 0;
  int wrong_ok = 0, wrong_degraded = 0;
  double ate_cm = NAN, max_cm = NAN, ate_after_cm = NAN;
  double relocalise_s = NAN;  // from the end of the fault to the first ok frame
  double median_ms = NAN, median_cpu_ms = NAN;
};

double thread_cpu_ms() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

double angle_deg(const SE3& T) {
  return 2.0 * std::acos(std::min(1.0, std::abs(T.quaternion().w()))) * 180.0 / M_PI;
}

std::optional<Sequence> load_tum(const std::string& dir, const std::string& name,
                                 const std::string& camera_file, std::string* error) {
  dqo::DatasetReaderParams params;
  params.load_meshes = false;
  params.tum.camera_file = camera_file;
  std::shared_ptr<const dqo::FrameSource> reader = dqo::open_dataset(dir, params, error);
  if (!reader) return std::nullopt;
  const auto source = dqo::tracking::rectified(reader, error);
  if (!source) return std::nullopt;
  Sequence s;
  s.name = name;
  s.camera = source->info().camera;
  s.rolling_shutter_s = source->info().rolling_shutter_s;
  for (int i = 0; i < source->num_frames(); ++i) {
    auto f = source->read_frame(i, error);
    if (!f) return std::nullopt;
    BenchFrame b;
    b.t = f->timestamp;
    b.depth_t = f->depth_timestamp;
    b.T_wc = f->T_wc;
    b.has_gt = f->has_pose;
    b.rgb = std::make_shared<dqo::ImageRgb8>(std::move(f->rgb));
    b.depth = std::make_shared<dqo::DepthImage>(std::move(f->depth));
    s.frames.push_back(std::move(b));
  }
  return s;
}

std::optional<Sequence> load_scene(const std::string& path, int frames, std::string* error) {
  const auto scene = dqo::sim::load_scene(path, {}, error);
  if (!scene) return std::nullopt;
  const dqo::sim::Renderer renderer(*scene, 0);
  Sequence s;
  s.name = std::filesystem::path(path).stem().string();
  s.camera = scene->camera;
  for (int i = 0; i < renderer.num_frames() && i < frames; ++i) {
    dqo::Frame f = renderer.render(i, true);
    BenchFrame b;
    b.t = f.timestamp;
    b.T_wc = f.T_wc;
    b.has_gt = true;
    b.rgb = std::make_shared<dqo::ImageRgb8>(std::move(f.rgb));
    b.depth = std::make_shared<dqo::DepthImage>(std::move(f.depth));
    s.frames.push_back(std::move(b));
  }
  return s;
}

Sequence every_kth(const Sequence& s, int k) {
  Sequence out{s.name + (k > 1 ? " every " + std::to_string(k) : ""), s.camera, s.rolling_shutter_s, {}};
  for (size_t i = 0; i < s.frames.size(); i += static_cast<size_t>(k)) out.frames.push_back(s.frames[i]);
  return out;
}

// The fault starts a third of the way in.
Sequence inject(const Sequence& s, const std::string& fault, Fault* f) {
  Sequence out{s.name + ", " + fault, s.camera, s.rolling_shutter_s, {}};
  const double t0 = s.frames.front().t;
  const double start = t0 + (s.frames.back().t - t0) / 3.0;
  f->name = fault;
  f->start = start;
  f->end = start + 1.0;
  const auto black = std::make_shared<dqo::ImageRgb8>(s.camera.width, s.camera.height, 3);
  const auto no_depth = std::make_shared<dqo::DepthImage>(s.camera.width, s.camera.height, 1);
  if (fault == "covered" || fault == "no depth") {
    for (BenchFrame b : s.frames) {
      if (b.t >= start && b.t < f->end) {
        if (fault == "covered") b.rgb = black;
        b.depth = no_depth;
      }
      out.frames.push_back(std::move(b));
    }
  } else if (fault == "repeated") {
    bool done = false;
    for (size_t i = 0; i < s.frames.size(); ++i) {
      out.frames.push_back(s.frames[i]);
      if (!done && s.frames[i].t >= start && i + 1 < s.frames.size()) {
        BenchFrame again = s.frames[i];
        again.t = 0.5 * (s.frames[i].t + s.frames[i + 1].t);  // the camera did not move
        if (again.depth_t) *again.depth_t += again.t - s.frames[i].t;  // nor did the depth's
        out.frames.push_back(again);
        f->end = again.t;
        done = true;
      }
    }
  } else if (fault == "jump 30deg") {
    // Leave out the frames of the turn until the camera has turned 30 degrees from the last one
    // given: the tracker sees one step of 30 degrees (and whatever translation came with it).
    size_t i = 0;
    while (i < s.frames.size() && s.frames[i].t < start) out.frames.push_back(s.frames[i++]);
    if (i == 0 || i >= s.frames.size()) return out;
    const SE3 before = s.frames[i - 1].T_wc;
    while (i < s.frames.size() && angle_deg(before.inverse() * s.frames[i].T_wc) < 30.0) ++i;
    if (i < s.frames.size()) f->end = s.frames[i].t;
    for (; i < s.frames.size(); ++i) out.frames.push_back(s.frames[i]);
  }
  return out;
}

Stats run(const Sequence& s, const Fault& fault, bool verbose) {
  Stats st;
  st.label = s.name;
  dqo::tracking::TrackerParams params;
  params.local_ba.deterministic = true;
  params.rolling_shutter.readout_s = s.rolling_shutter_s;  // the camera file's (dqo_track's rule)
  dqo::tracking::Tracker tracker(s.camera, params);
  std::vector<dqo::eval::StampedPose> estimate, truth;
  std::vector<TrackingState> states;  // per estimate entry
  std::vector<double> ms, cpu_ms;
  for (const BenchFrame& f : s.frames) {
    const dqo::tracking::RgbdInput input{f.t, f.rgb.get(), f.depth.get(), f.depth_t};
    const double c0 = thread_cpu_ms();
    const dqo::tracking::TrackResult r = tracker.track(input);
    cpu_ms.push_back(thread_cpu_ms() - c0);
    ms.push_back(r.milliseconds);
    ++st.frames;
    switch (r.state) {
      case TrackingState::kOk: ++st.ok; break;
      case TrackingState::kDegraded: ++st.degraded; break;
      case TrackingState::kLost: ++st.lost; break;
      case TrackingState::kNotInitialised: ++st.not_initialised; break;
    }
    if (verbose) {
      const SE3 rel = s.frames.front().T_wc.inverse() * f.T_wc;
      std::printf("  %8.3f %-9s inl %4d spread %.2f dense %d rms %.2f kf %d reloc %d |t - t_gt| %.3f %s\n",
                  f.t - s.frames.front().t, dqo::tracking::to_string(r.state), r.quality.inliers,
                  r.quality.spread, r.quality.dense_ok, r.quality.dense_rms, r.new_keyframe,
                  r.relocalised,
                  dqo::tracking::has_pose(r.state) ? (r.T_wc.translation() - rel.translation()).norm() : NAN,
                  dqo::tracking::reasons_to_string(r.quality.reasons).c_str());
    }
    if (f.has_gt) truth.emplace_back(f.t, f.T_wc);
    if (dqo::tracking::has_pose(r.state) && f.has_gt) {
      estimate.emplace_back(f.t, r.T_wc);
      states.push_back(r.state);
    }
    if (std::isfinite(fault.end) && f.t >= fault.end && std::isnan(st.relocalise_s) &&
        r.state == TrackingState::kOk) {
      st.relocalise_s = f.t - fault.end;
    }
  }
  tracker.wait_for_mapping();
  st.median_ms = dqo::percentile(ms, 0.5);
  st.median_cpu_ms = dqo::percentile(cpu_ms, 0.5);
  std::string error;
  const auto ate = dqo::eval::compute_ate(estimate, truth, dqo::eval::AteParams{}, &error);
  if (!ate) return st;
  st.ate_cm = 100.0 * ate->rmse_m;
  st.max_cm = 100.0 * ate->max_m;
  // Each posed frame against its ground truth (interpolation as compute_ate: nearest within its
  // window; the TUM ground truth is 100 Hz), after the same alignment.
  auto nearest_truth = [&truth](double t) {
    return std::min_element(truth.begin(), truth.end(), [t](const auto& a, const auto& b) {
      return std::abs(a.first - t) < std::abs(b.first - t);
    });
  };
  // The angles after their own alignment: Umeyama fits positions only, and where they lie nearly
  // on a line or a plane (fr1/xyz moves back and forth) the rotation about it is poorly fixed:
  // at every 10th frame 2-5 degrees off the orientations' best fit, the same for every frame,
  // which counted well tracked frames as wrong. The chordal mean of R_gt R_estᵀ fixes it.
  Eigen::Matrix3d sum_rotations = Eigen::Matrix3d::Zero();
  for (const auto& [t, T_wc] : estimate)
    sum_rotations += nearest_truth(t)->second.rotation() * T_wc.rotation().transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(sum_rotations, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  const SE3 R_gt_est = SE3::from_rotation_translation(
      svd.matrixU() * D * svd.matrixV().transpose(), Eigen::Vector3d::Zero());
  double after_sum = 0.0;
  int after_n = 0;
  for (size_t i = 0; i < estimate.size(); ++i) {
    const double t = estimate[i].first;
    const auto nearest = nearest_truth(t);
    const SE3 aligned = ate->T_gt_est * estimate[i].second;
    const SE3 delta = nearest->second.inverse() * (R_gt_est * estimate[i].second);
    const double e = (aligned.translation() - nearest->second.translation()).norm();
    const bool wrong = e > 0.05 || angle_deg(delta) > 5.0;
    if (wrong && verbose) {
      std::printf("  wrong pose at %.3f (%s): %.1f cm, %.1f deg\n", t - s.frames.front().t,
                  dqo::tracking::to_string(states[i]), 100.0 * e, angle_deg(delta));
    }
    if (wrong && states[i] == TrackingState::kOk) ++st.wrong_ok;
    if (wrong && states[i] == TrackingState::kDegraded) ++st.wrong_degraded;
    if (std::isfinite(fault.end) && t >= fault.end) {
      after_sum += e * e;
      ++after_n;
    }
  }
  if (after_n > 0) st.ate_after_cm = 100.0 * std::sqrt(after_sum / after_n);
  return st;
}

void print(const Stats& s) {
  std::printf("%-32s %6d %5d %5d %5d %5d %8.2f %8.2f %8d %8d %9.2f %9.2f %9.2f %7.2f %7.2f\n",
              s.label.c_str(), s.frames, s.ok, s.degraded, s.lost, s.not_initialised, s.ate_cm,
              s.max_cm, s.wrong_ok, s.wrong_degraded, s.relocalise_s, s.ate_after_cm,
              s.base_after_cm, s.median_ms, s.median_cpu_ms);
  std::fflush(stdout);
}

}  // namespace

int run_real_benchmark(const std::string& source_dir, const RealOptions& options) {
  std::string error;
  std::printf("%-32s %6s %5s %5s %5s %5s %8s %8s %8s %8s %9s %9s %9s %7s %7s\n", "run", "frames",
              "ok", "degr", "lost", "init", "ATE cm", "max cm", "wrong_ok", "wrong_dg",
              "reloc s", "after cm", "base aft", "med ms", "cpu ms");
  bool zero_wrong_ok = true;
  // Each fault injected into `seq`: the faulty run, with the fault-free run's ATE over the same span.
  auto run_faults = [&](const Sequence& seq, std::initializer_list<const char*> faults) {
    for (const std::string fault : faults) {
      if (!options.only.empty() && fault != options.only) continue;
      Fault f;
      const Sequence faulty = inject(seq, fault, &f);
      Stats s = run(faulty, f, options.verbose);
      s.base_after_cm = run(seq, f, false).ate_after_cm;
      zero_wrong_ok = zero_wrong_ok && s.wrong_ok == 0;
      print(s);
    }
  };
  const std::string tum_dir =
      std::filesystem::path(options.tum_dir.empty()
                                ? (std::filesystem::canonical(source_dir) / "../shared/data/tum_fr1_xyz").string()
                                : options.tum_dir)
          .lexically_normal()
          .string();
  if (!std::filesystem::exists(tum_dir + "/rgb.txt")) {
    std::printf("(TUM fr1/xyz not found at %s: real-data runs skipped)\n", tum_dir.c_str());
  } else {
    const auto tum =
        load_tum(tum_dir, "tum_fr1_xyz", source_dir + "/config/cameras/tum_fr1.yaml", &error);
    if (!tum) {
      std::fprintf(stderr, "bench_tracking: %s\n", error.c_str());
      return 1;
    }
    if (options.every > 0) {
      for (int r = 0; r < std::max(1, options.repeat); ++r) {
        const Stats s = run(every_kth(*tum, options.every), Fault{}, options.verbose);
        zero_wrong_ok = zero_wrong_ok && s.wrong_ok == 0;
        print(s);
      }
      return zero_wrong_ok ? 0 : 1;
    }
    for (const int k : {1, 5, 10, 20}) {
      const Stats s = run(every_kth(*tum, k), Fault{}, options.verbose);
      zero_wrong_ok = zero_wrong_ok && s.wrong_ok == 0;
      print(s);
    }
    run_faults(*tum, {"covered", "no depth", "repeated"});
  }
  // Fast hand-held motion (issue 25): motion blur, 2-3 cm and 2-4 degrees per frame, 15-30 cm and
  // 5-24 degrees at every 10th.
  const std::string desk_dir =
      (std::filesystem::canonical(source_dir) / "../shared/data/tum_fr1_desk_330").lexically_normal().string();
  if (!options.only.empty()) {
    // one fault only: the desk has no faults
  } else if (!std::filesystem::exists(desk_dir + "/rgb.txt")) {
    std::printf("(TUM fr1/desk not found at %s: its runs skipped)\n", desk_dir.c_str());
  } else {
    const auto desk = load_tum(desk_dir, "tum_fr1_desk_330",
                               source_dir + "/config/cameras/tum_fr1.yaml", &error);
    if (!desk) {
      std::fprintf(stderr, "bench_tracking: %s\n", error.c_str());
      return 1;
    }
    for (const int k : {1, 10}) {
      const Stats s = run(every_kth(*desk, k), Fault{}, options.verbose);
      zero_wrong_ok = zero_wrong_ok && s.wrong_ok == 0;
      print(s);
    }
  }
  const auto tabletop =
      load_scene(source_dir + "/config/scenes/tabletop.yaml", options.synthetic_frames, &error);
  if (!tabletop) {
    std::fprintf(stderr, "bench_tracking: %s\n", error.c_str());
    return 1;
  }
  print(run(*tabletop, Fault{}, options.verbose));
  run_faults(*tabletop, {"covered", "no depth", "jump 30deg", "repeated"});
  std::printf("\nwrong poses reported ok: %s\n", zero_wrong_ok ? "none (target met)" : "SOME (target missed)");
  return zero_wrong_ok ? 0 : 1;
}
