// The CUDA training engine's host side (cuda_training_engine.h): the map and optimiser state kept
// on the device from batch to batch (resident_map.h: only what the host appended or flagged goes
// up, only the trained attributes come down), the views' images cached by key, every iteration on
// the rasteriser's device pipeline and this ring's loss and Adam kernels.

#include "dqo_map/cuda/cuda_training_engine.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>

#include "../common/device_buffer.h"
#include "../raster/raster_pipeline.h"
#include "dqo_map/gaussians/detail/cpu_rasteriser.h"
#include "dqo_map/gaussians/removal_plan.h"
#include "resident_map.h"
#include "train_cuda.h"

namespace dqo::cuda {

namespace {

bool valid_depth(float d) { return std::isfinite(d) && d > 0.f; }

// A view's images on the device.
struct CachedView {
  DeviceBuffer<float> rgb, depth;
  DeviceBuffer<uint32_t> labels;
  size_t pixels = 0;
  size_t valid_depth = 0;  // pixels with a measurement: the depth term's normaliser
};

class CudaTrainingEngine final : public gs::TrainingEngine {
 public:
  // shared: the backend's rasteriser renders `resident` while it shows the map (the only case where
  // the trained attributes may stay here: every render of the map then shows them).
  CudaTrainingEngine(std::shared_ptr<detail::ResidentMap> resident, bool shared)
      : resident_(std::move(resident)), shared_(shared) {
    const char* env = std::getenv("DQO_CUDA_STAGE_TIMES");
    if (env && *env && std::string(env) != "0") {
      clock_.enable(true);
      pipe_.set_clock(&clock_);
    }
  }
  ~CudaTrainingEngine() override {
    if (select_temp_) cudaFree(select_temp_);
    if (!clock_.enabled()) return;
    clock_.collect();
    std::fprintf(stderr,
                 "CUDA training engine, GPU time by stage over %s; the views' selections held %.1f %% of the map; "
                 "%.0f pairs a tile\n",
                 clock_.summary().c_str(), selectable_ > 0.0 ? 100.0 * selected_ / selectable_ : 100.0,
                 tile_sum_ > 0.0 ? pair_sum_ / tile_sum_ : 0.0);
  }

  std::vector<double> run(const std::vector<gs::TrainingView>& views, const std::vector<gs::TrainingStep>& steps,
                          const gs::TrainingLoss& loss, gs::GaussianMap* map, gs::GaussianAdam* adam) override {
    std::vector<double> losses(steps.size(), 0.0);
    const size_t n = map->size();
    if (n == 0 || steps.empty()) return losses;
    if (adam->params().lr_opacity > 0.f)
      throw std::invalid_argument("CUDA training engine: opacity is fixed here (lr_opacity must be 0)");
    for (const gs::TrainingStep& s : steps)
      if (s.view >= views.size()) throw std::invalid_argument("CUDA training engine: a step names no view");
    cache_views(views);
    adam->resize_for(*map);
    if (rescued_) fetch_attributes(map);  // what a failed removal kept, into the map before it is sent
    try {
      return run_resident(views, steps, loss, map, adam);
    } catch (...) {
      // The device's copy may be half-trained: the next batch sends all. Deferred attributes
      // (this batch's steps done so far included) come down first where the device still gives
      // them; without deferral the map stays as before the batch.
      if (pending_) {
        try {
          resident_->download_trained(map, pipe_.stream());
          check(cudaStreamSynchronize(pipe_.stream()), "deferred attributes");
        } catch (const std::exception& e) {
          report_lost(e.what());
        }
        pending_ = false;
      }
      resident_->invalidate();
      throw;
    }
  }

