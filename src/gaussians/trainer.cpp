#include "dqo_map/gaussians/trainer.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>
#include <utility>

#include "compaction.h"
#include "dqo_map/gaussians/math/prune.h"
#include "dqo_map/gaussians/math/review.h"
#include "parallel.h"

namespace dqo::gs {
namespace {

bool valid_depth(float d) { return std::isfinite(d) && d > 0.f; }

// Rotation (w, x, y, z) whose columns are the given orthonormal, right-handed axes.
Eigen::Vector4f quaternion_of(const Eigen::Matrix3d& R) {
  const Eigen::Quaterniond q(R);
  return Eigen::Vector4f(static_cast<float>(q.w()), static_cast<float>(q.x()),
                         static_cast<float>(q.y()), static_cast<float>(q.z()));
}

}  // namespace

GaussianTrainer::GaussianTrainer(const Params& params, std::unique_ptr<Rasteriser> rasteriser,
                                 std::unique_ptr<TrainingEngine> engine)
    : params_(params),
      rasteriser_(rasteriser ? std::move(rasteriser) : make_cpu_rasteriser(0)),
      engine_(std::move(engine)),
      adam_(params.adam),
      rng_(params.seed) {
  // The engine keeps the optimiser's moments on its device; the host's would only be compacted.
  if (uses_engine()) adam_.keep_moments_on_host(false);
}

bool GaussianTrainer::uses_engine() const {
  return engine_ && params_.lambda_ssim <= 0.f && !params_.train_per_label && params_.adam.lr_opacity <= 0.f;
}

RenderSettings GaussianTrainer::settings(uint32_t ins_object, bool for_render) const {
  RenderSettings s;
  s.normalise_depth = params_.normalise_depth;
  s.surface_depth = params_.surface_depth && for_render;
  s.surface_gap = params_.surface_gap;
  s.surface_gap_relative = params_.surface_gap_relative;
  s.ins_object = ins_object;
  return s;
}

void GaussianTrainer::render(const PinholeCamera& camera, const SE3& T_wc, RenderOutput* out,
                             uint32_t ins_object) {
  sync_engine();
  rasteriser_->forward(map_, camera, T_wc.inverse(), settings(ins_object, true), out, nullptr);
}

void GaussianTrainer::sync_engine() {
  // Only where the engine runs the iterations: the host then never changes the attributes behind
  // its back (the host loop would, and the engine's copy would show a stale map).
  if (!uses_engine() || map_.empty()) return;
  sync_state();
  engine_->sync(map_, adam_);
  // A render of a map the engine does not hold (it could not take the appended Gaussians: out of
  // memory) sends the host's: deferred attributes come down first.
  if (attributes_on_device_ && !engine_->holds(map_)) fetch_attributes();
}

const GaussianMap& GaussianTrainer::map() const {
  fetch_attributes();
  return map_;
}

void GaussianTrainer::fetch_counters() {
  if (!counters_on_device_) return;
  sync_state();
  engine_->fetch_review_counters(usefulness_.data(), invisible_count_.data(), relabel_votes_.data());
  counters_on_device_ = false;
}

void GaussianTrainer::fetch_attributes() const {
  if (!attributes_on_device_) return;
  // map_ is not a const object: only this trainer's const view of it is.
  engine_->fetch_attributes(const_cast<GaussianMap*>(&map_));
  attributes_on_device_ = false;
}

void GaussianTrainer::sync_state() {
  adam_.resize_for(map_);
  invisible_count_.resize(map_.size(), 0);
  relabel_votes_.resize(map_.size(), 0);
  usefulness_.resize(map_.size(), std::numeric_limits<float>::infinity());
}

KeyframeReport GaussianTrainer::add_keyframe(TrainingKeyframe keyframe) {
  const auto t0 = std::chrono::steady_clock::now();
  const int w = keyframe.camera.width, h = keyframe.camera.height;
  if (w <= 0 || h <= 0 || !keyframe.rgb.same_size(w, h) || keyframe.rgb.channels != 3 ||
      !keyframe.depth.same_size(w, h) || keyframe.depth.channels != 1 ||
      (!keyframe.labels.empty() &&
       (!keyframe.labels.same_size(w, h) || keyframe.labels.channels != 1))) {
    throw std::invalid_argument("GaussianTrainer::add_keyframe: images do not match the camera");
  }
  KeyframeReport report;
  ++keyframe_count_;

  StoredKeyframe kf;
  kf.id = keyframe.id;
  kf.camera = keyframe.camera;
  kf.T_wc = keyframe.T_wc;
  kf.rgb = std::move(keyframe.rgb);
  kf.depth = std::move(keyframe.depth);
  kf.labels = std::move(keyframe.labels);
  kf.key = next_key_++;
  if (kf.labels.empty()) kf.labels = LabelImage(kf.camera.width, kf.camera.height, 1, 0u);
  {
    // The labels present, ascending. A pass over the runs of equal labels (a keyframe holds a few
    // objects, each over many pixels) rather than sorting every pixel's (7 ms at 1200×680).
    uint32_t run = 0;
    for (const uint32_t id : kf.labels.data) {
      if (id == run) continue;
      run = id;
      if (id != 0 && std::find(kf.objects.begin(), kf.objects.end(), id) == kf.objects.end()) kf.objects.push_back(id);
    }
    std::sort(kf.objects.begin(), kf.objects.end());
  }

  // 1-2. Render what the map has, update visibility, add where it is missing or wrong.
  const size_t relabelled_before = relabelled_;
  auto ms_since = [](std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
  };
  auto t = std::chrono::steady_clock::now();
  if (map_.empty()) {
    add_gaussians(kf, nullptr, &report);
    report.add_ms = ms_since(t);
  } else {
    // Added only where the render could be made: a map the device cannot render gets no more.
    with_memory_retry(
        [&] {
          KeyframeReport attempt;
          RenderOutput& out = scratch_.render;
          std::unique_ptr<RenderState> state;
          t = std::chrono::steady_clock::now();
          sync_engine();
          // The same render gives the masks' instance opacities (each pixel's own object's).
          rasteriser_->forward(map_, kf.camera, kf.T_wc.inverse(), mask_settings(kf), &out, &state);
          const size_t relabelled = relabelled_;
          review_gaussians(kf, *state);
          // Relabelling changes which Gaussians count for an object: then the instance opacities
          // are rendered again.
          const bool ins_current = relabelled_ == relabelled;
          report.review_ms = ms_since(t);
          t = std::chrono::steady_clock::now();
          // Into a scratch report first: a pass that fails half-way must not count its Gaussians
          // twice (what it added stays; the retry only adds where the map is still missing).
          attempt = report;
          add_gaussians(kf, &out, &attempt, ins_current);
          report = attempt;
          report.add_ms = ms_since(t);
        },
        &report);
  }
  sync_state();
  report.relabelled = relabelled_ - relabelled_before;

  window_.push_back(std::move(kf));
  while (static_cast<int>(window_.size()) > std::max(1, params_.window)) window_.pop_front();

  // 3. Optimise the unstable Gaussians over the window.
  t = std::chrono::steady_clock::now();
  with_memory_retry([&] { report.losses = train(params_.iterations); }, &report);
  report.train_ms = ms_since(t);
  report.iterations = static_cast<int>(report.losses.size());
  report.abandoned = report.iterations < params_.iterations && stop_ && stop_->load();
  if (!report.losses.empty()) {
    report.loss_first = report.losses.front();
    report.loss_last = report.losses.back();
  }
  t = std::chrono::steady_clock::now();

  // Stabilise (off by default: no pass over the map, and its flags stay as the device has them).
  if (params_.stable_confidence > 0.f) {
    fetch_attributes();
    auto& stable = map_.stable();
    const auto& confidence = map_.confidences();
    for (size_t i = 0; i < map_.size(); ++i) {
      if (!stable[i] && confidence[i] >= params_.stable_confidence) {
        stable[i] = 1;
        ++report.became_stable;
      }
    }
  }

  // 4. Prune (the budget's render can run out of device memory too).
  with_memory_retry(
      [&] {
        KeyframeReport attempt = report;  // a pass that fails half-way must not count twice
        prune(&attempt);
        report = attempt;
      },
      &report);
  report.prune_ms = ms_since(t);

  report.num_gaussians = map_.size();
  for (const uint8_t s : std::as_const(map_).stable()) report.num_unstable += s ? 0 : 1;
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return report;
}

template <typename Step>
bool GaussianTrainer::with_memory_retry(Step step, KeyframeReport* report) {
  for (int attempt = 0; attempt < 2; ++attempt) {
    try {
      step();
      return true;
    } catch (const OutOfDeviceMemory& e) {
      report->device_error = e.what();
      if (attempt == 0) report->pruned_memory += shrink(0.25);
    }
  }
  return false;
}

size_t GaussianTrainer::shrink(double fraction) {
  sync_state();
  fetch_counters();
  const size_t n = map_.size();
  const size_t drop = static_cast<size_t>(fraction * static_cast<double>(n));
  if (drop == 0) return 0;
  std::vector<uint32_t> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = static_cast<uint32_t>(i);
  const auto& ids = map_.object_ids_per_gaussian();
  const auto score = [&](uint32_t i) {
    return ids[i] != 0 ? params_.budget_object_weight * usefulness_[i] : usefulness_[i];
  };
  std::nth_element(order.begin(), order.begin() + drop, order.end(), [&score](uint32_t a, uint32_t b) {
    const float sa = score(a), sb = score(b);
    return sa < sb || (sa == sb && a < b);
  });
  std::vector<uint8_t> remove(n, 0);
  for (size_t k = 0; k < drop; ++k) remove[order[k]] = 1;
  return remove_if(remove);
}

double GaussianTrainer::optimise(int iterations) {
  if (window_.empty() || map_.empty()) return 0.0;
  const std::vector<double> losses = train(iterations);
  return losses.empty() ? 0.0 : losses.back();
}

std::vector<double> GaussianTrainer::train(int iterations) {
  if (iterations <= 0 || window_.empty()) return {};
  if (uses_engine()) return iterate_on_engine(iterations);
  // The host's losses take the colours as floats, made once per keyframe (an engine takes the
  // 8-bit images).
  for (StoredKeyframe& kf : window_)
    if (kf.rgb_float.data.empty()) kf.rgb_float = to_float_rgb(kf.rgb);
  std::vector<double> losses;
  losses.reserve(static_cast<size_t>(iterations));
  for (int it = 0; it < iterations; ++it) {
    if (stop_ && stop_->load(std::memory_order_relaxed)) break;
    losses.push_back(iterate(pick_keyframe()));
  }
  return losses;
}

std::vector<double> GaussianTrainer::iterate_on_engine(int iterations) {
  if (map_.empty()) {  // as the host loop: a keyframe drawn, nothing else
    for (int it = 0; it < iterations; ++it) pick_keyframe_index();
    return std::vector<double>(static_cast<size_t>(iterations), 0.0);
  }
  // The same draws, in the same order, as the host loop: the two backends see the same
  // keyframes and objects (their loss curves are compared in the tests).
  std::vector<TrainingStep> steps(static_cast<size_t>(iterations));
  for (TrainingStep& step : steps) {
    step.view = static_cast<uint32_t>(pick_keyframe_index());
    step.object = pick_object(window_[step.view]);
  }
  std::vector<TrainingView> views;
  views.reserve(window_.size());
  for (const StoredKeyframe& kf : window_)
    views.push_back(TrainingView{kf.key, &kf.camera, kf.T_wc.inverse(), &kf.rgb, &kf.depth, &kf.labels});
  TrainingLoss loss;
  loss.settings = settings(0, false);
  loss.lambda_depth = params_.lambda_depth;
  loss.lambda_ins = params_.lambda_ins;
  // The trained attributes stay on the engine's device until the host reads them (map(), the
  // host's own loops): the mapper reads them only for a save, a service or a publish. Flagged
  // before the run: a failed batch may leave some there too (fetch_attributes() is then cheap).
  if (engine_->defer_attributes(true)) attributes_on_device_ = true;
  return engine_->run(views, steps, loss, &map_, &adam_);
}

size_t GaussianTrainer::pick_keyframe_index() {
  const size_t n = window_.size();
  if (params_.newest_share <= 0.f || n == 1) {
    return std::uniform_int_distribution<size_t>(0, n - 1)(rng_);
  }
  if (std::uniform_real_distribution<float>(0.f, 1.f)(rng_) < params_.newest_share) {
    return n - 1;
  }
  return std::uniform_int_distribution<size_t>(0, n - 2)(rng_);
}

uint32_t GaussianTrainer::pick_object(const StoredKeyframe& kf) {
  if (params_.lambda_ins > 0.f && !kf.objects.empty()) {
    return kf.objects[std::uniform_int_distribution<size_t>(0, kf.objects.size() - 1)(rng_)];
  }
  return 0;
}

// One backward pass with dL/d(rgb) = (1, [label = 0], [label != 0]) gives, per Gaussian, in its
// colour gradient: its contribution to the view, Σ_p T_i α_i over the pixels it reaches, and how
// much of it falls on background and on object pixels.
void GaussianTrainer::review_gaussians(const StoredKeyframe& kf, const RenderState& state,
                                       bool usefulness_only) {
  const bool check_visibility = !usefulness_only && params_.max_invisible_keyframes > 0;
  const bool check_labels = !usefulness_only && params_.relabel_fraction > 0.f;
  const bool check_usefulness = params_.max_gaussians > 0;
  if (!check_visibility && !check_labels && !check_usefulness) return;
  const SE3 T_cw = kf.T_wc.inverse();
  const ReviewView view = review_view_of(kf.camera, T_cw, kf.depth, kf.labels);
  ReviewSettings rs = params_.review_settings();
  rs.check_visibility = check_visibility;
  rs.check_labels = check_labels;
  // Where the engine holds the map, on its device: no probe up, no gradients down, no loop here.
  if (uses_engine()) {
    const TrainingView tv{kf.key, &kf.camera, T_cw, &kf.rgb, &kf.depth, &kf.labels};
    std::vector<std::pair<uint32_t, uint32_t>> relabels;
    if (engine_->review(map_, tv, settings(0, false), view, rs, usefulness_.data(), invisible_count_.data(),
                        relabel_votes_.data(), &relabels)) {
      counters_on_device_ = engine_->holds_review_counters();
      relabel_gaussians(relabels);
      return;
    }
  }
  fetch_attributes();  // the host's pass and loop read the map's values and the counters
  fetch_counters();
  const size_t n_pixels = kf.labels.data.size();
  OutputGradients& probe = scratch_.probe;
  probe.rgb.resize(3 * n_pixels);
  detail::parallel_for_chunks(detail::resolve_threads(0), n_pixels, [&](size_t begin, size_t end) {
    for (size_t p = begin; p < end; ++p) {
      probe.rgb[3 * p] = 1.f;
      probe.rgb[3 * p + 1] = kf.labels.data[p] == 0 ? 1.f : 0.f;
      probe.rgb[3 * p + 2] = kf.labels.data[p] != 0 ? 1.f : 0.f;
    }
  });
  MapGradients& g = scratch_.review;
  g.colour_only = true;  // a GPU backend then brings back 3 of the 14 values per Gaussian
  g.colour.clear();  // backward() sizes it, zero-filled, and adds
  rasteriser_->backward(map_, kf.camera, T_cw, settings(0, false), state, probe, &g);

  const float* pos = map_.positions().data();
  const auto& ids = map_.object_ids_per_gaussian();
  // Each Gaussian on its own (its entries of the per-Gaussian arrays only): over threads, with
  // the same result on any number of them; a million Gaussians took 100 ms on one core. The few
  // relabels are listed per chunk (no per-Gaussian arrays to fill and walk for them), then put
  // in index order.
  std::vector<std::pair<uint32_t, uint32_t>> relabels;
  std::mutex relabels_mutex;
  detail::parallel_for_chunks(detail::resolve_threads(0), map_.size(), [&](size_t begin, size_t end) {
    std::vector<std::pair<uint32_t, uint32_t>> found;
    for (size_t i = begin; i < end; ++i) {
      uint32_t new_id = 0;
      if (review_gaussian(view, rs, pos + 3 * i, ids[i], g.colour.data() + 3 * i, &usefulness_[i],
                          &invisible_count_[i], &relabel_votes_[i], &new_id))
        found.emplace_back(static_cast<uint32_t>(i), new_id);
    }
    if (found.empty()) return;
    std::lock_guard<std::mutex> lock(relabels_mutex);
    relabels.insert(relabels.end(), found.begin(), found.end());
  });
  std::sort(relabels.begin(), relabels.end());
  relabel_gaussians(relabels);
}

// In place: a relabelled Gaussian keeps its index, attributes, optimiser state and counters (its
// votes start over). (It used to leave the map and come back appended, which cost a compaction
// of every array per keyframe and the optimiser's moments of the Gaussians that moved.)
void GaussianTrainer::relabel_gaussians(const std::vector<std::pair<uint32_t, uint32_t>>& changes) {
  const uint64_t flags_before = map_.flags_revision();
  const size_t n = map_.relabel_each(changes);
  if (n == 0) return;
  if (engine_) engine_->map_relabelled(map_, changes, flags_before);
  relabelled_ += n;
  for (const auto& [index, id] : changes) relabel_votes_[index] = 0;
}

RenderSettings GaussianTrainer::mask_settings(const StoredKeyframe& kf) const {
  RenderSettings s = settings(0, false);
  s.outputs = kRenderRgb | kRenderDepth | kRenderAlpha | kRenderIns;  // add_gaussians' masks
  if (!kf.objects.empty()) s.ins_labels = kf.labels.data.data();
  return s;
}

void GaussianTrainer::add_gaussians(const StoredKeyframe& kf, const RenderOutput* out,
                                    KeyframeReport* report, bool ins_current) {
  const int w = kf.camera.width, h = kf.camera.height;
  const size_t n = static_cast<size_t>(w) * h;
  std::vector<uint8_t> missing(n, 1), error(n, 0);  // error: 1 geometry, 2 colour only
  const int threads = detail::resolve_threads(0);
  if (out) {
    detail::parallel_for_chunks(threads, n, [&](size_t begin, size_t end) {
      for (size_t p = begin; p < end; ++p) {
        missing[p] = (1.f - out->alpha[p]) > params_.missing_transmittance;
        if (missing[p]) continue;
        const float d = kf.depth.data[p];
        if (valid_depth(d) && std::abs(out->depth[p] - d) > params_.depth_error) {
          error[p] = 1;
          continue;
        }
        float dc = 0.f;
        for (int c = 0; c < 3; ++c) dc += std::abs(out->rgb[3 * p + c] - unit_colour(kf.rgb.data[3 * p + c]));
        if (dc / 3.f > params_.colour_error) error[p] = 2;
      }
    });
    // Mask_geo also holds the pixels of object k where k's instance opacity is low (one render
    // gives every object's on its own pixels: RenderSettings::ins_labels).
    if (!kf.objects.empty()) {
      RenderOutput rendered;
      const std::vector<float>* ins = &out->ins;
      if (!ins_current) {
        sync_engine();
        RenderSettings ins_only = mask_settings(kf);
        ins_only.outputs = kRenderIns;
        rasteriser_->forward(map_, kf.camera, kf.T_wc.inverse(), ins_only, &rendered, nullptr);
        ins = &rendered.ins;
      }
      detail::parallel_for_chunks(threads, n, [&](size_t begin, size_t end) {
        for (size_t p = begin; p < end; ++p) {
          if (kf.labels.data[p] != 0 && !missing[p] && (*ins)[p] < params_.ins_threshold) error[p] = 1;
        }
      });
    }
  }

  // Near its budget the map takes new background surface at half the density, each Gaussian twice
  // as wide: the same area for a quarter of the Gaussians, where the full density would only push
  // out as many elsewhere (the budget's pruning) and leave holes in what the other views saw.
  // Objects keep the full density: they are what the map is for.
  const bool tight = params_.max_gaussians > 0 &&
                     map_.size() >= static_cast<size_t>(0.75 * params_.max_gaussians);
  const int fine_stride = std::max(1, params_.missing_stride);
  // The candidates row by row, over threads: missing pixels on the stride grid, and error pixels
  // with a measured depth in range (those draw their chance below).
  struct Candidate {
    int u, v, stride;
    uint8_t error;  // 0: missing, else error[p]
  };
  std::vector<std::vector<Candidate>> rows(static_cast<size_t>(h));
  std::vector<size_t> missing_in_row(h, 0), error_in_row(h, 0);
  detail::parallel_for_dynamic(threads, static_cast<size_t>(h), [&](size_t row) {
    const int v = static_cast<int>(row);
    for (int u = 0; u < w; ++u) {
      const size_t p = static_cast<size_t>(v) * w + u;
      if (!missing[p] && !error[p]) continue;
      const float d = kf.depth.data[p];
      const bool usable = valid_depth(d) && d >= params_.min_depth && d <= params_.max_depth;
      const bool coarse = tight && kf.labels.data[p] == 0;
      const int stride = fine_stride * (coarse ? 2 : 1);
      if (missing[p]) {
        ++missing_in_row[row];
        if (usable && u % stride == 0 && v % stride == 0) rows[row].push_back({u, v, stride, 0});
      } else {
        ++error_in_row[row];
        if (usable) rows[row].push_back({u, v, stride, error[p]});
      }
    }
  });
  // In raster order, one draw per usable error pixel (the sequence of a serial pass over the image).
  std::uniform_real_distribution<float> uniform(0.f, 1.f);
  std::vector<Candidate> chosen;
  for (int v = 0; v < h; ++v) {
    report->missing_pixels += missing_in_row[v];
    report->error_pixels += error_in_row[v];
    for (const Candidate& c : rows[v]) {
      if (c.error) {
        const bool coarse = c.stride != fine_stride;
        if (!(uniform(rng_) < params_.error_sample_rate / (coarse ? 4.f : 1.f))) continue;
        ++report->added_error;
      } else {
        ++report->added_missing;
      }
      chosen.push_back(c);
    }
  }
  // Each new Gaussian on its own (a normal from its neighbours' depths), then appended in order.
  std::vector<GaussianInit> made(chosen.size());
  detail::parallel_for_chunks(threads, chosen.size(), [&](size_t begin, size_t end) {
    for (size_t k = begin; k < end; ++k) {
      const Candidate& c = chosen[k];
      made[k] = gaussian_at(kf, c.u, c.v, c.stride, c.error == 2 && params_.transparent_for_colour_error);
    }
  });
  for (const GaussianInit& g : made) map_.add(g);  // (no reserve: the arrays' growth stays geometric)
}

GaussianInit GaussianTrainer::gaussian_at(const StoredKeyframe& kf, int u, int v, int stride,
                                          bool transparent) const {
  const PinholeCamera& cam = kf.camera;
  const int w = cam.width, h = cam.height;
  const float d = kf.depth.data[static_cast<size_t>(v) * w + u];
  const Eigen::Vector3d p_c = cam.back_project(u, v, d);

  // Normal from the back-projected neighbours at ± r pixels, central differences where both sides
  // are measured and on the same surface, one-sided otherwise; facing the camera without either.
  const int r = std::max(1, params_.normal_radius_px);
  auto neighbour = [&](int du, int dv, Eigen::Vector3d* q) {
    const int uu = u + du, vv = v + dv;
    if (uu < 0 || vv < 0 || uu >= w || vv >= h) return false;
    const float dn = kf.depth.data[static_cast<size_t>(vv) * w + uu];
    // Same surface: the depth step stays below what a 75° slope gives over r pixels.
    if (!valid_depth(dn) || std::abs(dn - d) > 4.f * r * d / cam.fx + 0.01f) return false;
    *q = cam.back_project(uu, vv, dn);
    return true;
  };
  auto difference = [&](int du, int dv, Eigen::Vector3d* diff) {
    Eigen::Vector3d a, b;
    const bool has_a = neighbour(du, dv, &a), has_b = neighbour(-du, -dv, &b);
    if (has_a && has_b)
      *diff = a - b;
    else if (has_a)
      *diff = a - p_c;
    else if (has_b)
      *diff = p_c - b;
    else
      return false;
    return true;
  };
  const Eigen::Vector3d ray = p_c.normalized();
  Eigen::Vector3d n_c = -ray;
  Eigen::Vector3d dx, dy;
  if (difference(r, 0, &dx) && difference(0, r, &dy)) {
    const Eigen::Vector3d c = dx.cross(dy);
    if (c.norm() > 1e-12) n_c = c.normalized();
  }
  if (n_c.dot(ray) > 0.0) n_c = -n_c;

  // Axes: t1 along the slope (the ray projected onto the surface), t2 = n × t1, n.
  const double cos_view = std::clamp(-n_c.dot(ray), 1e-3, 1.0);
  Eigen::Vector3d t1 = ray - ray.dot(n_c) * n_c;
  if (t1.norm() < 1e-6) t1 = n_c.unitOrthogonal();
  t1.normalize();
  const Eigen::Vector3d t2 = n_c.cross(t1);
  Eigen::Matrix3d R_c;
  R_c << t1, t2, n_c;
  const Eigen::Matrix3d R_w = kf.T_wc.rotation() * R_c;

  const double f = 0.5 * (cam.fx + cam.fy);
  const double sigma = params_.scale_factor * stride * d / f;
  const double stretch = std::min(1.0 / cos_view, static_cast<double>(params_.max_stretch));

  GaussianInit g;
  g.position = (kf.T_wc * p_c).cast<float>();
  g.log_scale = Eigen::Vector3f(static_cast<float>(std::log(sigma * stretch)),
                                static_cast<float>(std::log(sigma)),
                                static_cast<float>(std::log(sigma * params_.flatness)));
  g.rotation = quaternion_of(R_w);
  const size_t p = static_cast<size_t>(v) * w + u;
  g.colour = Eigen::Vector3f(unit_colour(kf.rgb.data[3 * p]), unit_colour(kf.rgb.data[3 * p + 1]),
                             unit_colour(kf.rgb.data[3 * p + 2]));
  g.object_id = kf.labels.data[p];
  g.type = transparent ? GaussianType::kTransparent : GaussianType::kOpaque;
  g.birth_keyframe = static_cast<uint32_t>(keyframe_count_ - 1);
  return g;
}

double GaussianTrainer::iterate(const StoredKeyframe& kf) {
  if (map_.empty()) return 0.0;
  const uint32_t object = pick_object(kf);
  const SE3 T_cw = kf.T_wc.inverse();
  const RenderSettings s = settings(object, false);
  RenderOutput out;
  std::unique_ptr<RenderState> state;
  rasteriser_->forward(map_, kf.camera, T_cw, s, &out, &state);

  // The photometric and depth terms over the pixels of `weights`, into `og`.
  const double l_ssim = params_.lambda_ssim;
  auto image_terms = [&](const PixelWeights& weights, OutputGradients* og) {
    double l = (1.0 - l_ssim) * l1_rgb_loss(out, kf.rgb_float, weights, 1.0 - l_ssim, og);
    if (l_ssim > 0.0) l += l_ssim * ssim_loss(out, kf.rgb_float, weights, l_ssim, og);
    if (params_.lambda_depth > 0.f) {
      l += params_.lambda_depth * l1_depth_loss(out, kf.depth, weights, params_.lambda_depth, og);
    }
    return l;
  };
  auto ins_term = [&](OutputGradients* og) {
    if (object == 0) return 0.0;
    ImageF mask(kf.labels.width, kf.labels.height, 1, 0.f);
    for (size_t p = 0; p < mask.data.size(); ++p) mask.data[p] = kf.labels.data[p] == object;
    return params_.lambda_ins * ins_loss(out, mask, {}, params_.lambda_ins, og);
  };

  double loss = 0.0;
  grad_.resize_for(map_);
  if (!params_.train_per_label || kf.objects.empty()) {
    OutputGradients og;
    loss = image_terms({}, &og) + ins_term(&og);
    rasteriser_->backward(map_, kf.camera, T_cw, s, *state, og, &grad_);
  } else {
    // Mask^{O_k} of METHOD.md §4: the background's Gaussians learn from background pixels only,
    // the objects' from object pixels (and L_ins), so that neither is pulled over the other's
    // pixels. Two backward passes over the one forward pass.
    const size_t n_pixels = kf.labels.data.size();
    PixelWeights background(n_pixels), objects(n_pixels);
    for (size_t p = 0; p < n_pixels; ++p) {
      background[p] = kf.labels.data[p] == 0 ? 1.f : 0.f;
      objects[p] = 1.f - background[p];
    }
    OutputGradients og_bg, og_obj;
    loss = image_terms(background, &og_bg);
    loss += image_terms(objects, &og_obj) + ins_term(&og_obj);
    rasteriser_->backward(map_, kf.camera, T_cw, s, *state, og_bg, &grad_);
    grad_objects_.resize_for(map_);
    rasteriser_->backward(map_, kf.camera, T_cw, s, *state, og_obj, &grad_objects_);
    const auto& ids = map_.object_ids_per_gaussian();
    auto take_rows = [&ids](std::vector<float>* dst, const std::vector<float>& src, size_t width) {
      for (size_t i = 0; i < ids.size(); ++i) {
        if (ids[i] == 0) continue;
        std::copy_n(src.begin() + i * width, width, dst->begin() + i * width);
      }
    };
    take_rows(&grad_.position, grad_objects_.position, 3);
    take_rows(&grad_.log_scale, grad_objects_.log_scale, 3);
    take_rows(&grad_.rotation, grad_objects_.rotation, 4);
    take_rows(&grad_.opacity, grad_objects_.opacity, 1);
    take_rows(&grad_.colour, grad_objects_.colour, 3);
  }

  // Step the unstable Gaussians that this view reached.
  const size_t n = map_.size();
  std::vector<uint8_t> update(n, 0);
  const auto& stable = std::as_const(map_).stable();
  auto any = [](const std::vector<float>& g, size_t i, size_t width) {
    for (size_t k = 0; k < width; ++k) {
      if (g[i * width + k] != 0.f) return true;
    }
    return false;
  };
  for (size_t i = 0; i < n; ++i) {
    if (stable[i]) continue;
    update[i] = any(grad_.position, i, 3) || any(grad_.colour, i, 3) ||
                any(grad_.log_scale, i, 3) || any(grad_.rotation, i, 4);
  }
  adam_.step(grad_, update, &map_);
  auto& confidence = map_.confidences();
  for (size_t i = 0; i < n; ++i) confidence[i] += update[i] ? 1.f : 0.f;
  return loss;
}

void GaussianTrainer::prune(KeyframeReport* report) {
  const size_t n = map_.size();
  if (n == 0) return;
  const uint32_t now = static_cast<uint32_t>(keyframe_count_ - 1);
  const float max_log_scale = std::log(params_.max_scale);
  const auto& stable = std::as_const(map_).stable();
  const auto& birth = map_.birth_keyframes();
  // The size and invisibility tests (bits 0 and 1) on what the engine holds where it holds the
  // map (1 byte a Gaussian down), else on the host's values.
  constexpr uint8_t kTooLarge = 1, kUnseen = 2;
  std::vector<uint8_t> tests;
  const int max_invisible = params_.max_invisible_keyframes;
  if (uses_engine() && engine_->flag_prune(map_, max_log_scale, max_invisible, usefulness_.data(),
                                           invisible_count_.data(), relabel_votes_.data(), &tests)) {
    counters_on_device_ = engine_->holds_review_counters();
  } else {
    fetch_attributes();
    fetch_counters();
    const auto& log_scale = map_.log_scales();
    tests.resize(n);
    detail::parallel_for_chunks(detail::resolve_threads(0), n, [&](size_t begin, size_t end) {
      for (size_t i = begin; i < end; ++i) {
        tests[i] = (oversized(log_scale.data() + 3 * i, max_log_scale) ? kTooLarge : 0) |
                   (max_invisible > 0 && invisible_count_[i] >= max_invisible ? kUnseen : 0);
      }
    });
  }
  // Each Gaussian on its own, over threads in fixed chunks (a million take a few ms on one core),
  // each chunk listing its removals in order: the lists joined make the removal's plan without
  // another pass over the map (removal_plan.h), and each owner of per-Gaussian arrays applies it.
  constexpr size_t kChunk = size_t{1} << 16;
  const size_t chunks = (n + kChunk - 1) / kChunk;
  std::vector<std::vector<uint32_t>> listed(chunks);
  std::atomic<size_t> stale{0}, oversized{0}, invisible{0};
  detail::parallel_for_dynamic(detail::resolve_threads(0), chunks, [&](size_t c) {
    size_t n_stale = 0, n_oversized = 0, n_invisible = 0;
    std::vector<uint32_t>& list = listed[c];
    for (size_t i = c * kChunk, end = std::min(n, (c + 1) * kChunk); i < end; ++i) {
      if (params_.max_unstable_age > 0 && !stable[i] &&
          now - birth[i] > static_cast<uint32_t>(params_.max_unstable_age)) {
        ++n_stale;
      } else if (tests[i] & kTooLarge) {
        ++n_oversized;
      } else if (tests[i] & kUnseen) {
        ++n_invisible;
      } else {
        continue;
      }
      list.push_back(static_cast<uint32_t>(i));
    }
    stale += n_stale, oversized += n_oversized, invisible += n_invisible;
  });
  std::vector<uint32_t> removed;
  removed.reserve(stale + oversized + invisible);
  for (const auto& list : listed) removed.insert(removed.end(), list.begin(), list.end());
  report->pruned_stale += stale;
  report->pruned_oversized += oversized;
  report->pruned_invisible += invisible;
  // The budget: of the survivors, the least useful go until max_gaussians remain. The Gaussians
  // this keyframe added have not been measured yet (the review ran on the render before they
  // were): they are measured first, on the newest view after its optimisation, or a budget
  // smaller than one keyframe's additions would drop them in the order they were added (whole
  // rows of the image).
  const size_t kept = n - removed.size();
  if (params_.max_gaussians > 0 && kept > static_cast<size_t>(params_.max_gaussians)) {
    const StoredKeyframe& newest = window_.back();
    RenderOutput out;
    std::unique_ptr<RenderState> state;
    sync_engine();
    RenderSettings state_only = settings(0, false);
    state_only.outputs = 0;  // the review reads the pass's state alone
    rasteriser_->forward(map_, newest.camera, newest.T_wc.inverse(), state_only, &out, &state);
    review_gaussians(newest, *state, true);
    fetch_counters();  // the usefulness, on the host for the selection
    std::vector<uint8_t> remove(n, 0);
    for (const uint32_t i : removed) remove[i] = 1;
    std::vector<uint32_t> order;
    order.reserve(kept);
    for (size_t i = 0; i < n; ++i) {
      if (!remove[i]) order.push_back(static_cast<uint32_t>(i));
    }
    const size_t excess = kept - static_cast<size_t>(params_.max_gaussians);
    const auto& ids = map_.object_ids_per_gaussian();
    const auto score = [&](uint32_t i) {
      return ids[i] != 0 ? params_.budget_object_weight * usefulness_[i] : usefulness_[i];
    };
    // Ties (equal scores) break by index, so the result is deterministic.
    std::nth_element(order.begin(), order.begin() + excess, order.end(),
                     [&score](uint32_t a, uint32_t b) {
                       const float sa = score(a), sb = score(b);
                       return sa < sb || (sa == sb && a < b);
                     });
    for (size_t k = 0; k < excess; ++k) remove[order[k]] = 1;
    report->pruned_budget += excess;
    remove_if(remove);
    return;
  }
  if (!removed.empty()) remove_by(plan_removal(removed, n));
}

const GaussianAdam::State& GaussianTrainer::adam_state() {
  if (engine_) engine_->fetch_optimiser_state(&adam_);
  return adam_.state();
}

size_t GaussianTrainer::remove_if(const std::vector<uint8_t>& remove) {
  if (remove.size() != map_.size())
    throw std::invalid_argument("GaussianTrainer::remove_if: mask has " + std::to_string(remove.size()) +
                                " entries for " + std::to_string(map_.size()) + " Gaussians");
  return remove_by(plan_removal(remove));
}

size_t GaussianTrainer::remove_by(const RemovalPlan& plan) {
  sync_state();
  if (plan.size != map_.size()) throw std::logic_error("GaussianTrainer: a removal plan for another map");
  if (plan.removed() == 0) return 0;
  // Deferred attributes or kept counters: the engine holds every Gaussian first (the appended
  // ones sent), so that its removal runs in full there and keeps what it trained and counted (a
  // fetch by map() leaves the counters there).
  if ((attributes_on_device_ || counters_on_device_) && !engine_->holds(map_)) sync_engine();
  // The map's arrays, the optimiser's step counts, the trainer's own and the engine's copy at
  // once, each by the same plan (removal_plan.h: as many moves as removals).
  detail::run_on_threads(4, [&](int job) {
    if (job == 0) {
      map_.remove(plan);
    } else if (job == 1) {
      adam_.remove(plan);
    } else if (job == 2) {
      if (engine_) engine_->map_removed(plan);
    } else {
      detail::Compaction c(plan);
      c.add(&invisible_count_, 1);
      c.add(&relabel_votes_, 1);
      c.add(&usefulness_, 1);
      c.run();
    }
  });
  return plan.removed();
}

bool GaussianTrainer::set_keyframe_pose(uint32_t id, const SE3& T_wc) {
  for (StoredKeyframe& kf : window_) {
    if (kf.id == id) {
      kf.T_wc = T_wc;
      return true;
    }
  }
  return false;
}

size_t GaussianTrainer::relabel(uint32_t from, uint32_t to) {
  for (StoredKeyframe& kf : window_) {
    bool changed = false;
    for (uint32_t& l : kf.labels.data) {
      if (l == from) {
        l = to;
        changed = true;
      }
    }
    if (!changed) continue;
    kf.key = next_key_++;  // the engine's copy of the labels is stale
    kf.objects.erase(std::remove(kf.objects.begin(), kf.objects.end(), from), kf.objects.end());
    if (to != 0 && std::find(kf.objects.begin(), kf.objects.end(), to) == kf.objects.end()) {
      kf.objects.insert(std::upper_bound(kf.objects.begin(), kf.objects.end(), to), to);
    }
  }
  return map_.relabel(from, to);
}

void GaussianTrainer::set_map(GaussianMap map) {
  map_ = std::move(map);
  attributes_on_device_ = false;
  counters_on_device_ = false;
  if (engine_) engine_->map_replaced();
  adam_.reset();
  invisible_count_.assign(map_.size(), 0);
  relabel_votes_.assign(map_.size(), 0);
  usefulness_.assign(map_.size(), std::numeric_limits<float>::infinity());
  sync_state();
}

}  // namespace dqo::gs
