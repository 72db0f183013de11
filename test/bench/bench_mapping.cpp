// bench_mapping: the incremental Gaussian mapper (GaussianTrainer) on a synthetic scene with
// ground-truth poses and instance labels, on the CPU rasteriser. Renders the scene (default
// `tabletop`, with its sensor noise) at a reduced resolution (default 320 wide: fx, fy, cx, cy
// scaled with it), feeds every K-th frame as a keyframe, then renders the map from every keyframe
// and from the held-out frames half-way between keyframes and prints
//   PSNR (against the noisy input and against the clean image), depth L1 on valid pixels (against
//   the noisy input and the clean depth), agreement of the rendered object IDs with the
//   ground-truth instance image on object pixels, seconds per keyframe, Gaussians, bytes each;
//   and where the depth L1 against the input comes from: pixels at depth edges and the others,
//   each with the noise floor (the clean depth's L1 against the noisy input, which no map that
//   does not reproduce the noise can beat).
// --ppm writes per view the render, the input, the ID agreement and the depth error.
//
//   bench_mapping [--scene PATH] [--keyframes N] [--every K] [--iters I] [--width W]
//                 [--threads T] [--no-noise] [--window W] [--stride S] [--ssim L] [--verbose]
//                 [--ppm DIR] [--set NAME=VALUE ...]
//
// --set overrides any numeric GaussianTrainer::Params field by name (see set_param below).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "dqo_map/common/frame_source.h"
#include "dqo_map/gaussians/pixel_labels.h"
#include "dqo_map/gaussians/render_metrics.h"
#include "dqo_map/gaussians/trainer.h"
#include "dqo_map/sim/renderer.h"
#include "dqo_map/sim/scene_loader.h"

