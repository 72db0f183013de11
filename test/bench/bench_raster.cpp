// bench_raster: forward and backward milliseconds of the CPU rasteriser for random Gaussians in
// view, at 320x240 and 640x480, with 1 and 2 threads (or the counts given), and the map's bytes per
// Gaussian. Gaussians: means uniform over the view at depths 1-5 m, log-uniform scales of 0.5-4 cm
// (the sizes a SLAM map of a room holds), random rotations and colours, opacity 0.9 (OG).
//
//   bench_raster [--counts 10000,100000] [--threads 1,2] [--repeats 5]
//
// On a given map (the comparison maps of ../shared/bench: room_gaussians.py N OUT.ply writes the
// PLY and OUT.camera.txt), the median of --repeats runs after 10 warm-ups, of the backend's forward
// (and, on the CPU, backward) — what gsplat_bench.py times on the same files:
//
//   bench_raster --map MAP.ply --camera MAP.camera.txt [--backend cpu|cuda] [--repeats 50] [--threads T]
//
// The mapping step's cost as the map grows (issue 12): with --keyframes K, the map is the
// trainer's and K + 1 keyframes rendered from it (from poses 2 cm and 0.5° apart around the
// camera) go through GaussianTrainer::add_keyframe with the default parameters (the first one
// warms up); the median milliseconds of the step and of its parts:
//
//   bench_raster --map MAP.ply --camera MAP.camera.txt --backend cuda --keyframes 5
//
// With --extend-to N as well, the map grows to N Gaussians by copies of itself placed behind the
// camera (8 m apart along its axis, out of every keyframe's view): the view's work stays that of
// MAP while the map grows, as when a robot maps room after room (the flat update: only
// what a keyframe sees trains).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "dqo_map/common/text_util.h"
#include "dqo_map/gaussians/gaussian_ply.h"
#include "dqo_map/gaussians/rasteriser.h"
#include "dqo_map/gaussians/trainer.h"
#ifdef DQO_BENCH_CUDA
#include "dqo_map/cuda/cuda_rasteriser.h"
#include "dqo_map/cuda/cuda_backend.h"
#include "dqo_map/cuda/cuda_training_engine.h"
#endif
#include <fstream>
#include <map>

namespace dqo::gs {
namespace {

std::vector<int> parse_list(const char* s) {
  std::vector<int> out;
  for (const std::string& item : text::split_list(s)) out.push_back(std::atoi(item.c_str()));
  return out;
}

PinholeCamera camera(int width, int height) {
  PinholeCamera c;
  c.width = width;
  c.height = height;
  c.fx = c.fy = 0.8 * width;  // ~64° horizontal field of view
  c.cx = 0.5 * (width - 1);
  c.cy = 0.5 * (height - 1);
  return c;
}

// Random Gaussians in the view of a 4:3 camera with fx = 0.8 width (any resolution sees the same).
GaussianMap random_map(size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  GaussianMap map;
  map.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    const double z = 1.0 + 4.0 * u01(rng);
    GaussianInit g;
    g.position = Eigen::Vector3f((u01(rng) - 0.5) / 0.8 * z, (u01(rng) - 0.5) * 0.75 / 0.8 * z, z);
    for (int k = 0; k < 3; ++k) g.log_scale[k] = std::log(0.005) + std::log(8.0) * u01(rng);
    g.rotation = Eigen::Vector4f(u01(rng) - 0.5, u01(rng) - 0.5, u01(rng) - 0.5, u01(rng) - 0.5);
    g.colour = Eigen::Vector3f(u01(rng), u01(rng), u01(rng));
    g.object_id = static_cast<uint32_t>(i % 8);
    map.add(g);
  }
  return map;
}

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// CPU time of the process (all threads), ms: on a shared machine it shows the work done where the
// wall time also shows the waiting for a core.
double cpu_ms() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

}  // namespace
}  // namespace dqo::gs

