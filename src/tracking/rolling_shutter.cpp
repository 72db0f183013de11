#include "rolling_shutter.h"

#include <algorithm>
#include <vector>

#include "dqo_map/geometry/se3.h"

namespace dqo::tracking {

double rolling_shutter_row_offset(double v, int height, double readout_s) {
  return (v - 0.5 * height) / height * readout_s;
}

void compensate_rolling_shutter(const PinholeCamera& camera,
                                const Eigen::Matrix<double, 6, 1>& twist_per_s, double readout_s,
                                OrbFrame* frame) {
  if (readout_s <= 0.0 || frame->keypoints.empty()) return;
  // Keypoints without depth move with a point at the frame's typical depth: the rotation, which
  // does not depend on it, is most of the shift.
  std::vector<float> depths;
  for (const Keypoint& k : frame->keypoints)
    if (k.depth > 0.0f) depths.push_back(k.depth);
  double typical_depth = 1.0;
  if (!depths.empty()) {
    std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
    typical_depth = depths[depths.size() / 2];
  }
  for (Keypoint& k : frame->keypoints) {
    const double dt = rolling_shutter_row_offset(k.uv.y(), camera.height, readout_s);
    const SE3 T_frame_row = SE3::exp(dt * twist_per_s);  // the camera at the row's instant
    const double z = k.depth > 0.0f ? k.depth : typical_depth;
    const Eigen::Vector3d p = T_frame_row * camera.back_project(k.uv.x(), k.uv.y(), z);
    if (p.z() <= 1e-6) continue;
    k.uv = Eigen::Vector2f(static_cast<float>(camera.fx * p.x() / p.z() + camera.cx),
                           static_cast<float>(camera.fy * p.y() / p.z() + camera.cy));
  }
  frame->grid.build(frame->keypoints, camera.width, camera.height, kKeypointGridCellPx);
}

}  // namespace dqo::tracking
