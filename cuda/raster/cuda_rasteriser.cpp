// The CUDA rasteriser's host side (compiled by the C++ compiler: Eigen and the map stay out of
// nvcc): uploads the map's arrays, runs the three stages on one stream and brings the images back.
// Device buffers are kept and grown between frames, so a warm rasteriser allocates nothing.

#include "dqo_map/cuda/cuda_rasteriser.h"

#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "dqo_map/gaussians/detail/cpu_rasteriser.h"
#include "dqo_map/gaussians/gaussian_map.h"
#include "raster_cuda.h"

namespace dqo::cuda {

namespace {

static_assert(static_cast<uint8_t>(gs::GaussianType::kOpaque) == detail::kOpaqueType,
              "raster_cuda.h's copy of the opaque type");

void check(cudaError_t err, const char* what) {
  if (err == cudaSuccess) return;
  cudaGetLastError();  // clear a non-sticky error so that the next frame can try again
  throw std::runtime_error(std::string("CUDA rasteriser: ") + what + ": " + cudaGetErrorString(err));
}

// A device array that only grows.
template <typename T>
class DeviceBuffer {
 public:
  DeviceBuffer() = default;
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
  ~DeviceBuffer() {
    if (ptr_) cudaFree(ptr_);
  }
  T* ensure(size_t n, const char* what) {
    if (n <= capacity_ && ptr_) return ptr_;
    if (ptr_) cudaFree(ptr_);
    ptr_ = nullptr;
    capacity_ = 0;
    const size_t want = std::max<size_t>(n, 1);
    check(cudaMalloc(reinterpret_cast<void**>(&ptr_), want * sizeof(T)), what);
    capacity_ = want;
    return ptr_;
  }
  T* get() const { return ptr_; }

 private:
  T* ptr_ = nullptr;
  size_t capacity_ = 0;
};

template <typename T>
const T* upload(DeviceBuffer<T>* buffer, const std::vector<T>& host, const char* what, cudaStream_t stream) {
  T* d = buffer->ensure(host.size(), what);
  if (!host.empty()) check(cudaMemcpyAsync(d, host.data(), host.size() * sizeof(T), cudaMemcpyHostToDevice, stream), what);
  return d;
}

template <typename T>
void download(std::vector<T>* host, const T* device, size_t n, cudaStream_t stream) {
  host->resize(n);
  if (n) check(cudaMemcpyAsync(host->data(), device, n * sizeof(T), cudaMemcpyDeviceToHost, stream), "download");
}

// What forward() hands out for backward(): the rasteriser keeps the projected Gaussians, tile lists
// and per-pixel state of its latest forward pass on the device; the state names that pass.
struct CudaRenderState final : gs::RenderState {
  const void* owner = nullptr;
  uint64_t generation = 0;
};

class CudaRasteriser final : public gs::Rasteriser {
 public:
  CudaRasteriser() {
    check(cudaStreamCreateWithFlags(&stream_, cudaStreamNonBlocking), "creating a stream");
    for (cudaEvent_t& e : events_) check(cudaEventCreate(&e), "creating events");
  }
  ~CudaRasteriser() override {
    for (cudaEvent_t e : events_) cudaEventDestroy(e);
    if (scan_temp_) cudaFree(scan_temp_);
    if (sort_temp_) cudaFree(sort_temp_);
    if (stream_) cudaStreamDestroy(stream_);
  }

