#include "dqo_map/gaussians/render_metrics.h"

#include <cmath>
#include <limits>

namespace dqo::gs {
namespace {

template <typename T>
double id_agreement_impl(const RenderOutput& out, const Image<T>& labels) {
  size_t total = 0, agree = 0;
  for (size_t p = 0; p < out.dominant_id.size(); ++p) {
    const uint32_t id = labels.data[p * labels.channels];
    if (id == 0) continue;
    ++total;
    agree += out.dominant_id[p] == id ? 1 : 0;
  }
  return total ? static_cast<double>(agree) / total : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace

double psnr(const RenderOutput& out, const ImageRgb8& target, const std::vector<uint8_t>& mask) {
  const size_t n = static_cast<size_t>(out.width) * out.height;
  double se = 0.0;
  size_t count = 0;
  for (size_t p = 0; p < n; ++p) {
    if (!mask.empty() && !mask[p]) continue;
    for (int c = 0; c < 3; ++c) {
      const double d = out.rgb[3 * p + c] - target.data[3 * p + c] / 255.0;
      se += d * d;
    }
    count += 3;
  }
  if (count == 0) return std::numeric_limits<double>::quiet_NaN();
  const double mse = se / count;
  return mse > 0.0 ? 10.0 * std::log10(1.0 / mse) : std::numeric_limits<double>::infinity();
}

double depth_l1(const RenderOutput& out, const DepthImage& target,
                const std::vector<uint8_t>& mask) {
  const size_t n = static_cast<size_t>(out.width) * out.height;
  double sum = 0.0;
  size_t count = 0;
  for (size_t p = 0; p < n; ++p) {
    const float d = target.data[p];
    if (!std::isfinite(d) || d <= 0.f || (!mask.empty() && !mask[p])) continue;
    sum += std::abs(static_cast<double>(out.depth[p]) - d);
    ++count;
  }
  return count ? sum / count : std::numeric_limits<double>::quiet_NaN();
}

double id_agreement(const RenderOutput& out, const Image<uint32_t>& labels) {
  return id_agreement_impl(out, labels);
}
double id_agreement(const RenderOutput& out, const InstanceImage& instance) {
  return id_agreement_impl(out, instance);
}

}  // namespace dqo::gs
