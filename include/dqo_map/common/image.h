#pragma once
// A plain interleaved image buffer: the core's image type where OpenCV is not allowed (sim/,
// gaussians/, cuda/). io/ converts to and from cv::Mat at its boundary.

#include <cstddef>
#include <cstdint>
#include <vector>

namespace dqo {

template <typename T>
struct Image {
  int width = 0;
  int height = 0;
  int channels = 1;
  std::vector<T> data;  // row-major, channels interleaved: data[(y * width + x) * channels + c]

  Image() = default;
  Image(int w, int h, int c, T fill = T{})
      : width(w), height(h), channels(c), data(static_cast<size_t>(w) * h * c, fill) {}

  bool empty() const { return data.empty(); }
  size_t index(int x, int y, int c = 0) const {
    return (static_cast<size_t>(y) * width + x) * channels + c;
  }
  T& at(int x, int y, int c = 0) { return data[index(x, y, c)]; }
  const T& at(int x, int y, int c = 0) const { return data[index(x, y, c)]; }
  bool same_size(int w, int h) const { return width == w && height == h; }
};

using ImageRgb8 = Image<uint8_t>;       // 3 channels, R G B
using DepthImage = Image<float>;        // metres; 0 or NaN = no measurement
using InstanceImage = Image<uint16_t>;  // object IDs (ground truth) or detection index + 1; 0 = none
using LabelImage = Image<uint32_t>;     // one channel: instance labels of a mask, 0 = none

}  // namespace dqo
