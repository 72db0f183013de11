// The rasteriser's device pipeline (raster_pipeline.h): the three forward stages and the backward
// pass sequenced on one stream over device-resident Gaussians.

#include "raster_pipeline.h"

#include <algorithm>
#include <stdexcept>
#include <string>
#include <utility>

namespace dqo::cuda::detail {

RasterPipeline::RasterPipeline() {
  check(cudaStreamCreateWithFlags(&stream_, cudaStreamNonBlocking), "creating a stream");
  for (cudaEvent_t& e : events_) check(cudaEventCreate(&e), "creating events");
}

RasterPipeline::~RasterPipeline() {
  for (cudaEvent_t e : events_) cudaEventDestroy(e);
  if (scan_temp_) cudaFree(scan_temp_);
  if (sort_temp_) cudaFree(sort_temp_);
  if (stream_) cudaStreamDestroy(stream_);
}

float RasterPipeline::ms_between(int a, int b) const {
  float ms = 0.f;
  if (cudaEventElapsedTime(&ms, events_[a], events_[b]) != cudaSuccess) {
    cudaGetLastError();  // an event not recorded yet: no time
    return 0.f;
  }
  return ms;
}

size_t RasterPipeline::bytes() const {
  return splats_.bytes() + rects_.bytes() + tile_count_.bytes() + offsets_.bytes() + values_.bytes() +
         sorted_ids_.bytes() + keys_.bytes() + sorted_keys_.bytes() + ranges_.bytes() + tile_order_.bytes() +
         tile_work_.bytes() + tile_ids_.bytes() + sorted_tile_work_.bytes() + rgb_.bytes() + depth_.bytes() +
         alpha_.bytes() + ins_.bytes() + dominant_.bytes() + labels_.bytes() + t_final_.bytes() + depth_raw_.bytes() +
         n_contrib_.bytes() + surface_.bytes() + grad2d_.bytes() + scan_temp_bytes_ + sort_temp_bytes_;
}

void RasterPipeline::forward(const DeviceGaussians& g, const gs::CameraView<float>& cam,
                             const gs::RenderSettings& settings, bool keep_state) {
  const size_t n = g.count;
  const int width = cam.K.width, height = cam.K.height;
  // The splats' α boxes hold pixel coordinates in 16 bits (DeviceSplat::box).
  if (width > kMaxImageSide || height > kMaxImageSide)
    throw std::invalid_argument("CUDA rasteriser: images of at most " + std::to_string(kMaxImageSide) +
                                " pixels on a side");
  const size_t pixels = static_cast<size_t>(width) * height;
  n_ = n;
  width_ = width;
  height_ = height;
  mark(1);
  // 1. projection
  DeviceSplat* splats = splats_.ensure(n, "splats");
  TileRect* rects = rects_.ensure(n, "tile rectangles");
  uint32_t* tile_count = tile_count_.ensure(n + 1, "tile counts");
  // The projection writes every Gaussian's count; the scan's extra last entry is zero.
  check(cudaMemsetAsync(tile_count + n, 0, sizeof(uint32_t), stream_), "tile counts");
  // For a backward pass: the 2D gradients' sums start at zero for the Gaussians it will reach (the
  // binned ones), zeroed by the projection rather than all of them by a memset.
  Grad2D* grad2d = keep_state ? grad2d_.ensure(n, "2D gradients") : nullptr;
  grad2d_zeroed_ = keep_state;
  launch_project(g, cam, settings.ins_object, settings.ins_labels != nullptr, splats, rects, tile_count, grad2d,
                 stream_);
  check(cudaGetLastError(), "projection");
  mark(2);
  if (clock_) clock_->end(Stage::kProject, stream_);
  // 2. binning: the pair count decides the sort's buffers (the one wait on the host here).
  uint32_t* offsets = offsets_.ensure(n + 1, "offsets");
  check(exclusive_scan(n, tile_count, offsets, &scan_temp_, &scan_temp_bytes_, stream_), "scan");
  uint32_t pairs = 0;
  check(cudaMemcpyAsync(&pairs, offsets + n, sizeof(uint32_t), cudaMemcpyDeviceToHost, stream_), "pair count");
  check(cudaStreamSynchronize(stream_), "pair count");
  pairs_ = pairs;
  const int tiles_x = (width + kTileSize - 1) / kTileSize;
  const int tiles_y = (height + kTileSize - 1) / kTileSize;
  const size_t tiles = static_cast<size_t>(tiles_x) * tiles_y;
  uint64_t* keys = keys_.ensure(pairs, "keys");
  uint32_t* values = values_.ensure(pairs, "values");
  uint64_t* sorted_keys = sorted_keys_.ensure(pairs, "sorted keys");
  uint32_t* sorted_ids = sorted_ids_.ensure(pairs, "sorted IDs");
  const DepthKey dk = depth_key_for(cam.near);
  launch_emit_keys(n, splats, rects, offsets, width, height, dk, keys, values, stream_);
  int tile_bits = 1;
  while ((size_t{1} << tile_bits) < tiles) ++tile_bits;
  check(sort_pairs(pairs, dk.bits + tile_bits, keys, sorted_keys, values, sorted_ids, &sort_temp_, &sort_temp_bytes_,
                   stream_),
        "sort");
  uint2* ranges = ranges_.ensure(tiles, "tile ranges");
  check(cudaMemsetAsync(ranges, 0, tiles * sizeof(uint2), stream_), "tile ranges");
  launch_tile_ranges(pairs, sorted_keys, dk.bits, ranges, stream_);
  uint32_t* tile_order = tile_order_.ensure(tiles, "tile order");
  check(order_tiles(tiles, ranges, tile_work_.ensure(tiles, "tile work"), tile_ids_.ensure(tiles, "tile work"),
                    sorted_tile_work_.ensure(tiles, "tile work"), tile_order, &sort_temp_, &sort_temp_bytes_,
                    stream_),
        "tile order");
  check(cudaGetLastError(), "binning");
  mark(3);
  if (clock_) clock_->end(Stage::kBin, stream_);
  // 3. compositing
  ForwardSettings fs;
  fs.surface_depth = settings.surface_depth;
  fs.normalise_depth = settings.normalise_depth;
  fs.gap_abs = settings.surface_gap;
  fs.gap_rel = settings.surface_gap_relative;
  fs.ins_object = settings.ins_object;
  if (settings.ins_labels) {
    uint32_t* labels = labels_.ensure(pixels, "label image");
    check(cudaMemcpyAsync(labels, settings.ins_labels, pixels * sizeof(uint32_t), cudaMemcpyHostToDevice, stream_),
          "label image");
    fs.ins_labels = labels;
  }
  for (int c = 0; c < 3; ++c) fs.background[c] = settings.background[c];
  images_.rgb = rgb_.ensure(3 * pixels, "rgb image");
  images_.depth = depth_.ensure(pixels, "depth image");
  images_.alpha = alpha_.ensure(pixels, "alpha image");
  images_.ins = ins_.ensure(pixels, "ins image");
  images_.dominant_id = dominant_.ensure(pixels, "ID image");
  ForwardState kept;
  if (keep_state) {
    kept.t_final = t_final_.ensure(pixels, "transmittance");
    kept.n_contrib = n_contrib_.ensure(pixels, "contributors");
    kept.depth_raw = depth_raw_.ensure(pixels, "raw depth");
    if (settings.surface_depth) kept.surface = surface_.ensure(pixels, "surface");
  }
  walk_ = walk_for(pairs, tiles);
  launch_forward(width, height, tile_order, ranges, sorted_ids, splats, fs, images_, kept, walk_, stream_);
  settings_ = fs;
  state_ = kept;
  check(cudaGetLastError(), "compositing");
  mark(4);
  if (clock_) clock_->end(Stage::kComposite, stream_);
}

void RasterPipeline::backward(const DeviceGaussians& g, const gs::CameraView<float>& cam,
                              const ImageGradientsDevice& grad_out, const DeviceAttributeGradients& out,
                              bool zero_culled) {
  if (!state_.t_final || g.count != n_ || cam.K.width != width_ || cam.K.height != height_) {
    throw std::invalid_argument(
        "CUDA rasteriser: backward() needs a forward pass that kept its state, on the same Gaussians and camera");
  }
  backward_2d(grad_out);
  launch_project_vjp(g, cam, tile_count_.get(), grad2d_.get(), out.position, out.log_scale, out.rotation, out.opacity,
                     out.colour, zero_culled, stream_);
  check(cudaGetLastError(), "projection backward");
  mark(7);
  if (clock_) clock_->end(Stage::kBackward, stream_);
}

void RasterPipeline::backward_2d(const ImageGradientsDevice& grad_out) {
  if (!state_.t_final)
    throw std::invalid_argument("CUDA rasteriser: backward() needs a forward pass that kept its state");
  const size_t n = n_;
  Grad2D* grad2d = grad2d_.get();  // zeroed for the binned Gaussians by the forward pass ...
  if (!grad2d_zeroed_)              // ... unless a backward pass of the same forward one ran before
    check(cudaMemsetAsync(grad2d, 0, n * sizeof(Grad2D), stream_), "2D gradients");
  grad2d_zeroed_ = false;
  mark(6);
  launch_backward(width_, height_, tile_order_.get(), ranges_.get(), sorted_ids_.get(), splats_.get(), settings_,
                  state_, grad_out, grad2d, walk_, stream_);
  check(cudaGetLastError(), "backward");
}

}  // namespace dqo::cuda::detail