  void map_removed(const gs::RemovalPlan& plan) override {
    try {
      if (pending_ && plan.size != resident_->count())
        throw std::logic_error("deferred attributes: the removal's plan covers Gaussians not on the device");
      resident_->remove(plan, pipe_.stream());
    } catch (const std::exception& e) {
      // The next batch sends the host's map. Deferred attributes come down first, with the same
      // removal applied, where the device still holds them as they were (remove() failed before
      // changing anything); fetch_attributes() writes them.
      if (pending_ && resident_->valid() && plan.size == resident_->count()) {
        try {
          detail::ResidentMap::Trained t = resident_->download_trained(pipe_.stream());
          const auto arrays = t.arrays();
          for (size_t k = 0; k < arrays.size(); ++k)
            gs::apply_removal(arrays[k], detail::ResidentMap::kTrainedWidths[k], plan);
          rescued_ = std::make_unique<detail::ResidentMap::Trained>(std::move(t));
        } catch (const std::exception& e2) {
          report_lost(e2.what());
        }
      } else if (pending_) {
        report_lost(e.what());
      }
      pending_ = false;
      resident_->invalidate();
    }
  }
  void map_relabelled(const gs::GaussianMap& map, const std::vector<std::pair<uint32_t, uint32_t>>& changes,
                      uint64_t flags_before) override {
    try {
      resident_->relabel(map, changes, flags_before, pipe_.stream());
    } catch (const std::exception&) {
      resident_->forget_flags();  // the next sync sends them whole
    }
  }
  void map_replaced() override {
    resident_->invalidate();
    pending_ = false;
    rescued_.reset();
  }
  void sync(const gs::GaussianMap& map, const gs::GaussianAdam& adam) override {
    if (adam.size() != map.size()) return;
    try {
      resident_->sync_up(map, adam, pipe_.stream());
    } catch (const std::exception&) {
      // Out of memory leaves what is held valid (sync_up allocates first): the caller fetches
      // deferred attributes from it (holds() is false). Only a failing device loses the copy.
      if (!resident_->valid() && pending_) {
        report_lost("the device's copy was dropped");
        pending_ = false;
      }
    }
  }
  bool defer_attributes(bool on) override {
    defer_ = on && shared_;
    return defer_;
  }
  void fetch_attributes(gs::GaussianMap* map) override {
    if (rescued_) {  // into the map's first Gaussians, those the rescued arrays hold
      if (map->size() < rescued_->confidence.size())
        throw std::logic_error("CUDA training engine: the map is smaller than the rescued one");
      const auto from = rescued_->arrays();
      const auto into = detail::ResidentMap::trained_arrays(map);
      for (size_t k = 0; k < from.size(); ++k) std::copy(from[k]->begin(), from[k]->end(), into[k]->begin());
      rescued_.reset();
      return;
    }
    if (!pending_) return;
    resident_->download_trained(map, pipe_.stream());
    check(cudaStreamSynchronize(pipe_.stream()), "deferred attributes");
    pending_ = false;
  }
  bool holds(const gs::GaussianMap& map) const override { return resident_->shows(map); }
  bool flag_prune(const gs::GaussianMap& map, float max_log_scale, int max_invisible, float* usefulness,
                  uint16_t* invisible, uint8_t* votes, std::vector<uint8_t>* flags) override {
    if (!resident_->shows(map)) return false;
    // The invisibility test needs the counters here: kept ones, or the caller's taken (and kept)
    // where attributes are deferred; otherwise the caller tests its own.
    if (max_invisible > 0 && !resident_->counters_held()) {
      if (!defer_) return false;
      resident_->take_counters(usefulness, invisible, votes, pipe_.stream());
    }
    const size_t n = map.size();
    flags->resize(n);
    if (n == 0) return true;
    uint8_t* d = flag_bytes_.ensure(n, "pruning flags");
    resident_->flag_prune(max_log_scale, max_invisible, d, pipe_.stream());
    check(cudaMemcpyAsync(flags->data(), d, n, cudaMemcpyDeviceToHost, pipe_.stream()), "pruning flags");
    check(cudaStreamSynchronize(pipe_.stream()), "pruning flags");
    return true;
  }
  bool holds_review_counters() const override { return resident_->counters_held(); }
  void fetch_review_counters(float* usefulness, uint16_t* invisible, uint8_t* votes) override {
    resident_->give_back_counters(usefulness, invisible, votes, pipe_.stream());
  }
  bool review(const gs::GaussianMap& map, const gs::TrainingView& view, const gs::RenderSettings& settings,
              const gs::ReviewView& rv, const gs::ReviewSettings& rs, float* usefulness, uint16_t* invisible,
              uint8_t* votes, std::vector<std::pair<uint32_t, uint32_t>>* relabels) override {
    if (!resident_->shows(map)) return false;  // the trainer syncs first; else its own loop runs
    const size_t n = map.size();
    relabels->clear();
    if (n == 0) return true;
    const PinholeCamera& camera = *view.camera;
    const size_t pixels = static_cast<size_t>(camera.width) * camera.height;
    if (!view.depth || !view.labels || view.depth->data.size() != pixels || view.labels->data.size() != pixels)
      throw std::invalid_argument("CUDA training engine: the review's view images do not match its camera");
    const cudaStream_t stream = pipe_.stream();
    resident_->wait();
    clock_.start(stream);  // with DQO_CUDA_STAGE_TIMES: the review's pass counts as one pass
    // The view's images cached (the batch that follows trains on them); one pass of the map kept
    // on the device, its colour gradient under the probe (1, [label = 0], [label != 0]) summed per
    // Gaussian.
    const CachedView& cv = cached(view);
    gs::ReviewView dv = rv;
    dv.depth = cv.depth.get();
    dv.labels = cv.labels.get();
    const detail::DeviceGaussians g = resident_->gaussians();
    const gs::CameraView<float> cam = gs::detail::make_camera_view<float>(camera, view.T_cw, settings.near);
    gs::RenderSettings pass = settings;
    pass.outputs = 0;
    pipe_.forward(g, cam, pass, true);
    float* v_rgb = v_rgb_.ensure(3 * pixels, "output gradients");
    detail::launch_review_probe(pixels, dv.labels, v_rgb, stream);
    check(cudaGetLastError(), "review probe");
    detail::ImageGradientsDevice go;
    go.rgb = v_rgb;
    pipe_.backward_2d(go);
    // The counters: those kept here (taken from the caller the first time, where attributes are
    // deferred: then they stay), or the caller's up, reviewed in place and down with the relabels
    // (few: their count first).
    const bool keep = defer_;
    if (keep && !resident_->counters_held()) resident_->take_counters(usefulness, invisible, votes, stream);
    float* d_usefulness;
    uint16_t* d_invisible;
    uint8_t* d_votes;
    if (keep) {
      const detail::ResidentMap::Counters c = resident_->counters();
      d_usefulness = c.usefulness, d_invisible = c.invisible, d_votes = c.votes;
    } else {
      d_usefulness = review_usefulness_.ensure(n, "review counters");
      d_invisible = review_invisible_.ensure(n, "review counters");
      d_votes = review_votes_.ensure(n, "review counters");
      check(cudaMemcpyAsync(d_usefulness, usefulness, n * sizeof(float), cudaMemcpyHostToDevice, stream), "review");
      check(cudaMemcpyAsync(d_invisible, invisible, n * sizeof(uint16_t), cudaMemcpyHostToDevice, stream), "review");
      check(cudaMemcpyAsync(d_votes, votes, n, cudaMemcpyHostToDevice, stream), "review");
    }
    uint2* d_relabels = review_relabels_.ensure(n, "review relabels");
    uint32_t* d_count = review_count_.ensure(1, "review relabels");
    check(cudaMemsetAsync(d_count, 0, sizeof(uint32_t), stream), "review");
    detail::launch_review(n, g.position, g.object_id, pipe_.tile_counts(), pipe_.grad2d(), dv, rs, d_usefulness,
                          d_invisible, d_votes, d_relabels, d_count, stream);
    check(cudaGetLastError(), "review");
    uint32_t count = 0;
    check(cudaMemcpyAsync(&count, d_count, sizeof(uint32_t), cudaMemcpyDeviceToHost, stream), "review");
    check(cudaStreamSynchronize(stream), "review");
    std::vector<uint2> listed(count);
    if (count)
      check(cudaMemcpyAsync(listed.data(), d_relabels, count * sizeof(uint2), cudaMemcpyDeviceToHost, stream),
            "review");
    // Into the caller's counters only once everything ran: a failure leaves them as they were.
    if (!keep) {
      check(cudaMemcpyAsync(usefulness, d_usefulness, n * sizeof(float), cudaMemcpyDeviceToHost, stream), "review");
      check(cudaMemcpyAsync(invisible, d_invisible, n * sizeof(uint16_t), cudaMemcpyDeviceToHost, stream), "review");
      check(cudaMemcpyAsync(votes, d_votes, n, cudaMemcpyDeviceToHost, stream), "review");
    }
    check(cudaStreamSynchronize(stream), "review");
    relabels->reserve(count);
    for (const uint2& r : listed) relabels->emplace_back(r.x, r.y);
    std::sort(relabels->begin(), relabels->end());
    return true;
  }

