#pragma once
// Chooses the keyframes handed to mapping (denser than the tracker's own): one whenever the camera
// has turned more than max_rotation_deg or moved more than max_translation_m since the last one,
// or max_frames frames have passed. The first tracked frame is always one. Used both behind the
// tracker and with `pose_source: tf`, where poses come from another SLAM.

#include <cstdint>

#include "dqo_map/geometry/se3.h"

namespace dqo {

struct KeyframeSelectorParams {
  double max_rotation_deg = 10.0;
  double max_translation_m = 0.1;
  int max_frames = 30;  // <= 0: no frame-count trigger
};

class KeyframeSelector {
 public:
  explicit KeyframeSelector(const KeyframeSelectorParams& params) : params_(params) {}

  // True when the frame at T_wc becomes a keyframe (the selector then measures from it).
  bool consider(const SE3& T_wc);

  // Forget the last keyframe (after a tracking reset): the next frame is a keyframe.
  void reset() { has_last_ = false; }

  uint64_t frames_since_last() const { return frames_since_; }

 private:
  KeyframeSelectorParams params_;
  bool has_last_ = false;
  SE3 last_T_wc_;
  uint64_t frames_since_ = 0;
};

}  // namespace dqo
