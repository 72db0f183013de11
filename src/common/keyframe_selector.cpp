#include "dqo_map/common/keyframe_selector.h"

#include <cmath>

namespace dqo {

bool KeyframeSelector::consider(const SE3& T_wc) {
  ++frames_since_;
  bool take = !has_last_;
  if (!take) {
    const SE3 delta = last_T_wc_.inverse() * T_wc;
    // The angle of the relative rotation: 2 acos(|w|), robust to the quaternion's sign.
    const double w = std::min(1.0, std::abs(delta.quaternion().w()));
    const double angle_deg = 2.0 * std::acos(w) * 180.0 / M_PI;
    take = angle_deg > params_.max_rotation_deg ||
           delta.translation().norm() > params_.max_translation_m ||
           (params_.max_frames > 0 && frames_since_ >= static_cast<uint64_t>(params_.max_frames));
  }
  if (take) {
    has_last_ = true;
    last_T_wc_ = T_wc;
    frames_since_ = 0;
  }
  return take;
}

}  // namespace dqo