  void fetch_optimiser_state(gs::GaussianAdam* adam) override {
    if (!resident_->valid() || adam->size() < resident_->count()) return;
    resident_->download_optimiser(adam, pipe_.stream());
    check(cudaStreamSynchronize(pipe_.stream()), "optimiser state");
  }

  size_t device_bytes() const override {
    size_t total = 0;
    for (const auto& [key, cv] : cache_) total += cv->rgb.bytes() + cv->depth.bytes() + cv->labels.bytes();
    for (const auto& cv : spare_) total += cv->rgb.bytes() + cv->depth.bytes() + cv->labels.bytes();
    for (const auto* b : {&v_rgb_, &v_depth_, &v_ins_}) total += b->bytes();
    total += rgb8_.bytes() + select_keep_.bytes() + select_offsets_.bytes() + select_counts_.bytes();
    total += select_temp_bytes_;
    for (const auto& b : select_index_) total += b->bytes();
    return total + resident_->bytes() + gradients_.bytes() + pipe_.bytes() + sums_.bytes();
  }

 private:
  static void report_lost(const char* why) {
    std::fprintf(stderr, "CUDA training engine: the trained attributes since the last fetch are lost (%s)\n", why);
  }

  std::vector<double> run_resident(const std::vector<gs::TrainingView>& views,
                                   const std::vector<gs::TrainingStep>& steps, const gs::TrainingLoss& loss,
                                   gs::GaussianMap* map, gs::GaussianAdam* adam) {
    std::vector<double> losses(steps.size(), 0.0);
    const cudaStream_t stream = pipe_.stream();
    clock_.start(stream);
    // What the host appended or flagged since the last batch, up.
    resident_->sync_up(*map, *adam, stream);
    clock_.end(detail::Stage::kUpload, stream);
    const detail::DeviceTrainable t = resident_->trainable();
    const detail::DeviceGaussians g = resident_->gaussians();
    const std::vector<Selection> selection = select(views, steps, loss, g);
    clock_.end(detail::Stage::kSelect, stream);
    const detail::DeviceAttributeGradients grad = gradients_.get(std::max<size_t>(g.count, 1));
    double* sums = sums_.ensure(3 * steps.size(), "loss sums");
    check(cudaMemsetAsync(sums, 0, 3 * steps.size() * sizeof(double), stream), "loss sums");

    const gs::GaussianAdam::Params& ap = adam->params();
    const detail::AdamRates rates{ap.lr_position, ap.lr_log_scale, ap.lr_rotation, ap.lr_colour, ap.beta1,
                                  ap.beta2,       ap.epsilon,      ap.normalise_rotation, ap.clamp_colour};
    std::vector<double> rgb_norm(steps.size()), depth_norm(steps.size()), ins_norm(steps.size());
    for (size_t k = 0; k < steps.size(); ++k) {
      const gs::TrainingView& view = views[steps[k].view];
      const CachedView& cv = *cache_.at(view.key);
      gs::RenderSettings settings = loss.settings;
      settings.ins_object = steps[k].object;
      const gs::CameraView<float> cam = gs::detail::make_camera_view<float>(*view.camera, view.T_cw, settings.near);
      // The pass on the view's selection: the map's entries through its list, or all of them.
      const Selection& sel = selection[steps[k].view];
      detail::DeviceGaussians gk = g;
      detail::DeviceTrainable tk = t;
      gk.index = tk.index = sel.index;
      gk.count = tk.count = sel.count;
      pipe_.forward(gk, cam, settings, true);
      pair_sum_ += static_cast<double>(pipe_.pairs());
      tile_sum_ += std::ceil(view.camera->width / double(detail::kTileSize)) *
                   std::ceil(view.camera->height / double(detail::kTileSize));
      const size_t pixels = cv.pixels;
      // The host's factors (losses.cpp): λ · (1 / weight sum), taken in double, used in float.
      detail::LossFactors f;
      rgb_norm[k] = 1.0 / (3.0 * static_cast<double>(pixels));
      f.rgb = static_cast<float>(rgb_norm[k]);
      if (loss.lambda_depth > 0.f && cv.valid_depth > 0) {
        depth_norm[k] = static_cast<double>(loss.lambda_depth) / static_cast<double>(cv.valid_depth);
        f.depth = static_cast<float>(depth_norm[k]);
      }
      if (loss.lambda_ins > 0.f && steps[k].object != 0) {
        ins_norm[k] = static_cast<double>(loss.lambda_ins) / static_cast<double>(pixels);
        f.ins = static_cast<float>(ins_norm[k]);
        f.object = steps[k].object;
      }
      float* v_rgb = v_rgb_.ensure(3 * pixels, "output gradients");
      float* v_depth = f.depth > 0.f ? v_depth_.ensure(pixels, "output gradients") : nullptr;
      float* v_ins = f.ins > 0.f ? v_ins_.ensure(pixels, "output gradients") : nullptr;
      const detail::ForwardImages& img = pipe_.images();
      const detail::DeviceView dv{cv.rgb.get(), cv.depth.get(), cv.labels.get()};
      detail::launch_losses(pixels, img.rgb, img.depth, img.ins, dv, f, v_rgb, v_depth, v_ins, sums + 3 * k, stream);
      check(cudaGetLastError(), "losses");
      clock_.end(detail::Stage::kLosses, stream);
      detail::ImageGradientsDevice go;
      go.rgb = v_rgb;
      go.depth = v_depth;
      go.ins = v_ins;
      pipe_.backward(gk, cam, go, grad, /*zero_culled=*/false);
      detail::launch_adam(tk, pipe_.tile_counts(), grad.position, grad.log_scale, grad.rotation, grad.colour, rates,
                          stream);
      check(cudaGetLastError(), "Adam");
      clock_.end(detail::Stage::kAdam, stream);
    }

    // Every iteration done without error before the host's map changes; then the trained
    // attributes and the loss sums down (the optimiser state stays).
    std::vector<double> host_sums;
    check(cudaStreamSynchronize(stream), "training batch");
    if (defer_) {
      pending_ = true;  // the map's attributes stay on the device until fetch_attributes()
    } else {
      resident_->download_trained(map, stream);
    }
    download(&host_sums, sums, 3 * steps.size(), stream);
    clock_.end(detail::Stage::kDownload, stream);
    check(cudaStreamSynchronize(stream), "training batch");
    clock_.collect();
    for (size_t k = 0; k < steps.size(); ++k) {
      losses[k] = host_sums[3 * k] * rgb_norm[k] + host_sums[3 * k + 1] * depth_norm[k] +
                  host_sums[3 * k + 2] * ins_norm[k];
    }
    return losses;
  }

