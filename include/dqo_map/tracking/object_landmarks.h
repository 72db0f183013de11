#pragma once
// Objects as landmarks of the tracker (issue 25, item 1): what the object stage hands back to
// tracking. The object stage owns the objects; the tracker only reads them, and local bundle
// adjustment gains a robust cost between a keyframe's pose and the objects it sees (the detection
// box against the box of the object's projected conic, QuadricSLAM's bounding-box cost).
//
// Which version of an object a keyframe uses: the tracker keeps the latest set it was given
// (set_object_landmarks replaces it whole) and every adjustment reads that set when its snapshot is
// taken, so a sighting is always costed against the newest ellipsoid of its object; a sighting whose
// object is no longer in the set (removed, merged into another ID, or not confirmed) is ignored.
//
// No Ceres or ROS here: this header is part of the tracker's public API.

#include <cstdint>
#include <vector>

#include "dqo_map/geometry/box2d.h"
#include "dqo_map/geometry/dual_quadric.h"

namespace dqo::tracking {

// One object of the object stage, in the tracker's world frame.
struct ObjectLandmark {
  uint64_t id = 0;          // the object stage's ID (never reused)
  DualQuadric quadric;      // world frame of the tracker
  bool confirmed = false;   // only confirmed objects anchor poses
  // In [0, 1]: how far the object stage believes it (its class vote's share, or its existence
  // probability); scales the cost's information. Below ObjectLandmarkParams::min_confidence: unused.
  double confidence = 0.0;
  int observations = 0;     // detections behind the ellipsoid (fewer than min_observations: unused)
};

// One detection of a registered frame (Tracker::register_frame) associated with an object.
struct ObjectSighting {
  uint64_t object_id = 0;
  Box2d box;                // rectified image, pixels
  double score = 1.0;       // the detector's score (not used as a weight: the object's confidence is)
};

}  // namespace dqo::tracking
