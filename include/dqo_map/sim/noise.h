#pragma once
// Sensor noise of an RGB-D camera (Kinect-like), applied to a clean rendered frame. Every random
// number is keyed by (seed, frame, pixel), so the result is the same for any thread count.

#include <cstdint>

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

struct DetectionNoiseParams {
  double box_jitter_px = 3.0;         // σ of each box edge
  double miss_rate = 0.10;            // a detectable object is not reported
  double false_positive_rate = 0.05;  // per reported detection, one spurious box of a random class
  double confusion_rate = 0.02;       // a reported object gets another class
  // Only objects seen well enough become detections (noise or not): their visible fraction and the
  // smaller side of their visible box.
  double min_visible_fraction = 0.2;
  double min_box_px = 10.0;
};

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
