#pragma once
// Sensor noise of an RGB-D camera (Kinect-like), applied to a clean rendered frame. Every random
// number is keyed by (seed, frame, pixel), so the result is the same for any thread count.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "dqo_map/common/dataset.h"

namespace dqo::sim {

struct SensorNoiseParams {
  double depth_sigma = 0.0015;  // σ = depth_sigma · z², z in metres (1.5 mm·z²: 6 mm at 2 m)
  double max_depth = 5.0;       // metres; beyond it the sensor returns nothing (0)
  // Edge holes: a pixel whose neighbour (8-neighbourhood) is nearer by more than
  // max(edge_jump, edge_jump_relative · z) lies in the shadow of a depth edge and becomes a hole
  // with this probability, as a structured-light or time-of-flight sensor loses it.
  double edge_jump = 0.05;
  double edge_jump_relative = 0.03;
  double edge_hole_probability = 0.8;
  double rgb_sigma = 2.0;  // 8-bit units, per channel
};

// How the simulated detector behaves, as a whole: `kKind` is a gentle detector (the defaults
// below), `kReal` one like a COCO detector on real frames (recall 40 %, labels flipped among
// look-alike classes, clutter boxed again and again at the same places).
enum class DetectorProfile { kKind, kReal };

struct DetectionNoiseParams {
  DetectorProfile profile = DetectorProfile::kKind;  // what the rates below came from
  double box_jitter_px = 3.0;  // σ of each box edge
  double miss_rate = 0.10;     // a detectable object is not reported
  // Per detectable object (reported or missed), one spurious box with this probability: the
  // expected number of false positives is false_positive_rate times the detectable objects.
  double false_positive_rate = 0.05;
  double confusion_rate = 0.02;  // a reported object gets another class
  // Confused classes stay within the object's group of confusion_groups (a class in no group:
  // any other class). False: any other class, groups or not (the kind detector).
  bool confusion_within_groups = false;
  // Look-alike classes (class IDs; each class in one group at most, two or more per group).
  std::vector<std::vector<int>> confusion_groups;
  // The share of false positives that fall on fixed clutter spots of the scene (surfaces of the
  // room and furniture, placed from the seed) visible in the frame, as a real detector boxes the
  // same cable as "scissors" frame after frame; the rest are random boxes. A frame in which no
  // spot is visible (or all have been used) gets random boxes instead.
  double false_positive_recurring = 0.0;
  int clutter_spots = 6;  // how many such spots the scene has (used when recurring > 0)
  // Only objects seen well enough become detections (noise or not): their visible fraction and the
  // smaller side of their visible box.
  double min_visible_fraction = 0.2;
  double min_box_px = 10.0;
};

// Sets the rates of `profile` (jitter, misses, false positives, confusions, groups on or off,
// recurring clutter) and params->profile; keeps the visibility thresholds and the groups.
void set_detector_profile(DetectorProfile profile, DetectionNoiseParams* params);
const char* detector_profile_name(DetectorProfile profile);  // "kind", "real"
// nullopt for a name that is not a profile.
std::optional<DetectorProfile> detector_profile_from_name(const std::string& name);
constexpr char kDetectorProfileNames[] = "kind, real";

struct NoiseParams {
  bool enabled = true;  // false: clean images and exact detections (the `tiny` scene)
  SensorNoiseParams sensor;
  DetectionNoiseParams detection;
};

// Always applies (the caller checks NoiseParams::enabled). In place on frame->depth and frame->rgb
// (instance, boxes and pose are ground truth and stay untouched). `threads` splits the rows; the
// result does not depend on it.
void apply_sensor_noise(const SensorNoiseParams& params, uint64_t seed, int threads, Frame* frame);

}  // namespace dqo::sim