  // A view's passes work on the map's entries index[0 .. count), or on the first count (all).
  struct Selection {
    const uint32_t* index = nullptr;
    size_t count = 0;
  };
  // The list below this share of the map: above, the list's indirection costs the passes about
  // what leaving the rest out saves.
  static constexpr double kListBelow = 0.9;

  // The batch's selection (train_select.cu): for each view the steps name, the Gaussians its
  // projection keeps, so that its passes (projection, binning, gradients, Adam) grow with what it
  // sees rather than with the map; the others get no gradient from it. One wait for the counts.
  std::vector<Selection> select(const std::vector<gs::TrainingView>& views, const std::vector<gs::TrainingStep>& steps,
                                const gs::TrainingLoss& loss, const detail::DeviceGaussians& g) {
    const size_t n = g.count;
    std::vector<Selection> out(views.size(), Selection{nullptr, n});
    std::vector<size_t> used;
    for (const gs::TrainingStep& s : steps)
      if (std::find(used.begin(), used.end(), s.view) == used.end()) used.push_back(s.view);
    while (select_index_.size() < used.size()) select_index_.push_back(std::make_unique<DeviceBuffer<uint32_t>>());
    uint32_t* keep = select_keep_.ensure(n + 1, "batch selection");
    uint32_t* offsets = select_offsets_.ensure(n + 1, "batch selection");
    uint32_t* counts = select_counts_.ensure(used.size(), "batch selection");
    const cudaStream_t stream = pipe_.stream();
    for (size_t k = 0; k < used.size(); ++k) {
      const gs::TrainingView& v = views[used[k]];
      const gs::CameraView<float> cam = gs::detail::make_camera_view<float>(*v.camera, v.T_cw, loss.settings.near);
      uint32_t* index = select_index_[k]->ensure(std::max<size_t>(n, 1), "batch selection");
      check(detail::select_in_view(g, cam, keep, offsets, index, counts + k, &select_temp_, &select_temp_bytes_,
                                   stream),
            "batch selection");
    }
    std::vector<uint32_t> selected(used.size());
    check(cudaMemcpyAsync(selected.data(), counts, used.size() * sizeof(uint32_t), cudaMemcpyDeviceToHost, stream),
          "batch selection");
    check(cudaStreamSynchronize(stream), "batch selection");
    for (size_t k = 0; k < used.size(); ++k) {
      selected_ += selected[k], selectable_ += n;
      if (selected[k] < kListBelow * static_cast<double>(n))
        out[used[k]] = Selection{select_index_[k]->get(), selected[k]};
    }
    return out;
  }

