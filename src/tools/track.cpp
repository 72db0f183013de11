// dqo_track: tracks the camera through an RGB-D dataset folder (the package's own format, TUM
// RGB-D or Replica: whatever dqo::open_dataset reads) and writes the trajectory in TUM format. Runs
// the same tracking stage as tracking_node (dqo::tracking::TrackingSession). Prints the median
// tracking time per frame, the lost frames and, where the dataset has ground truth, the ATE.
//
//   dqo_track DATASET_DIR --out traj.txt [--config tracking.yaml] [--frames N] [--every K]
//             [--camera camera.yaml] [--states states.txt] [--online]
// The trajectory written is the one after the tracker's final global bundle adjustment and
// refinement (Tracker::optimise_map), unless --online; the states are always the online ones.
// Images with lens distortion (camera.yaml's distortion_model and distortion) are undistorted
// first, as tracking_node does with a CameraInfo.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <future>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "dqo_map/common/progress.h"
#include "dqo_map/common/statistics.h"
#include "dqo_map/common/tum_trajectory.h"
#include "dqo_map/eval/ate.h"
#include "dqo_map/io/dataset_reader.h"
#include "dqo_map/tracking/frame_states.h"
#include "dqo_map/tracking/params_yaml.h"
#include "dqo_map/tracking/rectified_frame_source.h"
#include "dqo_map/tracking/tracking_session.h"

namespace {

using dqo::median;

constexpr char kUsage[] =
    "usage: dqo_track DATASET_DIR --out traj.txt [--config tracking.yaml] [--frames N] [--every K]\n"
    "                 [--camera camera.yaml] [--states states.txt] [--online] [--verbose]\n"
    "  DATASET_DIR        own format (camera.yaml, rgb/), TUM RGB-D (rgb.txt, depth.txt) or Replica\n"
    "  --out traj.txt     the estimated trajectory, TUM format (T_world_camera of tracked frames)\n"
    "  --config FILE      tracking parameters (default: the built-in ones, as config/tracking.yaml)\n"
    "  --frames N         track only the first N frames\n"
    "  --every K          track every K-th of them (frames 0, K, 2K, ...): larger baselines\n"
    "  --camera FILE      a TUM sequence's intrinsics and distortion from FILE, not its camera.yaml\n"
    "                     (e.g. config/cameras/tum_fr1.yaml)\n"
    "  --states FILE      each tracked frame's state, reasons and evidence, one line per frame\n"
    "                     (lost ones too; format: include/dqo_map/tracking/frame_states.h)\n"
    "  --verbose          one line per frame on stderr: state, its evidence and reasons\n"
    "  --online           write each frame's pose as tracking gave it (default: after the final\n"
    "                     global bundle adjustment, tracking.loop.final_global_ba, each frame\n"
    "                     following its reference keyframe; the states stay the online ones)\n"
    "Prints the frames per state (ok, degraded, lost) and why frames were not ok. The trajectory\n"
    "holds the ok and degraded frames (lost frames have no pose).\n";

// register_frame IDs for dqo_track's own frames, apart from the session's mapping keyframe IDs.
constexpr uint64_t kFrameIdBase = uint64_t{1} << 40;

struct Options {
  std::string dataset;
  std::string out;
  std::string config;
  std::string camera;
  std::string states;
  int frames = -1;
  int every = 1;
  bool verbose = false;
  bool online = false;
};

int usage_error(const std::string& message) {
  std::fprintf(stderr, "dqo_track: %s\n%s", message.c_str(), kUsage);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  int positional = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> const char* { return i + 1 < argc ? argv[++i] : nullptr; };
    if (a == "-h" || a == "--help") {
      std::fputs(kUsage, stdout);
      return 0;
    } else if (a == "--verbose") {
      o.verbose = true;
    } else if (a == "--online") {
      o.online = true;
    } else if (a == "--out" || a == "--config" || a == "--frames" || a == "--every" ||
               a == "--camera" || a == "--states") {
      const char* v = value();
      if (!v) return usage_error(a + " needs a value");
      if (a == "--out") o.out = v;
      if (a == "--config") o.config = v;
      if (a == "--camera") o.camera = v;
      if (a == "--states") o.states = v;
      if (a == "--frames") {
        char* end = nullptr;
        const long n = std::strtol(v, &end, 10);
        if (end == v || *end != '\0' || n < 1) return usage_error("--frames takes a whole number >= 1");
        o.frames = static_cast<int>(n);
      }
      if (a == "--every") {
        char* end = nullptr;
        const long n = std::strtol(v, &end, 10);
        if (end == v || *end != '\0' || n < 1) return usage_error("--every takes a whole number >= 1");
        o.every = static_cast<int>(n);
      }
    } else if (!a.empty() && a[0] == '-') {
      return usage_error("unknown option " + a);
    } else if (positional++ == 0) {
      o.dataset = a;
    } else {
      return usage_error("unexpected argument " + a);
    }
  }
  if (o.dataset.empty()) return usage_error("no dataset folder given");
  if (o.out.empty()) return usage_error("--out is required");

