#pragma once
// Poses of another world frame (a tracker's: its first camera at the origin) moved rigidly onto the
// ground truth, so that objects and meshes compare with it while the drift still counts in full.
// Private to system/: the object pipeline and the offline stages share it.

#include <optional>

#include "dqo_map/common/dataset.h"
#include "dqo_map/geometry/se3.h"

namespace dqo::system {

class TrajectoryAnchor {
 public:
  explicit TrajectoryAnchor(bool enabled) : enabled_(enabled) {}

  // The pose in the ground truth's frame. The anchor is fixed at the first frame that has both a
  // pose and ground truth; poses before it mean nothing in the ground truth's frame (nullopt).
  // Disabled: the pose as it is.
  std::optional<SE3> apply(const Frame& frame, const std::optional<SE3>& T_wc) {
    if (!enabled_ || !T_wc) return T_wc;
    if (!anchored_ && frame.has_pose) {
      T_gt_est_ = frame.T_wc * T_wc->inverse();
      anchored_ = true;
    }
    if (!anchored_) return std::nullopt;
    return T_gt_est_ * *T_wc;
  }
  // A pose corrected later (bundle adjustment), with the anchor already fixed.
  SE3 apply(const SE3& T_wc) const { return enabled_ && anchored_ ? T_gt_est_ * T_wc : T_wc; }
  bool anchored() const { return anchored_; }
  // The estimate's world in the ground truth's (identity when disabled or not yet anchored): maps
  // what was built on anchored poses (objects) back into the estimate's world.
  SE3 T_gt_est() const { return enabled_ && anchored_ ? T_gt_est_ : SE3(); }

 private:
  bool enabled_;
  bool anchored_ = false;
  SE3 T_gt_est_;  // estimate's world -> ground truth's world
};

}  // namespace dqo::system
