#pragma once
// The value types of the object stage (METHOD.md §2–3, DESIGN.md association_node): what goes in
// per keyframe, what an object of the map holds, and what comes out. They mirror the messages
// (KeyFrame + DetectionArray in; Object, ObjectEvent, KeyFrameObjects out) without depending on ROS.
#include <cstdint>
#include <map>
#include <string>
#include <vector>
#include "dqo_map/common/dataset.h"
#include "dqo_map/geometry/box2d.h"
#include "dqo_map/geometry/dual_quadric.h"
#include "dqo_map/geometry/oriented_box.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/quadric_init.h"
#include "dqo_map/geometry/se3.h"

namespace dqo::objects {

using ObjectId = uint64_t;      // 0 = none; never reused, also across restarts (state file)
using KeyFrameId = uint64_t;

// One keyframe as the object stage needs it. Detections are already in the rectified (pinhole)
// image: a node maps raw detector boxes through the undistortion before building this.
struct ObjectKeyFrame {
  KeyFrameId id = 0;
  double stamp = 0.0;           // seconds
  PinholeCamera camera;         // rectified pinhole camera; width/height give the image size
  SE3 T_wc;                     // camera (optical) to world/map
  DepthView depth;              // optional (data == nullptr): enables the single-view fallback
  std::vector<Detection2d> detections;
};

// One detection that was associated with an object.
struct ObjectObservation {
  KeyFrameId keyframe_id = 0;
  Box2d box;                    // rectified image, pixels
  int class_id = 0;
  float score = 0.0f;
};

enum class ObjectState {
  kCandidate,   // seen, not yet confirmed (has its final ID already)
  kConfirmed,
};

struct MapObject {
  ObjectId id = 0;
  ObjectState state = ObjectState::kCandidate;
  DualQuadric quadric;
  bool has_quadric = false;     // false only for a candidate whose first view gave no ellipsoid
  bool from_boxes = false;      // initialised from box planes (≥ 3 views), not from one depth view
  // The object's oriented box fitted to its detections (BoxFitParams); the ellipsoid's box
  // (box_from_quadric) until there is one. Object lists report this.
  bool has_box = false;
  OrientedBox box;
  // Labels as a histogram: association is by geometry, so look-alike classes of one object (a
  // cabinet called refrigerator, oven, microwave, tv in turn) build one object; its class is the
  // mode of the score-weighted votes (with hysteresis: LabelParams::rename_margin).
  int class_id = 0;             // the mode of the class vote
  std::string class_name;
  double confidence = 0.0;      // share of the (score-weighted) class vote won by class_id
  std::map<int, double> class_votes;           // class ID -> summed detection score
  std::vector<ObjectObservation> observations; // oldest first, at most one per keyframe
  // Every observation ever added (also those before a restart, whose keyframes are gone, and
  // those of objects merged into this one); observations.size() counts this run's only.
  int observation_count = 0;
  // Belief that the object exists, as log-odds (ExistenceParams): raised by detections, lowered
  // by misses where it should be seen, unless the depth shows it is there.
  double existence = 0.0;
  int missed = 0;               // keyframes since the last detection where it should have been seen
                                // (reporting only: removal goes by `existence`)
  KeyFrameId first_keyframe = 0;
  KeyFrameId last_keyframe = 0; // last keyframe with an observation
};

// The classes of an object's vote, most votes first (ties: lower class ID), with their shares of
// the total; at most `max` of them.
struct ClassShare {
  int class_id = 0;
  std::string class_name;
  double share = 0.0;
};
std::vector<ClassShare> top_classes(const MapObject& object, int max,
                                    const std::map<int, std::string>& names = {});

// P(exists) from the object's log-odds.
double existence_probability(const MapObject& object);

struct ObjectEvent {
  enum class Type { kCreated, kMerged, kRemoved, kRenamed };
  ObjectEvent() = default;
  ObjectEvent(Type type_, ObjectId id_, ObjectId into_id_ = 0) : type(type_), id(id_), into_id(into_id_) {}
  Type type = Type::kCreated;
  ObjectId id = 0;
  ObjectId into_id = 0;         // kMerged only: id was merged into into_id
  int class_id = 0;             // kRenamed only: the object's new class (its mode changed)
  std::string class_name;
};

// Why a detection of a keyframe did not become (part of) an object.
enum class DetectionVerdict {
  kAssociated,      // matched an existing object
  kNewObject,       // started a new object (candidate)
  kInvalid,         // NaN, negative or zero size
  kLowScore,
  kTooSmall,
  kTooLarge,
  kAtBorder,
  kDuplicate,       // overlaps a better detection of the frame
  kNoInit,          // would start an object but no ellipsoid could be initialised
  kOverLimit,       // beyond max_detections_per_keyframe
};
const char* to_string(DetectionVerdict verdict);

// The result of one keyframe, parallel to its input detections.
struct KeyFrameAssociation {
  KeyFrameId keyframe_id = 0;
  std::vector<DetectionVerdict> verdicts;      // [input detection]
  std::vector<ObjectId> object_ids;            // [input detection]; 0 = rejected
  // The detections that passed the filter (what KeyFrameObjects publishes), in input order, with
  // the index of each in the input and the object it became (0 when none).
  std::vector<Detection2d> filtered;
  std::vector<int> filtered_source;            // [filtered] -> input index
  std::vector<ObjectId> filtered_object_ids;   // [filtered]
  std::vector<ObjectEvent> events;             // in the order they happened
  // Objects confirmed by this keyframe (candidates before it, confirmed after it and still in the
  // map), by ascending ID: what a user waits for, apart from CREATED (which every candidate gets).
  std::vector<ObjectId> confirmed;
  double association_ms = 0.0;                 // filter + visibility + association + merge + init
  double refinement_ms = 0.0;                  // IoU refinement of the objects seen
  double box_fit_ms = 0.0;                     // box fits of the objects seen
  int refined_objects = 0;
  // One entry per refinement run in this keyframe (ok or not), for per-object timings.
  struct Refinement {
    ObjectId id = 0;
    bool ok = false;
    int views = 0;
    double ms = 0.0;
  };
  std::vector<Refinement> refinements;
};

// A detector's instance image (value k+1 = input detection k) renumbered for the filtered
// detections of a KeyFrameAssociation (value j+1 = filtered detection j, whose input index is
// filtered_source[j]); pixels of detections that did not pass become 0, as do values beyond the
// input's detection count. This is the instance image KeyFrameObjects carries.
InstanceImage renumber_instance(const InstanceImage& input, const std::vector<int>& filtered_source);

}  // namespace dqo::objects
