// bench_sim: rendering speed of the synthetic world. Renders the first N frames of a scene (default
// `tabletop`, 640x480, with its noise) and prints frames per second (median over the frames) and
// the per-frame time in ms (median, min, max), plus the ray rate. Optionally writes the frames as
// PPM/PGM images for a look (RGB, depth in mm as 16-bit PGM, instance IDs as 16-bit PGM).
//
//   bench_sim [--scene PATH] [--frames N] [--threads T] [--no-noise] [--warmup K]
//             [--ppm DIR] [--every K]

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "dqo_map/common/statistics.h"
#include "dqo_map/sim/renderer.h"
#include "dqo_map/sim/scene_loader.h"

namespace {

using dqo::median;

void write_ppm(const std::string& path, const dqo::ImageRgb8& img) {
  std::ofstream out(path, std::ios::binary);
  out << "P6\n" << img.width << " " << img.height << "\n255\n";
  out.write(reinterpret_cast<const char*>(img.data.data()),
            static_cast<std::streamsize>(img.data.size()));
}

void write_pgm16(const std::string& path, int w, int h, const std::vector<uint16_t>& v) {
  std::ofstream out(path, std::ios::binary);
  out << "P5\n" << w << " " << h << "\n65535\n";
  for (const uint16_t x : v) {
    const char b[2] = {static_cast<char>(x >> 8), static_cast<char>(x & 0xff)};  // big-endian
    out.write(b, 2);
  }
}

int usage(const char* argv0) {
  std::fprintf(stderr,
               "usage: %s [--scene PATH] [--frames N] [--threads T] [--no-noise] [--warmup K] "
               "[--ppm DIR] [--every K]\n",
               argv0);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::string scene_path = std::string(DQO_SOURCE_DIR) + "/config/scenes/tabletop.yaml";
  int frames = 60;
  int threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  int warmup = 2;
  bool noise = true;
  std::string ppm_dir;
  int every = 1;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> const char* { return i + 1 < argc ? argv[++i] : nullptr; };
    const char* v = nullptr;
    if (a == "--no-noise") {
      noise = false;
    } else if ((a == "--scene" || a == "--frames" || a == "--threads" || a == "--ppm" ||
                a == "--every" || a == "--warmup") &&
               (v = value()) != nullptr) {
      if (a == "--scene") scene_path = v;
      if (a == "--frames") frames = std::atoi(v);
      if (a == "--threads") threads = std::atoi(v);
      if (a == "--ppm") ppm_dir = v;
      if (a == "--every") every = std::max(1, std::atoi(v));
      if (a == "--warmup") warmup = std::max(0, std::atoi(v));
    } else {
      return usage(argv[0]);
    }
  }

  std::string error;
  const auto t_load = std::chrono::steady_clock::now();
  const std::optional<dqo::sim::Scene> scene = dqo::sim::load_scene(scene_path, {}, &error);
  if (!scene) {
    std::fprintf(stderr, "bench_sim: %s\n", error.c_str());
    return 1;
  }
  const double load_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_load).count();
  const dqo::sim::Renderer renderer(*scene, threads);
  frames = std::min(frames, renderer.num_frames());
  const int w = scene->camera.width, h = scene->camera.height;
  std::printf("scene %s (%s): %dx%d, %zu objects, %zu background surfaces, loaded in %.1f ms\n",
              scene->name.c_str(), scene_path.c_str(), w, h, scene->objects.size(),
              scene->background.size(), load_ms);
  std::printf("rendering %d frames (after %d warm-up) with %d thread(s), noise %s\n", frames,
              warmup, threads, noise ? "on" : "off");

  for (int i = 0; i < std::min(warmup, frames); ++i) renderer.render(i, noise);
  std::vector<double> ms;
  double visible_sum = 0.0;
  size_t detections = 0;
  for (int i = 0; i < frames; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    const dqo::Frame f = renderer.render(i, noise);
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    visible_sum += static_cast<double>(f.objects.size());
    detections += f.detections.size();
    if (!ppm_dir.empty() && i % every == 0) {
      char name[64];
      std::snprintf(name, sizeof(name), "/%06d", i);
      write_ppm(ppm_dir + name + "_rgb.ppm", f.rgb);
      std::vector<uint16_t> depth_mm(f.depth.data.size());
      for (size_t k = 0; k < depth_mm.size(); ++k) {
        depth_mm[k] =
            static_cast<uint16_t>(std::clamp(std::lround(f.depth.data[k] * 1000.0f), 0L, 65535L));
      }
      write_pgm16(ppm_dir + name + "_depth.pgm", w, h, depth_mm);
      write_pgm16(ppm_dir + name + "_instance.pgm", w, h, f.instance.data);
    }
  }
  const double med = median(ms);
  std::printf("per frame: median %.2f ms, min %.2f ms, max %.2f ms\n", med,
              *std::min_element(ms.begin(), ms.end()), *std::max_element(ms.begin(), ms.end()));
  std::printf("frames/s (median): %.1f   rays/s: %.2f M (%.2f M per thread)\n", 1000.0 / med,
              w * h / med / 1000.0, w * h / med / 1000.0 / threads);
  std::printf("visible objects per frame: %.2f, detections per frame: %.2f\n",
              visible_sum / std::max(1, frames),
              static_cast<double>(detections) / std::max(1, frames));
  return 0;
}