namespace {

using dqo::gs::GaussianTrainer;
using dqo::gs::RenderOutput;

// NAME=VALUE for a numeric trainer parameter; false when the name is unknown.
bool set_param(const std::string& assignment, GaussianTrainer::Params* p) {
  const size_t eq = assignment.find('=');
  if (eq == std::string::npos) return false;
  const std::string name = assignment.substr(0, eq);
  const double v = std::atof(assignment.c_str() + eq + 1);
  auto f = [&](const char* n, float* x) {
    return name == n ? (*x = static_cast<float>(v), true) : false;
  };
  auto i = [&](const char* n, int* x) {
    return name == n ? (*x = static_cast<int>(v), true) : false;
  };
  auto b = [&](const char* n, bool* x) { return name == n ? (*x = v != 0.0, true) : false; };
  return f("missing_transmittance", &p->missing_transmittance) ||
         f("depth_error", &p->depth_error) || f("colour_error", &p->colour_error) ||
         f("ins_threshold", &p->ins_threshold) || i("missing_stride", &p->missing_stride) ||
         f("error_sample_rate", &p->error_sample_rate) || f("min_depth", &p->min_depth) ||
         f("max_depth", &p->max_depth) || f("scale_factor", &p->scale_factor) ||
         f("flatness", &p->flatness) || f("max_stretch", &p->max_stretch) ||
         i("normal_radius_px", &p->normal_radius_px) || f("newest_share", &p->newest_share) ||
         b("transparent_for_colour_error", &p->transparent_for_colour_error) ||
         i("iterations", &p->iterations) || i("window", &p->window) ||
         f("lambda_depth", &p->lambda_depth) || f("lambda_ins", &p->lambda_ins) ||
         f("lambda_ssim", &p->lambda_ssim) || b("normalise_depth", &p->normalise_depth) ||
         b("surface_depth", &p->surface_depth) || f("surface_gap", &p->surface_gap) ||
         f("surface_gap_relative", &p->surface_gap_relative) ||
         b("train_per_label", &p->train_per_label) || f("lr_position", &p->adam.lr_position) ||
         f("lr_log_scale", &p->adam.lr_log_scale) || f("lr_rotation", &p->adam.lr_rotation) ||
         f("lr_colour", &p->adam.lr_colour) || f("lr_opacity", &p->adam.lr_opacity) ||
         f("stable_confidence", &p->stable_confidence) ||
         i("max_unstable_age", &p->max_unstable_age) || f("max_scale", &p->max_scale) ||
         i("max_invisible_keyframes", &p->max_invisible_keyframes) ||
         f("min_contribution", &p->min_contribution) ||
         f("relabel_fraction", &p->relabel_fraction) ||
         i("relabel_keyframes", &p->relabel_keyframes);
}

int usage(const char* argv0) {
  std::fprintf(stderr,
               "usage: %s [--scene PATH] [--keyframes N] [--every K] [--iters I] [--width W] "
               "[--threads T] [--no-noise] [--window W] [--stride S] [--ssim L] [--verbose] "
               "[--ppm DIR] [--set NAME=VALUE ...]\n",
               argv0);
  return 2;
}

void write_ppm(const std::string& path, const dqo::ImageRgb8& img) {
  std::ofstream out(path, std::ios::binary);
  out << "P6\n" << img.width << " " << img.height << "\n255\n";
  out.write(reinterpret_cast<const char*>(img.data.data()),
            static_cast<std::streamsize>(img.data.size()));
}

void write_ppm(const std::string& path, const RenderOutput& r) {
  std::ofstream out(path, std::ios::binary);
  out << "P6\n" << r.width << " " << r.height << "\n255\n";
  for (const float v : r.rgb) {
    out.put(static_cast<char>(std::clamp(static_cast<int>(std::lround(v * 255.f)), 0, 255)));
  }
}

// Pixels of a view whose surface (clean depth) some keyframe saw: back-projected, projected into
// every keyframe, and found there within 3 cm of that keyframe's clean depth. Held-out views show
// surfaces that no keyframe saw (disocclusions behind the table); no map can render those.
struct KeyframeView {
  dqo::SE3 T_wc;
  dqo::DepthImage depth;  // clean
};
std::vector<uint8_t> observed_mask(const dqo::PinholeCamera& cam, const dqo::Frame& clean,
                                   const std::vector<KeyframeView>& keyframes) {
  std::vector<uint8_t> mask(clean.depth.data.size(), 0);
  for (int v = 0; v < cam.height; ++v) {
    for (int u = 0; u < cam.width; ++u) {
      const size_t p = static_cast<size_t>(v) * cam.width + u;
      const float d = clean.depth.data[p];
      if (!(d > 0.f)) continue;
      const Eigen::Vector3d p_w = clean.T_wc * cam.back_project(u, v, d);
      for (const KeyframeView& kf : keyframes) {
        const Eigen::Vector3d p_c = kf.T_wc.inverse() * p_w;
        if (p_c.z() <= 0.0) continue;
        const Eigen::Vector2d uv = cam.project(p_c);
        const int ku = static_cast<int>(std::lround(uv.x())),
                  kv = static_cast<int>(std::lround(uv.y()));
        if (ku < 0 || kv < 0 || ku >= cam.width || kv >= cam.height) continue;
        const float dk = kf.depth.at(ku, kv);
        if (dk > 0.f && std::abs(dk - p_c.z()) < 0.03) {
          mask[p] = 1;
          break;
        }
      }
    }
  }
  return mask;
}

// Depth-edge pixels: the clean depth of some 8-neighbour differs by more than max(5 cm, 3 % of
// the depth), the sensor model's edge test (sim/noise.h). Where the depth L1 comes from.
std::vector<uint8_t> depth_edges(const dqo::DepthImage& clean) {
  const int w = clean.width, h = clean.height;
  std::vector<uint8_t> edge(clean.data.size(), 0);
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const float d = clean.at(u, v);
      if (!(d > 0.f)) continue;
      const float jump = std::max(0.05f, 0.03f * d);
      for (int dv = -1; dv <= 1; ++dv) {
        for (int du = -1; du <= 1; ++du) {
          const int uu = u + du, vv = v + dv;
          if (uu < 0 || vv < 0 || uu >= w || vv >= h) continue;
          const float dn = clean.at(uu, vv);
          if (dn > 0.f && std::abs(dn - d) > jump) edge[static_cast<size_t>(v) * w + u] = 1;
        }
      }
    }
  }
  return edge;
}

