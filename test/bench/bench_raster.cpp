// bench_raster: forward and backward milliseconds of the CPU rasteriser for random Gaussians in
// view, at 320x240 and 640x480, with 1 and 2 threads (or the counts given), and the map's bytes per
// Gaussian. Gaussians: means uniform over the view at depths 1-5 m, log-uniform scales of 0.5-4 cm
// (the sizes a SLAM map of a room holds), random rotations and colours, opacity 0.9 (OG).
//
//   bench_raster [--counts 10000,100000] [--threads 1,2] [--repeats 5]

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

#include "dqo_map/gaussians/rasteriser.h"

namespace dqo::gs {
namespace {

std::vector<int> parse_list(const char* s) {
  std::vector<int> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(std::atoi(item.c_str()));
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

int main(int argc, char** argv) {
  using namespace dqo;
  using namespace dqo::gs;
  std::vector<int> counts = {10000, 100000}, threads = {1, 2};
  int repeats = 5;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--counts"))
      counts = parse_list(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--threads"))
      threads = parse_list(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--repeats"))
      repeats = std::max(1, std::atoi(argv[i + 1]));
    else {
      std::fprintf(stderr, "usage: bench_raster [--counts A,B] [--threads A,B] [--repeats N]\n");
      return 2;
    }
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
