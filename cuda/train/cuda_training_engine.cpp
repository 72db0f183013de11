// The CUDA training engine's host side (cuda_training_engine.h): the map and optimiser state up
// once per batch, the views' images cached by key, every iteration on the rasteriser's device
// pipeline and this ring's loss and Adam kernels, the map and the state down once.

#include "dqo_map/cuda/cuda_training_engine.h"

#include <cmath>
#include <map>
#include <stdexcept>
#include <string>
#include <utility>

#include "../common/device_buffer.h"
#include "../raster/raster_pipeline.h"
#include "dqo_map/gaussians/detail/cpu_rasteriser.h"
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
    const cudaStream_t stream = pipe_.stream();

    // The map and the optimiser state, up.
    detail::DeviceTrainable t;
    t.count = n;
    t.position = upload(&position_, map->positions(), "positions", stream);
    t.log_scale = upload(&log_scale_, map->log_scales(), "log-scales", stream);
    t.rotation = upload(&rotation_, map->rotations(), "rotations", stream);
    t.colour = upload(&colour_, map->colours(), "colours", stream);
    t.confidence = upload(&confidence_, map->confidences(), "confidences", stream);
    t.stable = upload(&stable_, map->stable(), "stable flags", stream);
    const gs::GaussianAdam::State& st = adam->state();
    const gs::GaussianAdam::Moments* moments[4] = {&st.position, &st.log_scale, &st.rotation, &st.colour};
    for (int a = 0; a < 4; ++a) {
      t.m[a] = upload(&m_[a], moments[a]->m, "Adam moments", stream);
      t.v[a] = upload(&v_[a], moments[a]->v, "Adam moments", stream);
    }
    t.steps = upload(&steps_, st.steps, "Adam steps", stream);
    detail::DeviceGaussians g;
    g.count = n;
    g.position = t.position;
    g.log_scale = t.log_scale;
    g.rotation = t.rotation;
    g.colour = t.colour;
    g.opacity = upload(&opacity_, map->opacities(), "opacities", stream);
    g.object_id = upload(&object_id_, map->object_ids_per_gaussian(), "object IDs", stream);
    g.type = upload(&type_, map->types(), "types", stream);
    const detail::DeviceAttributeGradients grad = gradients_.get(n);
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
      pipe_.forward(g, cam, settings, true);
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
      detail::ImageGradientsDevice go;
      go.rgb = v_rgb;
      go.depth = v_depth;
      go.ins = v_ins;
      pipe_.backward(g, cam, go, grad);
      detail::launch_adam(t, grad.position, grad.log_scale, grad.rotation, grad.colour, rates, stream);
      check(cudaGetLastError(), "Adam");
    }

    // Down, all of it, one wait; only then does the host state change.
    std::vector<float> position, log_scale, rotation, colour, confidence;
    std::vector<float> m[4], v[4];
    std::vector<uint32_t> step_counts;
    std::vector<double> host_sums;
    download(&position, t.position, 3 * n, stream);
    download(&log_scale, t.log_scale, 3 * n, stream);
    download(&rotation, t.rotation, 4 * n, stream);
    download(&colour, t.colour, 3 * n, stream);
    download(&confidence, t.confidence, n, stream);
    for (int a = 0; a < 4; ++a) {
      download(&m[a], t.m[a], moments[a]->m.size(), stream);
      download(&v[a], t.v[a], moments[a]->v.size(), stream);
    }
    download(&step_counts, t.steps, n, stream);
    download(&host_sums, sums, 3 * steps.size(), stream);
    check(cudaStreamSynchronize(stream), "training batch");
    map->positions() = std::move(position);
    map->log_scales() = std::move(log_scale);
    map->rotations() = std::move(rotation);
    map->colours() = std::move(colour);
    map->confidences() = std::move(confidence);
    gs::GaussianAdam::State& state = adam->mutable_state();
    gs::GaussianAdam::Moments* dst[4] = {&state.position, &state.log_scale, &state.rotation, &state.colour};
    for (int a = 0; a < 4; ++a) {
      dst[a]->m = std::move(m[a]);
      dst[a]->v = std::move(v[a]);
    }
    state.steps = std::move(step_counts);
    for (size_t k = 0; k < steps.size(); ++k) {
      losses[k] = host_sums[3 * k] * rgb_norm[k] + host_sums[3 * k + 1] * depth_norm[k] +
                  host_sums[3 * k + 2] * ins_norm[k];
    }
    return losses;
  }

  size_t device_bytes() const override {
    size_t total = 0;
    for (const auto& [key, cv] : cache_) total += cv->rgb.bytes() + cv->depth.bytes() + cv->labels.bytes();
    for (const auto* b : {&position_, &log_scale_, &rotation_, &colour_, &confidence_, &opacity_, &v_rgb_, &v_depth_,
                          &v_ins_})
      total += b->bytes();
    total += gradients_.bytes() + pipe_.bytes();
    for (int a = 0; a < 4; ++a) total += m_[a].bytes() + v_[a].bytes();
    return total + stable_.bytes() + type_.bytes() + object_id_.bytes() + steps_.bytes() + sums_.bytes();
  }

 private:
  // Keeps the images of `views` on the device (new keys up, keys no longer in the window freed).
  void cache_views(const std::vector<gs::TrainingView>& views) {
    std::map<uint64_t, std::unique_ptr<CachedView>> kept;
    for (const gs::TrainingView& view : views) {
      if (kept.count(view.key)) continue;
      auto it = cache_.find(view.key);
      if (it != cache_.end()) {
        kept.emplace(view.key, std::move(it->second));
        cache_.erase(it);
        continue;
      }
      const PinholeCamera& cam = *view.camera;
      const size_t pixels = static_cast<size_t>(cam.width) * cam.height;
      if (!view.rgb || !view.depth || !view.labels || view.rgb->data.size() != 3 * pixels ||
          view.depth->data.size() != pixels || view.labels->data.size() != pixels) {
        throw std::invalid_argument("CUDA training engine: a view's images do not match its camera");
      }
      auto cv = std::make_unique<CachedView>();
      cv->pixels = pixels;
      for (const float d : view.depth->data) cv->valid_depth += valid_depth(d) ? 1 : 0;
      const cudaStream_t stream = pipe_.stream();
      upload(&cv->rgb, view.rgb->data, "view images", stream);
      upload(&cv->depth, view.depth->data, "view images", stream);
      upload(&cv->labels, view.labels->data, "view images", stream);
      kept.emplace(view.key, std::move(cv));
    }
    // The host vectors stay alive until the batch ends (the trainer's window), so the copies need
    // no wait here; the views that left the window are freed after the stream's earlier work.
    check(cudaStreamSynchronize(pipe_.stream()), "view images");
    cache_ = std::move(kept);
  }

  detail::RasterPipeline pipe_;
  std::map<uint64_t, std::unique_ptr<CachedView>> cache_;
  DeviceBuffer<float> position_, log_scale_, rotation_, colour_, confidence_, opacity_;
  DeviceBuffer<uint8_t> stable_, type_;
  DeviceBuffer<uint32_t> object_id_, steps_;
  DeviceBuffer<float> m_[4], v_[4];
  detail::GradientBuffers gradients_;
  DeviceBuffer<float> v_rgb_, v_depth_, v_ins_;
  DeviceBuffer<double> sums_;
};

}  // namespace

std::unique_ptr<gs::TrainingEngine> make_cuda_training_engine() {
  require_device();
  return std::make_unique<CudaTrainingEngine>();
}

}  // namespace dqo::cuda