// Where the depth L1 against the input comes from, summed over views: per pixel class (edge or
// not) the error sum and pixel count; on edges, the error of renders nearer than the input
// (foreground spilling over the background) apart; the floor any map has against the noisy
// input, L1 between the clean and the noisy depth; and the map's own error, against the clean
// depth (signed: its bias) on the same pixels.
struct DepthBreakdown {
  double edge_sum = 0, edge_near_sum = 0, flat_sum = 0, floor_flat = 0, floor_edge = 0;
  double flat_clean = 0, flat_bias = 0, edge_clean = 0;
  double edge_n = 0, valid_n = 0;
  void add(const RenderOutput& r, const dqo::DepthImage& noisy, const dqo::DepthImage& clean) {
    const std::vector<uint8_t> edge = depth_edges(clean);
    for (size_t p = 0; p < noisy.data.size(); ++p) {
      const float d = noisy.data[p];
      if (!std::isfinite(d) || d <= 0.f || !(clean.data[p] > 0.f)) continue;
      const double e = static_cast<double>(r.depth[p]) - d;
      const double e_clean = static_cast<double>(r.depth[p]) - clean.data[p];
      const double floor = std::abs(static_cast<double>(clean.data[p]) - d);
      valid_n += 1;
      if (edge[p]) {
        edge_n += 1;
        edge_sum += std::abs(e);
        if (e < 0.0) edge_near_sum += -e;
        floor_edge += floor;
        edge_clean += std::abs(e_clean);
      } else {
        flat_sum += std::abs(e);
        floor_flat += floor;
        flat_clean += std::abs(e_clean);
        flat_bias += e_clean;
      }
    }
  }
  void print(const char* name) const {
    if (valid_n == 0) return;
    const double k = 100.0 / valid_n;  // cm, as a share of the mean over valid pixels
    std::printf(
        "%-10s depth L1 = %.3f cm non-edge (floor %.3f, vs clean %.3f, bias %+.3f) + %.3f cm on "
        "the %.2f %% edge pixels (floor %.3f, vs clean %.3f, too near %.3f)\n",
        name, k * flat_sum, k * floor_flat, k * flat_clean, k * flat_bias, k * edge_sum,
        edge_n / valid_n * 100, k * floor_edge, k * edge_clean, k * edge_near_sum);
  }
};

struct Metrics {
  double psnr = 0, psnr_clean = 0, depth = 0, depth_clean = 0, ids = 0, psnr_observed = 0,
         unobserved = 0;
  int n = 0, n_ids = 0;
  DepthBreakdown breakdown;
  void add(const RenderOutput& r, const dqo::Frame& noisy, const dqo::Frame& clean,
           const std::vector<uint8_t>& observed) {
    breakdown.add(r, noisy.depth, clean.depth);
    size_t seen = 0;
    for (const uint8_t o : observed) seen += o;
    psnr_observed += dqo::gs::psnr(r, noisy.rgb, observed);
    unobserved += 1.0 - static_cast<double>(seen) / observed.size();
    psnr += dqo::gs::psnr(r, noisy.rgb);
    psnr_clean += dqo::gs::psnr(r, clean.rgb);
    depth += dqo::gs::depth_l1(r, noisy.depth);
    depth_clean += dqo::gs::depth_l1(r, clean.depth);
    const double a = dqo::gs::id_agreement(r, clean.instance);
    if (std::isfinite(a)) {
      ids += a;
      ++n_ids;
    }
    ++n;
  }
  void print(const char* name) const {
    if (n == 0) return;
    std::printf(
        "%-10s %3d views  PSNR %6.2f dB (clean %6.2f)  depth L1 %5.2f cm (clean %5.2f)  "
        "IDs %6.2f %%\n",
        name, n, psnr / n, psnr_clean / n, 100 * depth / n, 100 * depth_clean / n,
        n_ids ? 100 * ids / n_ids : NAN);
    std::printf("%-10s PSNR on surfaces some keyframe saw %6.2f dB (unseen: %.2f %% of pixels)\n",
                "", psnr_observed / n, 100 * unobserved / n);
    breakdown.print("");
  }
};

}  // namespace

