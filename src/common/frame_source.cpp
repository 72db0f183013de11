#include "dqo_map/common/frame_source.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>

namespace dqo {
namespace {

// Source pixel coordinate of a target pixel coordinate, per axis (pixel centres at integers).
double to_source(double x, double s) { return (x + 0.5) / s - 0.5; }

Box2d scale_box(const Box2d& b, double sx, double sy) {
  // Boxes are in continuous coordinates with pixel centres at integers: edges at u ± ½.
  Box2d out = b;
  out.x_min = (b.x_min + 0.5) * sx - 0.5;
  out.x_max = (b.x_max + 0.5) * sx - 0.5;
  out.y_min = (b.y_min + 0.5) * sy - 0.5;
  out.y_max = (b.y_max + 0.5) * sy - 0.5;
  return out;
}

template <typename T>
Image<T> nearest(const Image<T>& in, int w, int h) {
  if (in.empty()) return {};
  Image<T> out(w, h, in.channels);
  const double sx = static_cast<double>(w) / in.width, sy = static_cast<double>(h) / in.height;
  for (int v = 0; v < h; ++v) {
    const int y = std::clamp(static_cast<int>(std::lround(to_source(v, sy))), 0, in.height - 1);
    for (int u = 0; u < w; ++u) {
      const int x = std::clamp(static_cast<int>(std::lround(to_source(u, sx))), 0, in.width - 1);
      for (int c = 0; c < in.channels; ++c) out.at(u, v, c) = in.at(x, y, c);
    }
  }
  return out;
}

// Area average: each target pixel is the mean of the source pixels whose centres fall in its
// footprint (at least the nearest one, for upscaling).
ImageRgb8 area_average(const ImageRgb8& in, int w, int h) {
  if (in.empty()) return {};
  ImageRgb8 out(w, h, in.channels);
  const double fx = static_cast<double>(in.width) / w, fy = static_cast<double>(in.height) / h;
  for (int v = 0; v < h; ++v) {
    int y0 = static_cast<int>(std::ceil(v * fy - 0.5)), y1 = static_cast<int>(std::ceil((v + 1) * fy - 0.5));
    y0 = std::clamp(y0, 0, in.height - 1);
    y1 = std::clamp(std::max(y1, y0 + 1), 1, in.height);
    for (int u = 0; u < w; ++u) {
      int x0 = static_cast<int>(std::ceil(u * fx - 0.5)), x1 = static_cast<int>(std::ceil((u + 1) * fx - 0.5));
      x0 = std::clamp(x0, 0, in.width - 1);
      x1 = std::clamp(std::max(x1, x0 + 1), 1, in.width);
      for (int c = 0; c < in.channels; ++c) {
        double sum = 0.0;
        for (int y = y0; y < y1; ++y) {
          for (int x = x0; x < x1; ++x) sum += in.at(x, y, c);
        }
        out.at(u, v, c) = static_cast<uint8_t>(std::lround(sum / ((y1 - y0) * (x1 - x0))));
      }
    }
  }
  return out;
}

}  // namespace

PinholeCamera scale_camera(const PinholeCamera& c, double s) {
  PinholeCamera out = c;
  out.width = std::max(1, static_cast<int>(std::lround(c.width * s)));
  out.height = std::max(1, static_cast<int>(std::lround(c.height * s)));
  // The exact ratios of the rounded size, so that the image edges stay where they were.
  const double sx = static_cast<double>(out.width) / c.width;
  const double sy = static_cast<double>(out.height) / c.height;
  out.fx = c.fx * sx;
  out.fy = c.fy * sy;
  out.cx = (c.cx + 0.5) * sx - 0.5;
  out.cy = (c.cy + 0.5) * sy - 0.5;
  return out;
}

Frame scale_frame(const Frame& frame, const PinholeCamera& from, const PinholeCamera& to) {
  Frame out;
  out.index = frame.index;
  out.timestamp = frame.timestamp;
  out.T_wc = frame.T_wc;
  out.has_pose = frame.has_pose;
  out.rgb = area_average(frame.rgb, to.width, to.height);
  out.depth = nearest(frame.depth, to.width, to.height);
  out.instance = nearest(frame.instance, to.width, to.height);
  const double sx = static_cast<double>(to.width) / from.width;
  const double sy = static_cast<double>(to.height) / from.height;
  out.objects = frame.objects;
  for (FrameObject& o : out.objects) o.box = scale_box(o.box, sx, sy);
  out.detections = frame.detections;
  for (Detection2d& d : out.detections) d.box = scale_box(d.box, sx, sy);
  return out;
}

ScaledFrameSource::ScaledFrameSource(std::shared_ptr<const FrameSource> source, double s)
    : source_(std::move(source)), info_(source_->info()) {
  info_.camera = scale_camera(source_->info().camera, s);
}

std::optional<Frame> ScaledFrameSource::read_frame(int i, std::string* error) const {
  std::optional<Frame> f = source_->read_frame(i, error);
  if (!f) return f;
  return scale_frame(*f, source_->info().camera, info_.camera);
}

PreloadedFrameSource::PreloadedFrameSource(std::shared_ptr<const FrameSource> source, const std::vector<int>& indices,
                                           int threads)
    : source_(std::move(source)) {
  const int n = static_cast<int>(indices.size());
  const int workers = std::max(1, std::min(threads > 0 ? threads : static_cast<int>(std::thread::hardware_concurrency()), n));
  std::vector<std::optional<Frame>> read(indices.size());
  std::vector<std::string> errors(indices.size());
  std::atomic<int> next{0};
  std::vector<std::thread> pool;
  for (int w = 0; w < workers; ++w) {
    pool.emplace_back([&] {
      for (int k = next++; k < n; k = next++) read[k] = source_->read_frame(indices[k], &errors[k]);
    });
  }
  for (std::thread& t : pool) t.join();
  for (int k = 0; k < n; ++k) {
    if (!read[k]) throw std::runtime_error("frame " + std::to_string(indices[k]) + ": " + errors[k]);
    frames_.emplace(indices[k], std::move(*read[k]));
  }
}

std::optional<Frame> PreloadedFrameSource::read_frame(int i, std::string* error) const {
  const auto it = frames_.find(i);
  if (it != frames_.end()) return it->second;
  return source_->read_frame(i, error);
}

size_t PreloadedFrameSource::bytes() const {
  size_t total = 0;
  for (const auto& [i, f] : frames_)
    total += f.rgb.data.size() + f.depth.data.size() * sizeof(float) + f.instance.data.size() * sizeof(f.instance.data[0]);
  return total;
}

}  // namespace dqo