  // Keeps the images of `views` on the device (new keys up, keys no longer in the window freed).
  // The view's images on the device: cached by key, uploaded on first use (by the review, before
  // the batch that trains on the same keyframe).
  CachedView& cached(const gs::TrainingView& view) {
    const auto it = cache_.find(view.key);
    if (it != cache_.end()) return *it->second;
    const PinholeCamera& cam = *view.camera;
    const size_t pixels = static_cast<size_t>(cam.width) * cam.height;
    if (!view.rgb || !view.depth || !view.labels || view.rgb->data.size() != 3 * pixels ||
        view.depth->data.size() != pixels || view.labels->data.size() != pixels) {
      throw std::invalid_argument("CUDA training engine: a view's images do not match its camera");
    }
    // The views that left the window lend their buffers to the new ones (a pool of image buffers:
    // no cudaMalloc and cudaFree a keyframe, each of which waits for the device). Reuse is
    // stream-ordered after the batches that read them.
    std::unique_ptr<CachedView> cv;
    if (!spare_.empty()) {
      cv = std::move(spare_.back());
      spare_.pop_back();
    } else {
      cv = std::make_unique<CachedView>();
    }
    cv->pixels = pixels;
    cv->valid_depth = 0;
    for (const float d : view.depth->data) cv->valid_depth += valid_depth(d) ? 1 : 0;
    const cudaStream_t stream = pipe_.stream();
    // 8 bits up (a quarter of the floats' bytes), floats made here. The copies are from pageable
    // memory: each returns once its bytes are staged, so the host images may go afterwards.
    const uint8_t* rgb8 = upload(&rgb8_, view.rgb->data, "view images", stream);
    detail::launch_unit_colours(3 * pixels, rgb8, cv->rgb.ensure(3 * pixels, "view images"), stream);
    check(cudaGetLastError(), "view images");
    upload(&cv->depth, view.depth->data, "view images", stream);
    upload(&cv->labels, view.labels->data, "view images", stream);
    return *cache_.emplace(view.key, std::move(cv)).first->second;
  }