int main(int argc, char** argv) {
  std::string scene_path = std::string(DQO_SOURCE_DIR) + "/config/scenes/tabletop.yaml";
  int keyframes = 0;  // 0: as many as the trajectory holds
  int every = 10;
  int width = 320;
  int threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  bool noise = true, verbose = false;
  std::string ppm_dir;
  GaussianTrainer::Params params;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const char* v = i + 1 < argc ? argv[i + 1] : nullptr;
    auto take = [&]() {
      ++i;
      return v;
    };
    if (a == "--no-noise") {
      noise = false;
    } else if (a == "--verbose") {
      verbose = true;
    } else if (!v) {
      return usage(argv[0]);
    } else if (a == "--scene") {
      scene_path = take();
    } else if (a == "--keyframes") {
      keyframes = std::atoi(take());
    } else if (a == "--every") {
      every = std::max(1, std::atoi(take()));
    } else if (a == "--iters") {
      params.iterations = std::atoi(take());
    } else if (a == "--width") {
      width = std::atoi(take());
    } else if (a == "--threads") {
      threads = std::atoi(take());
    } else if (a == "--window") {
      params.window = std::atoi(take());
    } else if (a == "--stride") {
      params.missing_stride = std::atoi(take());
    } else if (a == "--ssim") {
      params.lambda_ssim = static_cast<float>(std::atof(take()));
    } else if (a == "--ppm") {
      ppm_dir = take();
    } else if (a == "--set") {
      if (!set_param(take(), &params)) return usage(argv[0]);
    } else {
      return usage(argv[0]);
    }
  }

  std::string error;
  auto scene = dqo::sim::load_scene(scene_path, {}, &error);
  if (!scene) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return 1;
  }
  scene->camera = dqo::scale_camera(scene->camera, static_cast<double>(width) / scene->camera.width);
  const dqo::sim::Renderer renderer(*scene, threads);
  const int max_keyframes = (renderer.num_frames() + every - 1) / every;
  if (keyframes <= 0 || keyframes > max_keyframes) keyframes = max_keyframes;

  std::printf(
      "bench_mapping: %s, %dx%d, %s, %d keyframes every %d frames, %d iterations, "
      "window %d, stride %d, %d threads\n",
      scene->name.c_str(), scene->camera.width, scene->camera.height, noise ? "noisy" : "clean",
      keyframes, every, params.iterations, params.window, params.missing_stride, threads);

  GaussianTrainer trainer(params, dqo::gs::make_cpu_rasteriser(threads));
  std::vector<double> seconds;
  std::vector<KeyframeView> keyframe_views;
  for (int k = 0; k < keyframes; ++k) {
    const dqo::Frame f = renderer.render(k * every, noise);
    dqo::gs::TrainingKeyframe kf;
    kf.id = static_cast<uint32_t>(k);
    kf.camera = scene->camera;
    kf.T_wc = f.T_wc;
    kf.rgb = f.rgb;
    kf.depth = f.depth;
    kf.labels = dqo::gs::labels_from_instance(f.instance);
    keyframe_views.push_back({f.T_wc, noise ? renderer.render(k * every, false).depth : f.depth});
    const auto r = trainer.add_keyframe(std::move(kf));
    seconds.push_back(r.seconds);
    if (verbose) {
      // The new keyframe and the first one, as rendered now: fit, and what later keyframes did to
      // earlier views.
      RenderOutput now, first;
      trainer.render(scene->camera, f.T_wc, &now);
      trainer.render(scene->camera, renderer.scene().trajectory[0].T_wc, &first);
      const dqo::Frame f0 = renderer.render(0, noise);
      std::printf("        PSNR now %.2f, keyframe 0 %.2f; ", dqo::gs::psnr(now, f.rgb),
                  dqo::gs::psnr(first, f0.rgb));
      std::printf(
          "kf %3d: +%zu missing +%zu error (%zu/%zu px), stable +%zu, relabelled %zu, pruned "
          "%zu/%zu/%zu, "
          "%zu Gaussians (%zu unstable), loss %.4f -> %.4f, %.2f s\n",
          k, r.added_missing, r.added_error, r.missing_pixels, r.error_pixels, r.became_stable,
          r.relabelled, r.pruned_stale, r.pruned_oversized, r.pruned_invisible, r.num_gaussians,
          r.num_unstable, r.loss_first, r.loss_last, r.seconds);
      std::fflush(stdout);
    }
  }

  Metrics on_keyframes, held_out;
  for (int k = 0; k < keyframes; ++k) {
    std::vector<int> frames = {k * every};
    // The held-out frame half-way to the next keyframe (none after the last one).
    if (every >= 2 && k + 1 < keyframes) frames.push_back(k * every + every / 2);
    for (const int frame : frames) {
      if (frame >= renderer.num_frames()) continue;
      const dqo::Frame noisy = renderer.render(frame, noise);
      const dqo::Frame clean = noise ? renderer.render(frame, false) : noisy;
      RenderOutput r;
      trainer.render(scene->camera, noisy.T_wc, &r);
      (frame == k * every ? on_keyframes : held_out)
          .add(r, noisy, clean, observed_mask(scene->camera, clean, keyframe_views));
      if (!ppm_dir.empty()) {
        const std::string n = std::to_string(frame);
        write_ppm(ppm_dir + "/render_" + n + ".ppm", r);
        write_ppm(ppm_dir + "/input_" + n + ".ppm", noisy.rgb);
        // Object pixels: green where the rendered ID agrees, red where the background took it,
        // blue where another object did; grey elsewhere.
        dqo::ImageRgb8 ids(r.width, r.height, 3, 60);
        for (size_t p = 0; p < r.dominant_id.size(); ++p) {
          const uint32_t gt = clean.instance.data[p], got = r.dominant_id[p];
          if (gt == 0) continue;
          ids.data[3 * p] = got == 0 ? 255 : 0;
          ids.data[3 * p + 1] = got == gt ? 255 : 0;
          ids.data[3 * p + 2] = got != gt && got != 0 ? 255 : 0;
        }
        write_ppm(ppm_dir + "/ids_" + n + ".ppm", ids);
        // Depth error against the input: red where the render is nearer, blue where farther, full
        // at 10 cm; depth edges (clean) in green; no measurement black.
        const std::vector<uint8_t> edges = depth_edges(clean.depth);
        dqo::ImageRgb8 err(r.width, r.height, 3, 0);
        for (size_t p = 0; p < r.depth.size(); ++p) {
          const float d = noisy.depth.data[p];
          if (!(d > 0.f)) continue;
          const float e = std::clamp((r.depth[p] - d) / 0.1f, -1.f, 1.f);
          err.data[3 * p] = static_cast<uint8_t>(255.f * std::max(0.f, -e));
          err.data[3 * p + 1] = edges[p] ? 90 : 0;
          err.data[3 * p + 2] = static_cast<uint8_t>(255.f * std::max(0.f, e));
        }
        write_ppm(ppm_dir + "/depth_error_" + n + ".ppm", err);
      }
    }
  }
  std::sort(seconds.begin(), seconds.end());
  double total = 0.0;
  for (const double s : seconds) total += s;
  const auto& map = trainer.map();
  size_t stable = 0;
  for (const uint8_t s : map.stable()) stable += s ? 1 : 0;
  on_keyframes.print("keyframes");
  held_out.print("held-out");
  std::printf("seconds per keyframe: mean %.2f, median %.2f, max %.2f; total %.1f s\n",
              total / seconds.size(), seconds[seconds.size() / 2], seconds.back(), total);
  std::printf("Gaussians: %zu (%zu stable), %.1f bytes each (%zu bytes)\n", map.size(), stable,
              map.empty() ? 0.0 : static_cast<double>(map.bytes_used()) / map.size(),
              map.bytes_used());
  return 0;
}
