// dqo_make_scene: renders a synthetic scene (config/scenes/*.yaml) into a dataset folder, and
// optionally into a rosbag laid out as the Azure Kinect driver records.
//
//   dqo_make_scene SCENE.yaml OUT_DIR [--bag OUT.bag] [--frames N] [--every K] [--seed S]
//                  [--no-noise] [--threads T] [--overwrite] [--gt-tf] [--detector-profile P]
//
// Rendering runs on all cores (the renderer splits each frame into tiles); PNG encoding and bag
// writing run on a second thread behind a short queue, so the two overlap.
#include <atomic>
#include <condition_variable>
#include <functional>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "dqo_map/common/frame_source.h"
#include "dqo_map/common/progress.h"
#include "dqo_map/io/dataset_writer.h"
#include "dqo_map/io/mesh_io.h"
#include "dqo_map/sim/renderer.h"
#include "dqo_map/sim/scene_loader.h"
#ifdef DQO_WITH_ROSBAG
#include "dqo_map/ros/kinect_bag_writer.h"
#endif

namespace {

constexpr char kUsage[] =
    "usage: dqo_make_scene SCENE.yaml OUT_DIR [--bag OUT.bag] [--frames N] [--every K] [--seed S]\n"
    "                      [--scale S] [--no-noise] [--threads T] [--overwrite] [--gt-tf] [--masks]\n"
    "                      [--detector-profile kind|real]\n"
    "  --bag OUT.bag  also write a rosbag in the Azure Kinect driver's layout (ROS builds only)\n"
    "  --frames N     at most N frames (default: the whole trajectory)\n"
    "  --every K      keep every K-th frame of the trajectory (default 1)\n"
    "  --seed S       override the scene's noise seed\n"
    "  --scale S      render at S times the scene's image size (e.g. 0.5: half width and height)\n"
    "  --no-noise     no sensor or detector noise\n"
    "  --detector-profile P  the simulated detector behaves as profile P whatever the scene file\n"
    "                 says of its rates: kind (the default) or real (recall 40 %, 30 % of labels\n"
    "                 flipped within the scene's confusion groups, 10 % false positives, half\n"
    "                 of them on fixed clutter spots); see config/scenes/README.md\n"
    "  --threads T    rendering threads (default: all cores)\n"
    "  --overwrite    replace OUT_DIR if it holds a dataset already\n"
    "  --gt-tf        write the ground-truth map -> camera_base tf into the bag\n"
    "  --masks        attach instance masks to the bag's detections (as a segmenting detector)\n";

struct Options {
  std::string scene;
  std::string out_dir;
  std::string bag;
  int frames = -1;
  int every = 1;
  std::optional<uint64_t> seed;
  bool noise = true;
  int threads = 0;
  double scale = 1.0;
  bool overwrite = false;
  bool gt_tf = false;
  bool masks = false;
  dqo::sim::SceneOverrides overrides;
};

bool parse_int(const char* text, long min, long* out) {
  char* end = nullptr;
  const long v = std::strtol(text, &end, 10);
  if (end == text || *end != '\0' || v < min) return false;
  *out = v;
  return true;
}

std::optional<Options> parse_args(int argc, char** argv) {
  Options o;
  int positional = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* name) -> const char* {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "dqo_make_scene: %s needs a value\n", name);
        return nullptr;
      }
      return argv[++i];
    };
    long n = 0;
    if (a == "-h" || a == "--help") {
      std::fputs(kUsage, stdout);
      std::exit(0);
    } else if (a == "--bag") {
      const char* v = value("--bag");
      if (!v) return std::nullopt;
      o.bag = v;
    } else if (a == "--frames" || a == "--every" || a == "--threads" || a == "--seed") {
      const char* v = value(a.c_str());
      if (!v) return std::nullopt;
      if (!parse_int(v, a == "--seed" || a == "--threads" ? 0 : 1, &n)) {
        std::fprintf(stderr, "dqo_make_scene: %s takes a whole number%s, not '%s'\n", a.c_str(),
                     a == "--seed" || a == "--threads" ? " >= 0" : " >= 1", v);
        return std::nullopt;
      }
      if (a == "--frames") o.frames = static_cast<int>(n);
      if (a == "--every") o.every = static_cast<int>(n);
      if (a == "--threads") o.threads = static_cast<int>(n);
      if (a == "--seed") o.seed = static_cast<uint64_t>(n);
    } else if (a == "--scale") {
      const char* v = value("--scale");
      if (!v) return std::nullopt;
      char* end = nullptr;
      o.scale = std::strtod(v, &end);
      if (end == v || *end != '\0' || !(o.scale > 0.0 && o.scale <= 4.0)) {
        std::fprintf(stderr, "dqo_make_scene: --scale takes a number in (0, 4], not '%s'\n", v);
        return std::nullopt;
      }
    } else if (a == "--detector-profile") {
      const char* v = value("--detector-profile");
      if (!v) return std::nullopt;
      o.overrides.detector_profile = dqo::sim::detector_profile_from_name(v);
      if (!o.overrides.detector_profile) {
        std::fprintf(stderr, "dqo_make_scene: unknown detector profile '%s' (%s)\n", v,
                     dqo::sim::kDetectorProfileNames);
        return std::nullopt;
      }
    } else if (a == "--no-noise") {
      o.noise = false;
    } else if (a == "--overwrite") {
      o.overwrite = true;
    } else if (a == "--gt-tf") {
      o.gt_tf = true;
    } else if (a == "--masks") {
      o.masks = true;
    } else if (!a.empty() && a[0] == '-') {
      std::fprintf(stderr, "dqo_make_scene: unknown option %s\n%s", a.c_str(), kUsage);
      return std::nullopt;
    } else if (positional == 0) {
      o.scene = a, ++positional;
    } else if (positional == 1) {
      o.out_dir = a, ++positional;
    } else {
      std::fprintf(stderr, "dqo_make_scene: unexpected argument %s\n%s", a.c_str(), kUsage);
      return std::nullopt;
    }
  }
  if (positional != 2) {
    std::fputs(kUsage, stderr);
    return std::nullopt;
  }
