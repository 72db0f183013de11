// The CPU reference rasteriser: sequences the stages (raster_projection → raster_binning →
// raster_forward; raster_backward) and adapts the map and the public buffers to the templated core.

#include <stdexcept>
#include <string>

#include "raster_internal.h"

namespace dqo::gs {

void MapGradients::resize_for(const GaussianMap& map) {
  const size_t n = map.size();
  position.assign(3 * n, 0.f);
  log_scale.assign(3 * n, 0.f);
  rotation.assign(4 * n, 0.f);
  opacity.assign(n, 0.f);
  colour.assign(3 * n, 0.f);
}

namespace detail {

GaussianArrays<float> arrays_of(const GaussianMap& map) {
  GaussianArrays<float> a;
  a.count = map.size();
  a.position = map.positions().data();
  a.log_scale = map.log_scales().data();
  a.rotation = map.rotations().data();
  a.opacity = map.opacities().data();
  a.colour = map.colours().data();
  a.object_id = map.object_ids_per_gaussian().data();
  a.type = map.types().data();
  return a;
}

template <typename S>
void cpu_forward(const GaussianArrays<S>& gaussians, const PinholeCamera& camera, const SE3& T_cw,
                 const RenderSettings& settings, int threads, const ImageBuffers<S>& out,
                 std::unique_ptr<RenderState>* state) {
  if (camera.width <= 0 || camera.height <= 0 || !(camera.fx > 0) || !(camera.fy > 0))
    throw std::invalid_argument("cpu rasteriser: camera without pixels or focal length");
  if (camera.width > kMaxImageSide || camera.height > kMaxImageSide)
    throw std::invalid_argument("cpu rasteriser: image larger than " +
                                std::to_string(kMaxImageSide) + " pixels on a side");
  threads = resolve_threads(threads);
  auto s = std::make_unique<CpuRenderState<S>>();
  s->gaussian_count = gaussians.count;
  s->width = camera.width;
  s->height = camera.height;
  const CameraView<S> view = make_camera_view<S>(camera, T_cw, settings.near);
  project_gaussians(gaussians, view, settings, threads, &s->projected);
  bin_gaussians(s->projected, camera.width, camera.height, &s->bins);
  composite_forward(settings, threads, out, s.get());
  if (state) *state = std::move(s);
}

template <typename S>
void cpu_backward(const GaussianArrays<S>& gaussians, const PinholeCamera& camera, const SE3& T_cw,
                  const RenderSettings& settings, int threads, const RenderState& state,
                  const ImageGradients<S>& grad_out, const AttributeGradients<S>& grad) {
  const auto* s = dynamic_cast<const CpuRenderState<S>*>(&state);
  if (!s) throw std::invalid_argument("cpu rasteriser: backward() given another backend's state");
  if (s->gaussian_count != gaussians.count || s->width != camera.width ||
      s->height != camera.height)
    throw std::invalid_argument(
        "cpu rasteriser: backward() with a map or camera other than the forward pass's (" +
        std::to_string(gaussians.count) + " Gaussians, forward had " +
        std::to_string(s->gaussian_count) + ")");
  threads = resolve_threads(threads);
  const CameraView<S> view = make_camera_view<S>(camera, T_cw, settings.near);
  composite_backward(gaussians, view, settings, threads, *s, grad_out, grad);
}

template void cpu_forward<float>(const GaussianArrays<float>&, const PinholeCamera&, const SE3&,
                                 const RenderSettings&, int, const ImageBuffers<float>&,
                                 std::unique_ptr<RenderState>*);
template void cpu_forward<double>(const GaussianArrays<double>&, const PinholeCamera&, const SE3&,
                                  const RenderSettings&, int, const ImageBuffers<double>&,
                                  std::unique_ptr<RenderState>*);
template void cpu_backward<float>(const GaussianArrays<float>&, const PinholeCamera&, const SE3&,
                                  const RenderSettings&, int, const RenderState&,
                                  const ImageGradients<float>&, const AttributeGradients<float>&);
template void cpu_backward<double>(const GaussianArrays<double>&, const PinholeCamera&, const SE3&,
                                   const RenderSettings&, int, const RenderState&,
                                   const ImageGradients<double>&,
                                   const AttributeGradients<double>&);

}  // namespace detail

namespace {

// An output gradient of the wrong size is a caller's bug; an empty one means zero.
const float* gradient_or_null(const std::vector<float>& v, size_t expected, const char* name) {
  if (v.empty()) return nullptr;
  if (v.size() != expected)
    throw std::invalid_argument(std::string("cpu rasteriser: OutputGradients::") + name + " has " +
                                std::to_string(v.size()) + " values, expected " +
                                std::to_string(expected));
  return v.data();
}

class CpuRasteriser final : public Rasteriser {
 public:
  explicit CpuRasteriser(int threads) : threads_(detail::resolve_threads(threads)) {}

