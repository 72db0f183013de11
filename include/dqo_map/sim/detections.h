#pragma once
// Detections simulated from a frame's ground truth (the visible boxes), with detector-like noise.

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "dqo_map/common/dataset.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/sim/noise.h"

namespace dqo::sim {

// A place in the scene where a detector keeps seeing an object that is not there (a cable, a
// pattern on the wall): a rectangle of the given size facing the camera, centred on p_w.
struct ClutterSpot {
  Eigen::Vector3d p_w = Eigen::Vector3d::Zero();  // on a surface of the room or the furniture
  double width = 0.1, height = 0.1;               // metres
  int class_id = 0;                               // what the detector calls it, every time
};

struct DetectionContext {
  int width = 0;  // image size, to clip boxes
  int height = 0;
  std::map<uint32_t, int> class_of_object;  // ground-truth object ID -> class ID
  std::map<int, std::string> class_names;   // the scene's classes (confusions and false positives
                                            // draw from it)
  // Recurring false positives: the spots, and the camera that projects them (the frame's T_wc,
  // depth and instance image decide which are in view and not hidden).
  std::vector<ClutterSpot> clutter;
  PinholeCamera camera;
};

// One detection per ground-truth object in frame.objects that passes the visibility thresholds
// (a "detectable" object), in ascending ID order, with gt_id set. With `noise`: each detectable
// object is missed with miss_rate, otherwise its class is confused with confusion_rate (to another
// class of its confusion group where confusion_within_groups says so, else to any other class),
// each box edge jittered by box_jitter_px (then clipped to the image) and a score drawn in
// [0.5, 1]; and, missed or not, it brings a false positive (gt_id 0, score in [0.3, 0.8]) with
// false_positive_rate: with false_positive_recurring, the box of a clutter spot in view (its own
// class, edges jittered), otherwise a random box of a random class. Without: the exact visible
// boxes with score 1. Deterministic in (seed, frame.index); the kind profile's detections are
// those of the detector before profiles existed, draw for draw.
std::vector<Detection2d> simulate_detections(const Frame& frame, const DetectionContext& context,
                                             const DetectionNoiseParams& params, bool noise,
                                             uint64_t seed);

}  // namespace dqo::sim