  void forward(const gs::GaussianMap& map, const PinholeCamera& camera, const SE3& T_cw,
               const gs::RenderSettings& settings, gs::RenderOutput* out,
               std::unique_ptr<gs::RenderState>* state) override {
    if (state) state->reset();
    ++generation_;
    const size_t n = map.size();
    const int width = camera.width, height = camera.height;
    const size_t pixels = static_cast<size_t>(width) * height;
    check(cudaEventRecord(events_[0], stream_), "timing");
    detail::DeviceGaussians g;
    g.count = n;
    g.position = upload(&position_, map.positions(), "positions", stream_);
    g.log_scale = upload(&log_scale_, map.log_scales(), "log-scales", stream_);
    g.rotation = upload(&rotation_, map.rotations(), "rotations", stream_);
    g.opacity = upload(&opacity_, map.opacities(), "opacities", stream_);
    g.colour = upload(&colour_, map.colours(), "colours", stream_);
    g.object_id = upload(&object_id_, map.object_ids_per_gaussian(), "object IDs", stream_);
    g.type = upload(&type_, map.types(), "types", stream_);
    const gs::CameraView<float> cam = gs::detail::make_camera_view<float>(camera, T_cw, settings.near);
    gaussians_ = g;

    check(cudaEventRecord(events_[1], stream_), "timing");
    // 1. projection
    detail::DeviceSplat* splats = splats_.ensure(n, "splats");
    detail::TileRect* rects = rects_.ensure(n, "tile rectangles");
    uint32_t* tile_count = tile_count_.ensure(n + 1, "tile counts");
    check(cudaMemsetAsync(tile_count, 0, (n + 1) * sizeof(uint32_t), stream_), "tile counts");
    detail::launch_project(g, cam, settings.ins_object, splats, rects, tile_count, stream_);
    check(cudaGetLastError(), "projection");
    check(cudaEventRecord(events_[2], stream_), "timing");
    // 2. binning: the pair count decides the sort's buffers (the one wait on the host here).
    uint32_t* offsets = offsets_.ensure(n + 1, "offsets");
    detail::exclusive_scan(n, tile_count, offsets, &scan_temp_, &scan_temp_bytes_, stream_);
    uint32_t pairs = 0;
    check(cudaMemcpyAsync(&pairs, offsets + n, sizeof(uint32_t), cudaMemcpyDeviceToHost, stream_), "pair count");
    check(cudaStreamSynchronize(stream_), "pair count");
    const int tiles_x = (width + detail::kTileSize - 1) / detail::kTileSize;
    const int tiles_y = (height + detail::kTileSize - 1) / detail::kTileSize;
    const size_t tiles = static_cast<size_t>(tiles_x) * tiles_y;
    uint64_t* keys = keys_.ensure(pairs, "keys");
    uint32_t* values = values_.ensure(pairs, "values");
    uint64_t* sorted_keys = sorted_keys_.ensure(pairs, "sorted keys");
    uint32_t* sorted_ids = sorted_ids_.ensure(pairs, "sorted IDs");
    detail::launch_emit_keys(n, splats, rects, offsets, tiles_x, keys, values, stream_);
    int tile_bits = 1;
    while ((size_t{1} << tile_bits) < tiles) ++tile_bits;
    detail::sort_pairs(pairs, tile_bits, keys, sorted_keys, values, sorted_ids, &sort_temp_, &sort_temp_bytes_,
                       stream_);
    uint2* ranges = ranges_.ensure(tiles, "tile ranges");
    check(cudaMemsetAsync(ranges, 0, tiles * sizeof(uint2), stream_), "tile ranges");
    detail::launch_tile_ranges(pairs, sorted_keys, ranges, stream_);
    check(cudaGetLastError(), "binning");
    check(cudaEventRecord(events_[3], stream_), "timing");
    // 3. compositing
    detail::ForwardSettings fs;
    fs.surface_depth = settings.surface_depth;
    fs.normalise_depth = settings.normalise_depth;
    fs.gap_abs = settings.surface_gap;
    fs.gap_rel = settings.surface_gap_relative;
    fs.ins_object = settings.ins_object;
    for (int c = 0; c < 3; ++c) fs.background[c] = settings.background[c];
    detail::ForwardImages img;
    img.rgb = rgb_.ensure(3 * pixels, "rgb image");
    img.depth = depth_.ensure(pixels, "depth image");
    img.alpha = alpha_.ensure(pixels, "alpha image");
    img.ins = ins_.ensure(pixels, "ins image");
    img.dominant_id = dominant_.ensure(pixels, "ID image");
    detail::ForwardState kept;
    if (state) {
      kept.t_final = t_final_.ensure(pixels, "transmittance");
      kept.n_contrib = n_contrib_.ensure(pixels, "contributors");
      kept.depth_raw = depth_raw_.ensure(pixels, "raw depth");
      if (settings.surface_depth) kept.surface = surface_.ensure(pixels, "surface");
    }
    detail::launch_forward(width, height, ranges, sorted_ids, splats, fs, img, kept, stream_);
    forward_settings_ = fs;
    forward_state_ = kept;
    n_ = n;
    check(cudaGetLastError(), "compositing");
    check(cudaEventRecord(events_[4], stream_), "timing");
    out->width = width;
    out->height = height;
    download(&out->rgb, img.rgb, 3 * pixels, stream_);
    download(&out->depth, img.depth, pixels, stream_);
    download(&out->alpha, img.alpha, pixels, stream_);
    download(&out->ins, img.ins, pixels, stream_);
    download(&out->dominant_id, img.dominant_id, pixels, stream_);
    check(cudaEventRecord(events_[5], stream_), "timing");
    check(cudaStreamSynchronize(stream_), "compositing");
    float ms[5] = {0, 0, 0, 0, 0};
    for (int k = 0; k < 5; ++k) cudaEventElapsedTime(&ms[k], events_[k], events_[k + 1]);
    timings_ = ForwardTimings{ms[0], ms[1], ms[2], ms[3], ms[4], 0.0, pairs};
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
    const size_t n = n_;
    const int width = camera.width, height = camera.height;
    const size_t pixels = static_cast<size_t>(width) * height;
    auto upload_or_null = [&](DeviceBuffer<float>* b, const std::vector<float>& v, size_t expected) -> const float* {
      if (v.empty()) return nullptr;
      if (v.size() != expected) throw std::invalid_argument("CUDA rasteriser: an output gradient of the wrong size");
      return upload(b, v, "output gradients", stream_);
    };
    detail::ImageGradientsDevice go;
    go.rgb = upload_or_null(&v_rgb_, grad_out.rgb, 3 * pixels);
    go.depth = upload_or_null(&v_depth_, grad_out.depth, pixels);
    go.alpha = upload_or_null(&v_alpha_, grad_out.alpha, pixels);
    go.ins = upload_or_null(&v_ins_, grad_out.ins, pixels);
    detail::Grad2D* grad2d = grad2d_.ensure(n, "2D gradients");
    check(cudaMemsetAsync(grad2d, 0, n * sizeof(detail::Grad2D), stream_), "2D gradients");
    check(cudaEventRecord(events_[0], stream_), "timing");
    detail::launch_backward(width, height, ranges_.get(), sorted_ids_.get(), splats_.get(), forward_settings_,
                            forward_state_, go, grad2d, stream_);
    check(cudaGetLastError(), "backward");
    float* gp = g_position_.ensure(3 * n, "gradients");
    float* gl = g_log_scale_.ensure(3 * n, "gradients");
    float* gr = g_rotation_.ensure(4 * n, "gradients");
    float* gop = g_opacity_.ensure(n, "gradients");
    float* gc = g_colour_.ensure(3 * n, "gradients");
    const std::pair<float*, size_t> blocks[] = {{gp, 3 * n}, {gl, 3 * n}, {gr, 4 * n}, {gop, n}, {gc, 3 * n}};
    for (const auto& [ptr, count] : blocks)
      check(cudaMemsetAsync(ptr, 0, std::max<size_t>(count, 1) * sizeof(float), stream_), "gradients");
    const gs::CameraView<float> cam = gs::detail::make_camera_view<float>(camera, T_cw, settings.near);
    detail::launch_project_vjp(gaussians_, cam, tile_count_.get(), grad2d, gp, gl, gr, gop, gc, stream_);
    check(cudaGetLastError(), "projection backward");
    check(cudaEventRecord(events_[1], stream_), "timing");
    if (grad_map->position.size() != 3 * n) grad_map->resize_for(map);
    // All five down, one wait, then added (MapGradients accumulates).
    std::vector<float> host[5];
    std::vector<float>* dst[5] = {&grad_map->position, &grad_map->log_scale, &grad_map->rotation,
                                  &grad_map->opacity, &grad_map->colour};
    for (int b = 0; b < 5; ++b) download(&host[b], blocks[b].first, blocks[b].second, stream_);
    check(cudaStreamSynchronize(stream_), "gradients");
    for (int b = 0; b < 5; ++b)
      for (size_t k = 0; k < host[b].size(); ++k) (*dst[b])[k] += host[b][k];
    float ms = 0;
    cudaEventElapsedTime(&ms, events_[0], events_[1]);
    timings_.backward_ms = ms;
  }