#ifndef DQO_WITH_ROSBAG
  if (!o.bag.empty()) {
    std::fprintf(stderr, "dqo_make_scene: --bag needs the ROS build of dqo_map (this one has no rosbag)\n");
    return std::nullopt;
  }
#endif
  return o;
}

// Frames rendered on the main thread, written on this one.
class FrameSink {
 public:
  using WriteFn = std::function<bool(const dqo::Frame&, std::string*)>;
  explicit FrameSink(WriteFn write) : write_(std::move(write)), worker_([this] { run(); }) {}
  ~FrameSink() { finish(); }

  // False once a write has failed (the error is kept).
  bool push(dqo::Frame frame) {
    std::unique_lock<std::mutex> lock(mutex_);
    space_.wait(lock, [&] { return queue_.size() < kMaxQueue || failed_; });
    if (failed_) return false;
    queue_.push_back(std::move(frame));
    ready_.notify_one();
    return true;
  }

  // Waits for the queue to drain; true when every frame was written.
  bool finish() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      done_ = true;
    }
    ready_.notify_one();
    if (worker_.joinable()) worker_.join();
    return !failed_;
  }
  const std::string& error() const { return error_; }
  int written() const { return written_; }

 private:
  static constexpr size_t kMaxQueue = 4;

  void run() {
    for (;;) {
      dqo::Frame frame;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        ready_.wait(lock, [&] { return !queue_.empty() || done_; });
        if (queue_.empty()) return;
        frame = std::move(queue_.front());
        queue_.pop_front();
      }
      space_.notify_one();
      std::string error;
      if (!write_(frame, &error)) {
        std::lock_guard<std::mutex> lock(mutex_);
        failed_ = true;
        error_ = error;
        queue_.clear();
        space_.notify_all();
        return;
      }
      ++written_;
    }
  }

  WriteFn write_;
  std::mutex mutex_;
  std::condition_variable ready_, space_;
  std::deque<dqo::Frame> queue_;
  bool done_ = false;
  bool failed_ = false;
  std::string error_;
  std::atomic<int> written_{0};
  std::thread worker_;
};

}  // namespace

