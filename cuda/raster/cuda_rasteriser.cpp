// The CUDA rasteriser's host side (compiled by the C++ compiler: Eigen and the map stay out of
// nvcc): uploads the map's arrays (or, in a backend, renders the engine's copy while it shows the
// map: cuda_backend.h), runs the device pipeline (raster_pipeline.h) and brings the images back.
// Device buffers are kept and grown between frames, so a warm rasteriser allocates nothing.

#include "dqo_map/cuda/cuda_rasteriser.h"

#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>

#include "dqo_map/gaussians/detail/cpu_rasteriser.h"
#include "dqo_map/gaussians/gaussian_map.h"
#include "../train/resident_map.h"
#include "raster_pipeline.h"

namespace dqo::cuda {

namespace {

static_assert(static_cast<uint8_t>(gs::GaussianType::kOpaque) == detail::kOpaqueType,
              "raster_cuda.h's copy of the opaque type");

// What forward() hands out for backward(): the pipeline keeps the projected Gaussians, tile lists
// and per-pixel state of its latest forward pass on the device; the state names that pass.
struct CudaRenderState final : gs::RenderState {
  const void* owner = nullptr;
  uint64_t generation = 0;
};

class CudaRasteriser final : public gs::Rasteriser {
 public:
  // shared: the resident map of the backend's training engine (null: this rasteriser alone).
  explicit CudaRasteriser(std::shared_ptr<detail::ResidentMap> shared = nullptr) : shared_(std::move(shared)) {}

  void forward(const gs::GaussianMap& map, const PinholeCamera& camera, const SE3& T_cw,
               const gs::RenderSettings& settings, gs::RenderOutput* out,
               std::unique_ptr<gs::RenderState>* state) override {
    if (state) state->reset();
    ++generation_;
    n_ = 0;  // no backward() for this pass unless it completes
    const cudaStream_t stream = pipe_.stream();
    const size_t n = map.size();
    const size_t pixels = static_cast<size_t>(camera.width) * camera.height;
    pipe_.mark(0);
    // The engine's copy where it shows this map (trained there, nothing sent; shows() checks the
    // map's revision, so its IDs and types are the map's too); else the map goes up.
    detail::DeviceGaussians g;
    const bool resident = shared_ && shared_->shows(map);
    if (resident) {
      shared_->wait();
      g = shared_->gaussians();
    } else {
      g.count = n;
      g.position = upload(&position_, map.positions(), "positions", stream);
      g.log_scale = upload(&log_scale_, map.log_scales(), "log-scales", stream);
      g.rotation = upload(&rotation_, map.rotations(), "rotations", stream);
      g.opacity = upload(&opacity_, map.opacities(), "opacities", stream);
      g.colour = upload(&colour_, map.colours(), "colours", stream);
      g.object_id = upload(&object_id_, map.object_ids_per_gaussian(), "object IDs", stream);
      g.type = upload(&type_, map.types(), "types", stream);
    }
    const gs::CameraView<float> cam = gs::detail::make_camera_view<float>(camera, T_cw, settings.near);
    pipe_.forward(g, cam, settings, state != nullptr);
    const detail::ForwardImages& img = pipe_.images();
    out->width = camera.width;
    out->height = camera.height;
    // The images asked for come down; the others are left empty (RenderSettings::outputs).
    const auto bring = [&](auto* host, const auto* device, size_t count, gs::RenderImage bit) {
      if (settings.outputs & bit)
        download(host, device, count, stream);
      else
        host->clear();
    };
    bring(&out->rgb, img.rgb, 3 * pixels, gs::kRenderRgb);
    bring(&out->depth, img.depth, pixels, gs::kRenderDepth);
    bring(&out->alpha, img.alpha, pixels, gs::kRenderAlpha);
    bring(&out->ins, img.ins, pixels, gs::kRenderIns);
    bring(&out->dominant_id, img.dominant_id, pixels, gs::kRenderDominantId);
    pipe_.mark(5);
    check(cudaStreamSynchronize(stream), "compositing");
    timings_ = ForwardTimings{pipe_.ms_between(0, 1), pipe_.project_ms(), pipe_.bin_ms(), pipe_.composite_ms(),
                              pipe_.ms_between(4, 5), 0.0, pipe_.pairs(), resident};
    gaussians_ = g;
    n_ = n;
    if (state) {
      auto st = std::make_unique<CudaRenderState>();
      st->owner = this;
      st->generation = generation_;
      *state = std::move(st);
    }
  }

  const ForwardTimings& timings() const { return timings_; }

