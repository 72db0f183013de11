#pragma once
// The value types of the mapping stage (DESIGN.md "mapping nodelet"): what it is told about the
// objects (mirroring the Object, ObjectEvent and KeyFrameObjects messages) and what it stores of the
// keyframes. Plain C++ + Eigen: the mapping stage builds where only CMake, a compiler, Eigen,
// GoogleTest and yaml-cpp exist (the GPU machine), so it does not depend on objects/ (Ceres).

#include <cstdint>
#include <string>
#include <vector>

#include "dqo_map/common/dataset.h"
#include "dqo_map/common/image.h"
#include "dqo_map/geometry/dual_quadric.h"
#include "dqo_map/geometry/oriented_box.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"

namespace dqo::mapping {

using ObjectId = uint64_t;    // as objects::ObjectId; 0 = background / none
using KeyframeId = uint64_t;  // the tracker's mapping keyframe ID

// One object of the map as the object stage reports it (the Object message). The Gaussian count is
// the mapper's own and is not stored here.
struct ObjectRecord {
  ObjectId id = 0;
  int class_id = 0;
  std::string class_name;
  DualQuadric quadric;       // world (map) frame
  OrientedBox box;           // the box the object list reports (fitted, or the ellipsoid's)
  int observations = 0;
  double confidence = 0.0;
};

// A keyframe's pose as the map file stores it (the images are not stored).
struct KeyframePose {
  KeyframeId id = 0;
  double stamp = 0.0;     // seconds
  PinholeCamera camera;   // rectified pinhole camera of the keyframe
  SE3 T_wc;               // camera (optical) to map, after the latest bundle adjustment
};

// A keyframe as the mapping stage gets it (the KeyFrame message).
struct MappingKeyframe {
  KeyframeId id = 0;
  double stamp = 0.0;
  PinholeCamera camera;  // rectified pinhole; the images are of its size
  SE3 T_wc;
  ImageRgb8 rgb;         // 3 channels, RGB
  DepthImage depth;      // metres; 0 / NaN = no measurement
};

// The object stage's verdict on one keyframe (the KeyFrameObjects message): its filtered,
// rectified detections, their instance image if the detector gave one (value j+1 = detection j,
// 0 = none; empty when there is none) and, parallel to the detections, the object each became
// (0 = rejected).
struct KeyframeObjects {
  KeyframeId keyframe_id = 0;
  std::vector<Detection2d> detections;
  InstanceImage instance;
  std::vector<ObjectId> object_ids;  // [detection]
};

// An object event (the ObjectEvent message).
struct MappingEvent {
  enum class Type { kCreated, kMerged, kRemoved };
  Type type = Type::kCreated;
  ObjectId id = 0;
  ObjectId into_id = 0;  // kMerged: id was merged into into_id
};

}  // namespace dqo::mapping