  // Check everything that can fail before the long part.
  std::string error;
  dqo::tracking::TrackingConfig config;
  if (!o.config.empty()) {
    const auto loaded = dqo::tracking::load_tracking_config(o.config, &error);
    if (!loaded) {
      std::fprintf(stderr, "dqo_track: %s\n", error.c_str());
      return 1;
    }
    config = *loaded;
  }
  const std::filesystem::path out_dir = std::filesystem::absolute(o.out).parent_path();
  if (!std::filesystem::is_directory(out_dir)) {
    std::fprintf(stderr, "dqo_track: the folder of --out (%s) does not exist\n", out_dir.c_str());
    return 1;
  }
  std::ofstream states;
  if (!o.states.empty()) {
    states.open(o.states);
    if (!states) {
      std::fprintf(stderr, "dqo_track: cannot write --states %s\n", o.states.c_str());
      return 1;
    }
    states << dqo::tracking::frame_states_header() << '\n';
  }
  dqo::DatasetReaderParams reader_params;
  reader_params.load_meshes = false;
  reader_params.tum.camera_file = o.camera;
  const std::shared_ptr<const dqo::DatasetReader> dataset =
      dqo::open_dataset(o.dataset, reader_params, &error);
  if (!dataset) {
    std::fprintf(stderr, "dqo_track: %s\n", error.c_str());
    return 1;
  }
  if (!o.camera.empty() && dataset->format() != "tum") {
    std::fprintf(stderr, "dqo_track: --camera applies to TUM sequences only\n");
    return 1;
  }
  const std::shared_ptr<const dqo::FrameSource> reader = dqo::tracking::rectified(dataset, &error);
  if (!reader) {
    std::fprintf(stderr, "dqo_track: %s\n", error.c_str());
    return 1;
  }
  const int total = o.frames > 0 ? std::min(o.frames, reader->num_frames()) : reader->num_frames();
  if (total < 1) {
    std::fprintf(stderr, "dqo_track: %s holds no frames\n", o.dataset.c_str());
    return 1;
  }
  const dqo::PinholeCamera& camera = reader->info().camera;
  const int count = (total + o.every - 1) / o.every;  // frames tracked: 0, K, 2K, ...
  const std::string lens = dataset->info().distortion_model;
  std::fprintf(stderr, "dqo_track: %s dataset %s, %d frames of %dx%d%s\n", dataset->format().c_str(),
               o.dataset.c_str(), count, camera.width, camera.height,
               lens.empty() ? "" : (", " + lens + " undistorted").c_str());

  // Bit-identical output for the same input on any machine load (local BA at fixed points).
  config.tracker.local_ba.deterministic = true;
  // The camera's rolling shutter is a property of the sensor: its file's value wins.
  if (dataset->info().rolling_shutter_s > 0.0)
    config.tracker.rolling_shutter.readout_s = dataset->info().rolling_shutter_s;
  dqo::tracking::TrackingSession session(config);
  dqo::Trajectory estimate, ground_truth;
  std::vector<double> ms;
  int ok = 0, degraded = 0, lost = 0, not_initialised = 0, relocalised = 0, skipped = 0;
  std::map<std::string, int> reasons;  // why frames were degraded or lost
  dqo::tracking::Tracker* tracker_of_frames = nullptr;
  dqo::ProgressBar progress("tracking", count);
  // Reading (PNG decoding) of frame i + 1 overlaps tracking of frame i.
  auto read = [&](int i) {
    return std::async(std::launch::async, [&reader, i] {
      std::string e;
      auto frame = reader->read_frame(i, &e);
      return std::make_pair(std::move(frame), e);
    });
  };
  auto next = read(0);
  for (int j = 0; j < count; ++j) {
    const int i = j * o.every;
    auto [frame, read_error] = next.get();
    if (j + 1 < count) next = read(i + o.every);
    if (!frame) {
      std::fprintf(stderr, "\ndqo_track: frame %d: %s\n", i, read_error.c_str());
      return 1;
    }
    if (frame->has_pose) ground_truth.emplace_back(frame->timestamp, frame->T_wc);
    const dqo::tracking::RgbdInput input{frame->timestamp, &frame->rgb, &frame->depth,
                                         frame->depth_timestamp};
    const dqo::tracking::SessionResult r = session.track(camera, input);
    if (r.skipped != dqo::tracking::SessionResult::Skip::kNone) {
      ++skipped;
      progress.update(j + 1);
      continue;
    }
    if (r.reset) {
      std::fprintf(stderr, "\ndqo_track: frame %d: time went back by %.3f s: tracking restarted\n", i,
                   r.time_jump);
    }
    ms.push_back(r.track.milliseconds);
    if (states.is_open()) states << dqo::tracking::format_frame_state(frame->timestamp, r.track) << '\n';
    if (r.track.relocalised) ++relocalised;
    switch (r.track.state) {
      case dqo::tracking::TrackingState::kOk:
        ++ok;
        estimate.emplace_back(frame->timestamp, r.track.T_wc);
        break;
      case dqo::tracking::TrackingState::kDegraded:
        ++degraded;
        estimate.emplace_back(frame->timestamp, r.track.T_wc);
        break;
      default:
        break;
    }
    if (dqo::tracking::has_pose(r.track.state) && session.tracker() != nullptr && !o.online) {
      session.tracker()->register_frame(kFrameIdBase + estimate.size() - 1);
      tracker_of_frames = session.tracker();
    }
    switch (r.track.state) {
      case dqo::tracking::TrackingState::kLost:
        ++lost;
        break;
      case dqo::tracking::TrackingState::kNotInitialised:
        ++not_initialised;
        break;
      default:
        break;
    }
    if (r.track.state != dqo::tracking::TrackingState::kOk) {
      ++reasons[dqo::tracking::reasons_to_string(r.track.quality.reasons)];
    }
    if (o.verbose) {
      const dqo::tracking::TrackQuality& q = r.track.quality;
      std::fprintf(stderr,
                   "frame %4d %-15s inl %4d spread %.2f dense %d rms %.2f ratio %.2f "
                   "disagree %.3f m %.2f deg kf %d %6.2f ms %s\n",
                   i, dqo::tracking::to_string(r.track.state), q.inliers, q.spread, q.dense_ok,
                   q.dense_rms, q.dense_inlier_ratio, q.disagreement_m, q.disagreement_deg,
                   r.track.new_keyframe, r.track.milliseconds,
                   dqo::tracking::reasons_to_string(q.reasons).c_str());
    }
    progress.update(j + 1);
  }

