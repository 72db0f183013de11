#include "dqo_map/gaussians/pixel_labels.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace dqo::gs {

LabelImage labels_from_instance(const InstanceImage& instance, const std::vector<uint32_t>& table) {
  LabelImage out(instance.width, instance.height, 1, 0u);
  for (size_t p = 0; p < out.data.size(); ++p) {
    const uint16_t v = instance.data[p * instance.channels];
    out.data[p] = (v != 0 && v < table.size()) ? table[v] : 0u;
  }
  return out;
}

LabelImage labels_from_instance(const InstanceImage& instance) {
  LabelImage out(instance.width, instance.height, 1, 0u);
  for (size_t p = 0; p < out.data.size(); ++p) out.data[p] = instance.data[p * instance.channels];
  return out;
}

LabelImage labels_from_objects(const DepthImage& depth, const PinholeCamera& camera,
                               const SE3& T_wc, const std::vector<LabelledObject>& objects,
                               const ObjectLabelParams& params) {
  const int w = depth.width, h = depth.height;
  LabelImage out(w, h, 1, 0u);
  std::vector<float> best(static_cast<size_t>(w) * h, -std::numeric_limits<float>::infinity());
  for (const LabelledObject& obj : objects) {
    if (obj.object_id == 0 || !obj.box.valid()) continue;
    // The ellipsoid in the camera frame: x_o = Aᵀ (p_c − μ_c) / (s·axes), inside iff ‖x_o‖ ≤ 1.
    const DualQuadric q_c = obj.quadric.transformed(T_wc.inverse());
    const Eigen::Matrix3d Rt = q_c.rotation().transpose();
    const Eigen::Vector3d inv_axes = (params.ellipsoid_scale * q_c.semi_axes()).cwiseInverse();
    const Eigen::Vector3d& mu = q_c.centre();
    // Pixel (u, v) has its centre at integer coordinates: those with centres inside the box.
    const int u0 = std::max(0, static_cast<int>(std::ceil(obj.box.x_min)));
    const int u1 = std::min(w - 1, static_cast<int>(std::floor(obj.box.x_max)));
    const int v0 = std::max(0, static_cast<int>(std::ceil(obj.box.y_min)));
    const int v1 = std::min(h - 1, static_cast<int>(std::floor(obj.box.y_max)));
    for (int v = v0; v <= v1; ++v) {
      for (int u = u0; u <= u1; ++u) {
        const size_t p = static_cast<size_t>(v) * w + u;
        const float d = depth.data[p * depth.channels];
        if (!std::isfinite(d) || d <= 0.f || d < params.min_depth || d > params.max_depth) continue;
        if (obj.score <= best[p]) continue;
        const Eigen::Vector3d p_c = camera.back_project(u, v, d);
        const Eigen::Vector3d x_o = (Rt * (p_c - mu)).cwiseProduct(inv_axes);
        if (x_o.squaredNorm() > 1.0) continue;
        best[p] = obj.score;
        out.data[p] = obj.object_id;
      }
    }
  }
  return out;
}

}  // namespace dqo::gs