  void forward(const GaussianMap& map, const PinholeCamera& camera, const SE3& T_cw,
               const RenderSettings& settings, RenderOutput* out,
               std::unique_ptr<RenderState>* state) override {
    const size_t pixels = static_cast<size_t>(std::max(camera.width, 0)) *
                          static_cast<size_t>(std::max(camera.height, 0));
    out->width = camera.width;
    out->height = camera.height;
    out->rgb.resize(3 * pixels);
    out->depth.resize(pixels);
    out->alpha.resize(pixels);
    out->ins.resize(pixels);
    out->dominant_id.resize(pixels);
    detail::ImageBuffers<float> buffers;
    buffers.rgb = out->rgb.data();
    buffers.depth = out->depth.data();
    buffers.alpha = out->alpha.data();
    buffers.ins = out->ins.data();
    buffers.dominant_id = out->dominant_id.data();
    detail::cpu_forward(detail::arrays_of(map), camera, T_cw, settings, threads_, buffers, state);
  }

  void backward(const GaussianMap& map, const PinholeCamera& camera, const SE3& T_cw,
                const RenderSettings& settings, const RenderState& state,
                const OutputGradients& grad_out, MapGradients* grad_map) override {
    const size_t pixels = static_cast<size_t>(camera.width) * camera.height;
    detail::ImageGradients<float> g_out;
    g_out.rgb = gradient_or_null(grad_out.rgb, 3 * pixels, "rgb");
    g_out.depth = gradient_or_null(grad_out.depth, pixels, "depth");
    g_out.ins = gradient_or_null(grad_out.ins, pixels, "ins");
    if (g_out.ins && settings.ins_labels)
      throw std::invalid_argument("cpu rasteriser: no gradient of a per-label instance opacity");
    g_out.alpha = gradient_or_null(grad_out.alpha, pixels, "alpha");
    const size_t n = map.size();
    // Colour only: the other arrays (which the backward pass fills all the same) go to scratch.
    MapGradients scratch;
    MapGradients* into = grad_map;
    if (grad_map->colour_only) {
      if (grad_map->colour.size() != 3 * n) grad_map->colour.assign(3 * n, 0.f);
      scratch.resize_for(map);
      scratch.colour.swap(grad_map->colour);
      into = &scratch;
    }
    if (into->position.empty() && into->opacity.empty()) into->resize_for(map);
    if (into->position.size() != 3 * n || into->log_scale.size() != 3 * n || into->rotation.size() != 4 * n ||
        into->opacity.size() != n || into->colour.size() != 3 * n)
      throw std::invalid_argument("cpu rasteriser: MapGradients not sized for the map");
    detail::AttributeGradients<float> g;
    g.position = into->position.data();
    g.log_scale = into->log_scale.data();
    g.rotation = into->rotation.data();
    g.opacity = into->opacity.data();
    g.colour = into->colour.data();
    detail::cpu_backward(detail::arrays_of(map), camera, T_cw, settings, threads_, state, g_out, g);
    if (grad_map->colour_only) grad_map->colour.swap(scratch.colour);
  }

 private:
  int threads_;
};

}  // namespace

std::unique_ptr<Rasteriser> make_cpu_rasteriser(int threads) {
  return std::make_unique<CpuRasteriser>(threads);
}

}  // namespace dqo::gs