  void backward(const gs::GaussianMap& map, const PinholeCamera& camera, const SE3& T_cw,
                const gs::RenderSettings& settings, const gs::RenderState& state, const gs::OutputGradients& grad_out,
                gs::MapGradients* grad_map) override {
    const auto* st = dynamic_cast<const CudaRenderState*>(&state);
    if (!st || st->owner != this || st->generation != generation_ || map.size() != n_) {
      throw std::invalid_argument(
          "CUDA rasteriser: backward() needs the state of this rasteriser's latest forward() on the same map");
    }
    const cudaStream_t stream = pipe_.stream();
    const size_t n = n_;
    const size_t pixels = static_cast<size_t>(camera.width) * camera.height;
    auto upload_or_null = [&](DeviceBuffer<float>* b, const std::vector<float>& v, size_t expected) -> const float* {
      if (v.empty()) return nullptr;
      if (v.size() != expected) throw std::invalid_argument("CUDA rasteriser: an output gradient of the wrong size");
      return upload(b, v, "output gradients", stream);
    };
    detail::ImageGradientsDevice go;
    go.rgb = upload_or_null(&v_rgb_, grad_out.rgb, 3 * pixels);
    go.depth = upload_or_null(&v_depth_, grad_out.depth, pixels);
    go.alpha = upload_or_null(&v_alpha_, grad_out.alpha, pixels);
    go.ins = upload_or_null(&v_ins_, grad_out.ins, pixels);
    if (go.ins && settings.ins_labels)
      throw std::invalid_argument("CUDA rasteriser: no gradient of a per-label instance opacity");
    const detail::DeviceAttributeGradients d = gradients_.get(n);
    const gs::CameraView<float> cam = gs::detail::make_camera_view<float>(camera, T_cw, settings.near);
    pipe_.backward(gaussians_, cam, go, d);
    // All five (or the colour's alone) down, one wait, then added (MapGradients accumulates);
    // an array left empty (or of another size) is sized zero-filled first, so the gradient
    // comes down straight into it (0 + g is g).
    const int first = grad_map->colour_only ? 4 : 0;
    std::vector<float> host[5];
    const std::pair<const float*, size_t> blocks[] = {
        {d.position, 3 * n}, {d.log_scale, 3 * n}, {d.rotation, 4 * n}, {d.opacity, n}, {d.colour, 3 * n}};
    std::vector<float>* dst[5] = {&grad_map->position, &grad_map->log_scale, &grad_map->rotation,
                                  &grad_map->opacity, &grad_map->colour};
    bool direct[5] = {false, false, false, false, false};
    for (int b = first; b < 5; ++b) {
      direct[b] = dst[b]->size() != blocks[b].second;
      download(direct[b] ? dst[b] : &host[b], blocks[b].first, blocks[b].second, stream);
    }
    check(cudaStreamSynchronize(stream), "gradients");
    for (int b = first; b < 5; ++b)
      if (!direct[b])
        for (size_t k = 0; k < host[b].size(); ++k) (*dst[b])[k] += host[b][k];
    timings_.backward_ms = pipe_.backward_ms();
  }

 private:
  detail::RasterPipeline pipe_;
  DeviceBuffer<float> position_, log_scale_, rotation_, opacity_, colour_;
  DeviceBuffer<uint32_t> object_id_;
  DeviceBuffer<uint8_t> type_;
  ForwardTimings timings_;
  std::shared_ptr<detail::ResidentMap> shared_;
  // The latest forward pass, for backward().
  uint64_t generation_ = 0;
  size_t n_ = 0;
  detail::DeviceGaussians gaussians_;  // the map as the latest forward() rendered it (uploaded or shared)
  DeviceBuffer<float> v_rgb_, v_depth_, v_alpha_, v_ins_;
  detail::GradientBuffers gradients_;
};

}  // namespace

std::optional<ForwardTimings> last_forward_timings(const gs::Rasteriser& rasteriser) {
  const auto* r = dynamic_cast<const CudaRasteriser*>(&rasteriser);
  if (!r) return std::nullopt;
  return r->timings();
}

std::unique_ptr<gs::Rasteriser> make_cuda_rasteriser() {
  require_device();
  return std::make_unique<CudaRasteriser>();
}

namespace detail {
std::unique_ptr<gs::Rasteriser> make_cuda_rasteriser_sharing(std::shared_ptr<ResidentMap> resident) {
  require_device();
  return std::make_unique<CudaRasteriser>(std::move(resident));
}
}  // namespace detail

}  // namespace dqo::cuda