 private:
  cudaStream_t stream_ = nullptr;
  DeviceBuffer<float> position_, log_scale_, rotation_, opacity_, colour_;
  DeviceBuffer<uint32_t> object_id_;
  DeviceBuffer<uint8_t> type_;
  DeviceBuffer<detail::DeviceSplat> splats_;
  DeviceBuffer<detail::TileRect> rects_;
  DeviceBuffer<uint32_t> tile_count_, offsets_, values_, sorted_ids_;
  DeviceBuffer<uint64_t> keys_, sorted_keys_;
  DeviceBuffer<uint2> ranges_;
  DeviceBuffer<float> rgb_, depth_, alpha_, ins_;
  DeviceBuffer<uint32_t> dominant_;
  void* scan_temp_ = nullptr;
  void* sort_temp_ = nullptr;
  size_t scan_temp_bytes_ = 0, sort_temp_bytes_ = 0;
  cudaEvent_t events_[6] = {};
  ForwardTimings timings_;
  // The latest forward pass, for backward().
  uint64_t generation_ = 0;
  size_t n_ = 0;
  detail::DeviceGaussians gaussians_;  // the map as uploaded by the latest forward()
  detail::ForwardSettings forward_settings_;
  detail::ForwardState forward_state_;
  DeviceBuffer<float> t_final_, depth_raw_;
  DeviceBuffer<uint32_t> n_contrib_;
  DeviceBuffer<gs::SurfaceAccum<float>> surface_;
  DeviceBuffer<float> v_rgb_, v_depth_, v_alpha_, v_ins_;
  DeviceBuffer<detail::Grad2D> grad2d_;
  DeviceBuffer<float> g_position_, g_log_scale_, g_rotation_, g_opacity_, g_colour_;
};

}  // namespace

std::optional<ForwardTimings> last_forward_timings(const gs::Rasteriser& rasteriser) {
  const auto* r = dynamic_cast<const CudaRasteriser*>(&rasteriser);
  if (!r) return std::nullopt;
  return r->timings();
}

std::unique_ptr<gs::Rasteriser> make_cuda_rasteriser() {
  int count = 0;
  const cudaError_t err = cudaGetDeviceCount(&count);
  if (err != cudaSuccess || count == 0) {
    cudaGetLastError();
    throw std::runtime_error(std::string("no CUDA device: ") + (err != cudaSuccess ? cudaGetErrorString(err) : "none found"));
  }
  return std::make_unique<CudaRasteriser>();
}

}  // namespace dqo::cuda