int main(int argc, char** argv) {
  const auto opt = parse_args(argc, argv);
  if (!opt) return 2;

  std::string error;
  auto scene = dqo::sim::load_scene(opt->scene, &dqo::load_mesh, &error, opt->overrides);
  if (!scene) {
    std::fprintf(stderr, "dqo_make_scene: %s\n", error.c_str());
    return 1;
  }
  if (opt->seed) scene->seed = *opt->seed;
  // The scene rendered by a camera of another resolution (same field of view): a quicker world.
  if (opt->scale != 1.0) scene->camera = dqo::scale_camera(scene->camera, opt->scale);
  const dqo::sim::Renderer renderer(*scene, opt->threads);

  std::vector<int> indices;
  for (int i = 0; i < renderer.num_frames(); i += opt->every) {
    if (opt->frames >= 0 && static_cast<int>(indices.size()) >= opt->frames) break;
    indices.push_back(i);
  }
  const bool noisy = opt->noise && scene->noise.enabled;
  std::fprintf(stderr, "dqo_make_scene: scene '%s': %zu objects, %dx%d, %zu of %d frames, noise %s, "
               "detector %s, %d threads\n",
               scene->name.c_str(), scene->objects.size(), scene->camera.width, scene->camera.height,
               indices.size(), renderer.num_frames(), noisy ? "on" : "off",
               noisy ? dqo::sim::detector_profile_name(scene->noise.detection.profile) : "exact",
               renderer.threads());
  if (opt->overrides.detector_profile && !noisy) {
    std::fprintf(stderr, "dqo_make_scene: warning: --detector-profile has no effect: %s\n",
                 opt->noise ? "the scene's noise is off" : "--no-noise");
  }

  dqo::DatasetWriter::Params writer_params;
  writer_params.overwrite = opt->overwrite;
  dqo::DatasetWriter writer(opt->out_dir, writer_params);
  const dqo::DatasetInfo info = renderer.info();
  if (!writer.write_info(info, &error)) {
    std::fprintf(stderr, "dqo_make_scene: %s\n", error.c_str());
    return 1;
  }

#ifdef DQO_WITH_ROSBAG
  std::unique_ptr<dqo::ros_bridge::KinectBagWriter> bag;
  if (!opt->bag.empty()) {
    dqo::ros_bridge::KinectBagOptions bag_options;
    bag_options.ground_truth_tf = opt->gt_tf;
    bag_options.instance_masks = opt->masks;
    bag = dqo::ros_bridge::KinectBagWriter::open(opt->bag, info, bag_options, &error);
    if (!bag) {
      writer.abort();
      std::fprintf(stderr, "dqo_make_scene: %s\n", error.c_str());
      return 1;
    }
  }
#endif

  FrameSink sink([&](const dqo::Frame& frame, std::string* err) {
#ifdef DQO_WITH_ROSBAG
    if (bag && !bag->write(frame, err)) return false;
#endif
    return writer.write_frame(frame, err);
  });

  dqo::ProgressBar progress("rendering", static_cast<int>(indices.size()));
  bool ok = true;
  for (size_t k = 0; k < indices.size() && ok; ++k) {
    dqo::Frame frame = renderer.render(indices[k], opt->noise);
    frame.index = static_cast<int>(k);  // the dataset numbers the frames it holds 0, 1, 2, ...
    ok = sink.push(std::move(frame));
    progress.update(static_cast<int>(k + 1));
  }
  ok = sink.finish() && ok;
#ifdef DQO_WITH_ROSBAG
  if (bag) bag->close();
#endif
  if (!ok || !writer.finish(&error)) {
    if (error.empty()) error = sink.error();
    writer.abort();
#ifdef DQO_WITH_ROSBAG
    if (!opt->bag.empty()) std::filesystem::remove(opt->bag);
#endif
    std::fprintf(stderr, "dqo_make_scene: failed, nothing written: %s\n", error.c_str());
    return 1;
  }
  std::fprintf(stderr, "dqo_make_scene: wrote %d frames to %s%s%s in %.1f s (%.1f frames/s)\n",
               sink.written(), opt->out_dir.c_str(), opt->bag.empty() ? "" : " and ", opt->bag.c_str(),
               progress.seconds(), sink.written() / std::max(progress.seconds(), 1e-9));
  return 0;
}