namespace dqo::gs {
namespace {

// room_gaussians.py's camera file: `key value` lines, T_cw as 12 numbers (3x4, row-major).
bool read_camera_file(const std::string& path, PinholeCamera* cam, SE3* T_cw, std::string* error) {
  std::ifstream in(path);
  if (!in) {
    *error = "cannot read " + path;
    return false;
  }
  std::map<std::string, double> v;
  std::vector<double> T;
  std::string line;
  while (std::getline(in, line)) {
    std::stringstream ss(line.substr(0, line.find('#')));
    std::string key;
    if (!(ss >> key)) continue;
    if (key == "T_cw") {
      double x;
      while (ss >> x) T.push_back(x);
    } else {
      ss >> v[key];
    }
  }
  for (const char* key : {"width", "height", "fx", "fy", "cx", "cy"}) {
    if (!v.count(key)) {
      *error = path + ": no " + key;
      return false;
    }
  }
  if (T.size() != 12) {
    *error = path + ": T_cw needs 12 numbers";
    return false;
  }
  *cam = PinholeCamera{v["fx"], v["fy"], v["cx"], v["cy"], static_cast<int>(v["width"]), static_cast<int>(v["height"])};
  Eigen::Matrix3d R;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) R(r, c) = T[4 * r + c];
  *T_cw = SE3::from_rotation_translation(R, Eigen::Vector3d(T[3], T[7], T[11]));
  return true;
}

double median_of(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}


// The mapping step on a map of the given size (--keyframes): see the header.
int bench_keyframes(const GaussianMap& map, const PinholeCamera& cam, const SE3& T_cw, const std::string& backend,
                    int keyframes, int threads) {
  std::unique_ptr<Rasteriser> rasteriser, truth_renderer;
  std::unique_ptr<TrainingEngine> engine;
  if (backend == "cuda") {
#ifdef DQO_BENCH_CUDA
    cuda::CudaBackend gpu = cuda::make_cuda_backend();  // as the mapping stage makes it
    rasteriser = std::move(gpu.rasteriser);
    engine = std::move(gpu.engine);
    truth_renderer = cuda::make_cuda_rasteriser();
#else
    std::fprintf(stderr, "bench_raster: this build has no CUDA backend\n");
    return 1;
#endif
  } else {
    rasteriser = make_cpu_rasteriser(threads);
    truth_renderer = make_cpu_rasteriser(threads);
  }
  GaussianTrainer trainer(GaussianTrainer::Params{}, std::move(rasteriser), std::move(engine));
  trainer.set_map(map);
  std::vector<double> total, review, add, train, prune;
  size_t size_after = 0;
  for (int k = 0; k <= keyframes; ++k) {
    TrainingKeyframe kf;
    kf.id = static_cast<uint32_t>(k + 1);
    kf.camera = cam;
    const SE3 step(Eigen::Quaterniond(Eigen::AngleAxisd(0.0087 * k, Eigen::Vector3d::UnitY())),
                   Eigen::Vector3d(0.02 * k, 0.0, 0.0));
    kf.T_wc = T_cw.inverse() * step;
    RenderSettings s;
    s.normalise_depth = true;
    RenderOutput out;
    truth_renderer->forward(map, cam, kf.T_wc.inverse(), s, &out, nullptr);
    const size_t pixels = out.alpha.size();
    kf.rgb = ImageRgb8(cam.width, cam.height, 3, 0);
    kf.depth = DepthImage(cam.width, cam.height, 1, 0.f);
    kf.labels = LabelImage(cam.width, cam.height, 1, 0u);
    for (size_t p = 0; p < pixels; ++p) {
      for (int c = 0; c < 3; ++c)
        kf.rgb.data[3 * p + c] = static_cast<uint8_t>(std::lround(255.f * std::clamp(out.rgb[3 * p + c], 0.f, 1.f)));
      kf.depth.data[p] = out.alpha[p] > 0.5f ? out.depth[p] : 0.f;
      kf.labels.data[p] = out.dominant_id[p];
    }
    const KeyframeReport r = trainer.add_keyframe(std::move(kf));
    if (k == 0) continue;  // warm-up
    total.push_back(r.seconds * 1e3), review.push_back(r.review_ms), add.push_back(r.add_ms);
    train.push_back(r.train_ms), prune.push_back(r.prune_ms);
    size_after = r.num_gaussians;
  }
  const size_t device_bytes = trainer.engine() ? trainer.engine()->device_bytes() : 0;
  std::printf("keyframe update, %zu Gaussians (%zu after), %dx%d, backend %s, %s, median of %d: %.1f ms "
              "(review %.1f, add %.1f, train %.1f for %d iterations, prune %.1f); engine device memory %.0f MB "
              "(%.0f bytes per Gaussian with the window's %zu keyframes)\n",
              map.size(), size_after, cam.width, cam.height, backend.c_str(),
              trainer.uses_engine() ? "training engine" : "host iterations", keyframes, median_of(total),
              median_of(review), median_of(add), median_of(train), trainer.params().iterations, median_of(prune),
              device_bytes / 1e6, size_after ? static_cast<double>(device_bytes) / size_after : 0.0,
              trainer.keyframes_stored());
  return 0;
}

// `map` grown to n Gaussians by copies of itself behind the camera (--extend-to).
GaussianMap extended(const GaussianMap& map, const SE3& T_cw, size_t n) {
  GaussianMap out = map;
  if (map.empty() || n <= map.size()) return out;
  out.reserve(n);
  // The camera's axis in the world; the copies start 8 m behind the camera (the map's own extent
  // in front of it is under 8 m: room_gaussians.py's room is 6 × 5 × 2.8 m).
  const SE3 T_wc = T_cw.inverse();
  const Eigen::Vector3f back = -T_wc.rotation().col(2).cast<float>();
  for (int copy = 1; out.size() < n; ++copy) {
    const Eigen::Vector3f shift = (8.f * copy + 8.f) * back;
    for (size_t i = 0; i < map.size() && out.size() < n; ++i) {
      GaussianInit g = map.gaussian(i);
      g.position += shift;
      out.add(g);
    }
  }
  return out;
}

int bench_map(const std::string& map_path, const std::string& camera_path, const std::string& backend, int repeats,
              int threads, int keyframes, size_t extend_to) {
  std::string error;
  const auto map = load_gaussians_ply(map_path, &error);
  PinholeCamera cam;
  SE3 T_cw;
  if (!map || !read_camera_file(camera_path, &cam, &T_cw, &error)) {
    std::fprintf(stderr, "bench_raster: %s\n", error.c_str());
    return 1;
  }
  if (keyframes > 0) {
    if (extend_to > map->size()) {
      const GaussianMap grown = extended(*map, T_cw, extend_to);
      std::printf("map extended to %zu Gaussians: %zu in view, the rest in copies behind the camera\n", grown.size(),
                  map->size());
      return bench_keyframes(grown, cam, T_cw, backend, keyframes, threads);
    }
    return bench_keyframes(*map, cam, T_cw, backend, keyframes, threads);
  }
  if (extend_to > 0) {
    std::fprintf(stderr, "bench_raster: --extend-to goes with --keyframes\n");
    return 2;
  }
  std::unique_ptr<Rasteriser> r;
  if (backend == "cpu") {
    r = make_cpu_rasteriser(threads);
  } else if (backend == "cuda") {
#ifdef DQO_BENCH_CUDA
    r = cuda::make_cuda_rasteriser();
#else
    std::fprintf(stderr, "bench_raster: this build has no CUDA backend\n");
    return 1;
#endif
  } else {
    std::fprintf(stderr, "bench_raster: --backend is cpu or cuda, not %s\n", backend.c_str());
    return 2;
  }
  RenderSettings settings;  // expected depth, as gsplat_bench.py renders
  const bool with_backward = true;
  const int warmups = backend == "cpu" ? 1 : 10;
  std::vector<double> fwd, bwd, upload, project, bin, composite, download, backward_gpu;
  size_t pairs = 0;
  RenderOutput out;
  for (int i = 0; i < warmups + repeats; ++i) {
    std::unique_ptr<RenderState> state;
    const auto t0 = std::chrono::steady_clock::now();
    // (timings of the forward are read after the backward below: both are in the same struct)
    r->forward(*map, cam, T_cw, settings, &out, with_backward ? &state : nullptr);
    const auto t1 = std::chrono::steady_clock::now();
    if (with_backward) {
      OutputGradients g;
      g.rgb.assign(out.rgb.size(), 1e-3f);
      g.depth.assign(out.depth.size(), 1e-3f);
      MapGradients grad;
      r->backward(*map, cam, T_cw, settings, *state, g, &grad);
    }
    const auto t2 = std::chrono::steady_clock::now();
    if (i >= warmups) {
      fwd.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
      bwd.push_back(std::chrono::duration<double, std::milli>(t2 - t1).count());
#ifdef DQO_BENCH_CUDA
      if (const auto t = cuda::last_forward_timings(*r)) {
        upload.push_back(t->upload_ms), project.push_back(t->project_ms), bin.push_back(t->bin_ms);
        composite.push_back(t->composite_ms), download.push_back(t->download_ms), pairs = t->pairs;
        backward_gpu.push_back(t->backward_ms);
      }
#endif
    }
  }
  size_t covered = 0;
  for (float a : out.alpha) covered += a > 0.5f;
  std::printf("%s: %zu Gaussians, %dx%d, backend %s, median of %d: forward %.2f ms wall (upload of the map and "
              "download of the images included)%s; coverage %.3f\n",
              map_path.c_str(), map->size(), cam.width, cam.height, backend.c_str(), repeats, median_of(fwd),
              with_backward ? (", backward " + std::to_string(median_of(bwd)) + " ms wall (gradients downloaded)").c_str() : "",
              static_cast<double>(covered) / out.alpha.size());
  if (!upload.empty()) {
    std::printf("  GPU time (CUDA events, medians): upload %.2f ms, projection %.3f ms, binning %.3f ms (%zu pairs), "
                "compositing %.3f ms, download %.2f ms; forward on the device %.3f ms; backward on the device %.3f ms; "
                "forward + backward on the device %.3f ms\n",
                median_of(upload), median_of(project), median_of(bin), pairs, median_of(composite),
                median_of(download), median_of(project) + median_of(bin) + median_of(composite), median_of(backward_gpu),
                median_of(project) + median_of(bin) + median_of(composite) + median_of(backward_gpu));
  }
  return 0;
}

}  // namespace
}  // namespace dqo::gs