  // The final global adjustment: each frame where its reference keyframe ended up (ORB-SLAM2
  // saves its trajectory so). A tracker restarted by a reset starts a new map: its frames only.
  double final_ba_ms = 0.0;
  int refined = 0;
  if (!o.online && tracker_of_frames != nullptr && tracker_of_frames == session.tracker()) {
    const auto start = std::chrono::steady_clock::now();
    session.tracker()->optimise_map();
    for (const dqo::tracking::CorrectedPose& c : session.tracker()->corrected_frames()) {
      if (c.id < kFrameIdBase || c.id - kFrameIdBase >= estimate.size()) continue;
      estimate[c.id - kFrameIdBase].second = c.T_wc;
      ++refined;
    }
    final_ba_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  }
  if (!dqo::write_tum_trajectory(o.out, estimate, &error)) {
    std::fprintf(stderr, "dqo_track: %s\n", error.c_str());
    return 1;
  }
  if (states.is_open()) {
    states.close();
    if (!states) {
      std::fprintf(stderr, "dqo_track: writing --states %s failed\n", o.states.c_str());
      return 1;
    }
  }
  const dqo::tracking::Tracker* tracker = session.tracker();
  std::printf("frames: %d (tracked %zu, lost %d, not initialised %d, skipped %d)\n", count,
              estimate.size(), lost, not_initialised, skipped);
  std::printf("states: ok %d, degraded %d, lost %d, not_initialised %d\n", ok, degraded, lost,
              not_initialised);
  for (const auto& [why, n] : reasons) {
    std::printf("  %d frames not ok: %s\n", n, why.empty() ? "(not initialised)" : why.c_str());
  }
  std::printf("relocalisations: %d\n", relocalised);
  std::printf("keyframes: %zu tracker, %llu mapping; map points: %zu\n",
              tracker ? tracker->num_keyframes() : size_t{0},
              static_cast<unsigned long long>(session.keyframes()), tracker ? tracker->num_map_points() : size_t{0});
  std::printf("local_ba_runs: %llu\n",
              static_cast<unsigned long long>(tracker ? tracker->local_ba_runs() : 0));
  if (tracker) {
    const dqo::tracking::LoopStats loops = tracker->loop_stats();
    std::printf("loops: %llu closed of %llu keyframes checked, %.1f ms in total\n",
                static_cast<unsigned long long>(loops.closed),
                static_cast<unsigned long long>(loops.queries), loops.milliseconds);
  }
  if (!o.online) std::printf("final global BA: %d frames refined, %.1f ms\n", refined, final_ba_ms);
  std::printf("wrote: %s\n", o.out.c_str());
  if (!o.states.empty()) std::printf("wrote: %s\n", o.states.c_str());
  if (ground_truth.size() >= 3 && estimate.size() >= 3) {
    const auto ate = dqo::eval::compute_ate(estimate, ground_truth, dqo::eval::AteParams{}, &error);
    if (ate) {
      std::printf("ate_rmse_m: %.6f (%d poses; max %.6f)\n", ate->rmse_m, ate->matched, ate->max_m);
    } else {
      std::printf("ate: %s\n", error.c_str());
    }
  }
  std::printf("lost_frames: %d\n", lost);
  std::printf("tracking_ms_median: %.2f\n", median(ms));
  double sum = 0.0;
  for (const double m : ms) sum += m;
  std::printf("tracking_ms_mean: %.2f\n", ms.empty() ? 0.0 : sum / static_cast<double>(ms.size()));
  return 0;
}
