#pragma once
// The rasteriser's device pipeline (host side, plain C++ with the CUDA runtime): projection,
// binning and compositing of Gaussians already on the device into images that stay on the device,
// and the backward pass of the latest forward one into attribute gradients on the device. Shared
// by the CUDA rasteriser (which uploads a host map and downloads the images) and the CUDA training
// engine (whose map and images never leave the device). One stream; device buffers only grow.

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

#include "../common/device_buffer.h"
#include "../common/stage_clock.h"
#include "dqo_map/gaussians/rasteriser.h"
#include "raster_cuda.h"

namespace dqo::cuda::detail {

// dL/d(attributes) on the device, laid out as the map's arrays.
struct DeviceAttributeGradients {
  float* position = nullptr;   // [N*3]
  float* log_scale = nullptr;  // [N*3]
  float* rotation = nullptr;   // [N*4]
  float* opacity = nullptr;    // [N]
  float* colour = nullptr;     // [N*3]
};

// The device arrays behind a DeviceAttributeGradients, grown to n Gaussians by get().
struct GradientBuffers {
  DeviceBuffer<float> position, log_scale, rotation, opacity, colour;
  DeviceAttributeGradients get(size_t n) {
    return {position.ensure(3 * n, "gradients"), log_scale.ensure(3 * n, "gradients"),
            rotation.ensure(4 * n, "gradients"), opacity.ensure(n, "gradients"), colour.ensure(3 * n, "gradients")};
  }
  size_t bytes() const {
    return position.bytes() + log_scale.bytes() + rotation.bytes() + opacity.bytes() + colour.bytes();
  }
};

class RasterPipeline {
 public:
  RasterPipeline();
  ~RasterPipeline();
  RasterPipeline(const RasterPipeline&) = delete;
  RasterPipeline& operator=(const RasterPipeline&) = delete;

  cudaStream_t stream() const { return stream_; }

  // Renders `g` from `cam` into images(); keep_state: keeps what backward() needs. Waits for the
  // (Gaussian, tile) pair count once, to size the sort.
  void forward(const DeviceGaussians& g, const gs::CameraView<float>& cam, const gs::RenderSettings& settings,
               bool keep_state);
  const ForwardImages& images() const { return images_; }
  size_t pairs() const { return pairs_; }

  // Gradients of the latest forward pass (made with keep_state, on the same `g` and camera) into
  // `out` (sized for g.count; overwritten: no memset). Null output gradients count as zero. The
  // Gaussians the pass culled (tile_counts() 0) get zeros only with zero_culled; without, their
  // entries are left as they were (a training step skips them by tile_counts(): 52 bytes per
  // culled Gaussian not written per iteration).
  void backward(const DeviceGaussians& g, const gs::CameraView<float>& cam, const ImageGradientsDevice& grad_out,
                const DeviceAttributeGradients& out, bool zero_culled = true);
  // The first half of backward(): the latest forward pass's gradients of each Gaussian's screen-space
  // quantities, summed over pixels into grad2d() (valid where tile_counts() > 0), and no more.
  void backward_2d(const ImageGradientsDevice& grad_out);
  const Grad2D* grad2d() const { return grad2d_.get(); }
  // Per Gaussian, the tiles the latest forward pass binned it into (0: culled).
  const uint32_t* tile_counts() const { return tile_count_.get(); }

  // GPU milliseconds of the latest forward pass's stages and of the latest backward pass.
  float project_ms() const { return ms_between(1, 2); }
  float bin_ms() const { return ms_between(2, 3); }
  float composite_ms() const { return ms_between(3, 4); }
  float backward_ms() const { return ms_between(6, 7); }
  // Events for the caller's own steps around the pipeline (0: before its upload, 5: after its
  // download; 1-4 and 6-7 are the pipeline's).
  void mark(int k) { check(cudaEventRecord(events_[k], stream_), "timing"); }
  float ms_between(int a, int b) const;
  // A clock that gets the end of each stage (project, bin, composite, backward); null: none.
  void set_clock(StageClock* clock) { clock_ = clock; }
  // Device bytes its buffers hold (per Gaussian, per pair, per pixel, the sort's scratch).
  size_t bytes() const;

 private:
  cudaStream_t stream_ = nullptr;
  cudaEvent_t events_[8] = {};
  StageClock* clock_ = nullptr;
  size_t n_ = 0, pairs_ = 0;
  WalkOrder walk_ = WalkOrder::kStaged;  // the latest forward's, which its backward follows
  int width_ = 0, height_ = 0;
  ForwardSettings settings_;
  ForwardState state_;
  ForwardImages images_;
  DeviceBuffer<DeviceSplat> splats_;
  DeviceBuffer<TileRect> rects_;
  DeviceBuffer<uint32_t> tile_count_, offsets_, values_, sorted_ids_;
  DeviceBuffer<uint64_t> keys_, sorted_keys_;
  DeviceBuffer<uint2> ranges_;
  DeviceBuffer<uint32_t> tile_order_, tile_work_, tile_ids_, sorted_tile_work_;
  DeviceBuffer<float> rgb_, depth_, alpha_, ins_;
  DeviceBuffer<uint32_t> dominant_, labels_;
  DeviceBuffer<float> t_final_, depth_raw_;
  DeviceBuffer<uint32_t> n_contrib_;
  DeviceBuffer<gs::SurfaceAccum<float>> surface_;
  DeviceBuffer<Grad2D> grad2d_;
  bool grad2d_zeroed_ = false;  // by the latest forward pass, and no backward one since
  void* scan_temp_ = nullptr;
  void* sort_temp_ = nullptr;
  size_t scan_temp_bytes_ = 0, sort_temp_bytes_ = 0;
};

}  // namespace dqo::cuda::detail