int main(int argc, char** argv) {
  using namespace dqo;
  using namespace dqo::gs;
  std::vector<int> counts = {10000, 100000}, threads = {1, 2};
  int repeats = 5;
  std::string map_path, camera_path, backend = "cpu";
  bool repeats_given = false;
  int keyframes = 0;
  size_t extend_to = 0;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--map"))
      map_path = argv[i + 1];
    else if (!std::strcmp(argv[i], "--camera"))
      camera_path = argv[i + 1];
    else if (!std::strcmp(argv[i], "--backend"))
      backend = argv[i + 1];
    else if (!std::strcmp(argv[i], "--counts"))
      counts = parse_list(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--threads"))
      threads = parse_list(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--keyframes"))
      keyframes = std::max(0, std::atoi(argv[i + 1]));
    else if (!std::strcmp(argv[i], "--extend-to"))
      extend_to = static_cast<size_t>(std::max(0.0, std::atof(argv[i + 1])));
    else if (!std::strcmp(argv[i], "--repeats"))
      repeats = std::max(1, std::atoi(argv[i + 1])), repeats_given = true;
    else {
      std::fprintf(stderr,
                   "usage: bench_raster [--counts A,B] [--threads A,B] [--repeats N]\n"
                   "       bench_raster --map MAP.ply --camera MAP.camera.txt [--backend cpu|cuda] [--repeats N]\n"
                   "                    [--keyframes K [--extend-to N]]\n");
      return 2;
    }
  }
  if (!map_path.empty() || !camera_path.empty()) {
    if (map_path.empty() || camera_path.empty()) {
      std::fprintf(stderr, "bench_raster: --map and --camera go together\n");
      return 2;
    }
    return bench_map(map_path, camera_path, backend, repeats_given ? repeats : 50, threads.empty() ? 0 : threads[0],
                     keyframes, extend_to);
  }
  const int sizes[][2] = {{320, 240}, {640, 480}};
  std::printf("CPU rasteriser, median of %d runs (ms); loss gradient on rgb, depth and ins\n",
              repeats);
  std::printf("%9s %9s %7s %10s %10s %10s %12s %12s %9s\n", "gaussians", "image", "threads",
              "forward", "backward", "fwd+bwd", "fwd cpu-ms", "bwd cpu-ms", "coverage");
  for (int n : counts) {
    const GaussianMap map = random_map(static_cast<size_t>(n), 1);
    for (const auto& wh : sizes) {
      const PinholeCamera cam = camera(wh[0], wh[1]);
      RenderSettings settings;
      settings.ins_object = 3;
      for (int t : threads) {
        auto r = make_cpu_rasteriser(t);
        std::vector<double> fwd, bwd, fwd_cpu, bwd_cpu;
        double coverage = 0.0;
        for (int rep = 0; rep < repeats + 1; ++rep) {
          RenderOutput out;
          std::unique_ptr<RenderState> state;
          double c0 = cpu_ms();
          auto t0 = std::chrono::steady_clock::now();
          r->forward(map, cam, SE3(), settings, &out, &state);
          const double f_ms = ms_since(t0), f_cpu = cpu_ms() - c0;
          OutputGradients og;
          og.rgb.assign(out.rgb.size(), 1e-3f);
          og.depth.assign(out.depth.size(), -1e-3f);
          og.ins.assign(out.ins.size(), 1e-3f);
          MapGradients g;
          g.resize_for(map);
          c0 = cpu_ms();
          t0 = std::chrono::steady_clock::now();
          r->backward(map, cam, SE3(), settings, *state, og, &g);
          const double b_ms = ms_since(t0), b_cpu = cpu_ms() - c0;
          if (rep == 0) {  // warm-up
            double s = 0.0;
            for (float a : out.alpha) s += a;
            coverage = s / out.alpha.size();
            continue;
          }
          fwd.push_back(f_ms);
          bwd.push_back(b_ms);
          fwd_cpu.push_back(f_cpu);
          bwd_cpu.push_back(b_cpu);
        }
        auto median = [](std::vector<double> v) {
          std::sort(v.begin(), v.end());
          return v[v.size() / 2];
        };
        const double f = median(fwd), b = median(bwd);
        char image[32];
        std::snprintf(image, sizeof image, "%dx%d", wh[0], wh[1]);
        std::printf("%9d %9s %7d %10.1f %10.1f %10.1f %12.1f %12.1f %9.3f\n", n, image, t, f, b,
                    f + b, median(fwd_cpu), median(bwd_cpu), coverage);
      }
    }
    std::printf("%9d Gaussians: %.1f bytes per Gaussian (map.bytes_used() / size)\n", n,
                double(map.bytes_used()) / map.size());
  }
  return 0;
}