  // The window's views cached, those gone from it moved to the spares (at most kSpareViews kept).
  void cache_views(const std::vector<gs::TrainingView>& views) {
    for (auto it = cache_.begin(); it != cache_.end();) {
      const bool wanted = std::any_of(views.begin(), views.end(),
                                      [&](const gs::TrainingView& v) { return v.key == it->first; });
      if (wanted) {
        ++it;
      } else {
        spare_.push_back(std::move(it->second));
        it = cache_.erase(it);
      }
    }
    for (const gs::TrainingView& view : views) cached(view);
    check(cudaStreamSynchronize(pipe_.stream()), "view images");
    if (spare_.size() > kSpareViews) spare_.resize(kSpareViews);  // freed: the stream is idle now
  }

  static constexpr size_t kSpareViews = 2;

  detail::StageClock clock_;  // before pipe_: the pipeline holds a pointer to it
  detail::RasterPipeline pipe_;
  std::map<uint64_t, std::unique_ptr<CachedView>> cache_;
  std::vector<std::unique_ptr<CachedView>> spare_;  // buffers of views gone from the window
  std::shared_ptr<detail::ResidentMap> resident_;  // shared with the backend's rasteriser
  const bool shared_;
  detail::GradientBuffers gradients_;
  DeviceBuffer<float> v_rgb_, v_depth_, v_ins_;
  DeviceBuffer<uint8_t> rgb8_;  // a view's 8-bit colours on their way up (stream-ordered reuse)
  DeviceBuffer<double> sums_;
  // review()'s: the trainer's counters, the relabels and their count.
  DeviceBuffer<float> review_usefulness_;
  DeviceBuffer<uint32_t> review_count_;
  DeviceBuffer<uint16_t> review_invisible_;
  DeviceBuffer<uint8_t> review_votes_;
  DeviceBuffer<uint2> review_relabels_;
  DeviceBuffer<uint8_t> flag_bytes_;  // flag_prune()'s
  // select()'s scratch, counts and lists (one per view of a batch); the scan's scratch; the sums
  // of the selections' sizes and of the map's (the share the passes worked on, with the stage
  // times).
  DeviceBuffer<uint32_t> select_keep_, select_offsets_, select_counts_;
  std::vector<std::unique_ptr<DeviceBuffer<uint32_t>>> select_index_;
  void* select_temp_ = nullptr;
  size_t select_temp_bytes_ = 0;
  double selected_ = 0.0, selectable_ = 0.0;
  double pair_sum_ = 0.0, tile_sum_ = 0.0;  // the training passes' pairs and tiles (their lists' mean length)
  // Deferred attributes (defer_attributes()): asked for; the device's newer than the host map's;
  // what a failed removal brought down for fetch_attributes().
  bool defer_ = false;
  bool pending_ = false;
  std::unique_ptr<detail::ResidentMap::Trained> rescued_;
};

}  // namespace

std::unique_ptr<gs::TrainingEngine> make_cuda_training_engine() {
  require_device();
  return std::make_unique<CudaTrainingEngine>(std::make_shared<detail::ResidentMap>(), false);
}

namespace detail {
std::unique_ptr<gs::TrainingEngine> make_cuda_training_engine_sharing(std::shared_ptr<ResidentMap> resident) {
  require_device();
  return std::make_unique<CudaTrainingEngine>(std::move(resident), true);
}
}  // namespace detail

}  // namespace dqo::cuda
