#pragma once
// The three stages in-process over a sequence of frames (DESIGN.md "Layers": system/ wires the
// stage classes the nodes call, for dqo_map_offline and the benchmarks). Per frame: a pose (ground
// truth, a trajectory file or the tracker) and whether it is a mapping keyframe; per keyframe: the
// object stage (or the ground-truth instance masks) and the mapping stage (GaussianMapper), fed in
// the order the ROS nodes publish: the keyframe, the object events, the objects, the keyframe's
// objects; then corrected poses.
//
// This part needs neither OpenCV, Ceres nor Open3D (it builds on the GPU machine): the tracker and
// the object stage come in as OfflineStages callbacks (system/offline_stages.h makes them).

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "dqo_map/common/frame_source.h"
#include "dqo_map/common/keyframe_selector.h"
#include "dqo_map/mapping/gaussian_mapper.h"

namespace dqo::system {

// A frame's pose and whether it became a mapping keyframe.
struct FramePose {
  std::optional<SE3> T_wc;                      // nullopt: no pose (frame skipped)
  std::optional<mapping::KeyframeId> keyframe;  // set: the frame is mapping keyframe `keyframe`
  double ms = 0.0;                              // time the pose took (tracking)
  std::string state;                            // the tracker's state ("ok", ...); "" without one
  uint64_t object_costs = 0;                    // object-landmark costs in the tracker's BA so far
};

// What the object stage gives back for one keyframe.
struct ObjectStageOutput {
  mapping::KeyframeObjects keyframe_objects;
  std::vector<mapping::MappingEvent> events;   // in the order they happened
  std::vector<mapping::ObjectRecord> objects;  // every object the stage holds now
  double ms = 0.0;
};

struct OfflineStages {
  // Empty: the frame's ground-truth pose, keyframes chosen by a KeyframeSelector.
  std::function<FramePose(const Frame&)> pose;
  // Keyframe poses moved by bundle adjustment since the last call. May be empty.
  std::function<std::map<mapping::KeyframeId, SE3>()> corrected_poses;
  // Empty: ground_truth_objects() (the dataset's instance masks and boxes).
  std::function<ObjectStageOutput(const mapping::MappingKeyframe&, const Frame&)> objects;
  // Objects as landmarks of the tracker: each keyframe's object stage output handed back to the
  // pose stage right after it (before the next frame is tracked), as association_node's objects
  // topic does live. Called only with `objects` set (never with the ground truth's objects).
  std::function<void(const ObjectStageOutput&)> object_feedback;
};

struct OfflineMappingParams {
  KeyframeSelectorParams keyframes;  // for ground-truth poses
  int max_frames = -1;               // < 0: all
  int every = 1;                     // every K-th input frame is read
  // The mapping stage on a thread of its own while the frame loop goes on (as the ROS system
  // runs it); the map is the same either way (src/system/mapping_thread.h).
  bool mapping_thread = true;
};

// Per-stage timings, milliseconds.
struct StageTimings {
  std::vector<double> read_ms;     // [frame read] PNG decoding or rendering
  std::vector<double> pose_ms;     // [frame read] tracking
  std::vector<double> objects_ms;  // [keyframe] object stage
  std::vector<double> mapping_ms;  // [keyframe] mapping stage (labels + trainer)
};

struct OfflineResult {
  bool ok = false;
  std::string error;  // empty when ok
  int frames = 0;     // frames read
  int frames_without_pose = 0;
  int keyframes = 0;
  int rejected_keyframes = 0;  // refused by the mapper (bad images): logged in warnings
  std::vector<std::string> warnings;
  std::vector<std::pair<double, SE3>> trajectory;     // estimated T_wc per posed frame (by time)
  std::vector<std::pair<double, std::string>> states; // the tracker's state per frame (with a tracker)
  uint64_t object_costs = 0;  // object-landmark costs the tracker's bundle adjustments applied
  std::vector<std::pair<double, SE3>> ground_truth;   // the frames' ground truth, where they have it
  std::vector<mapping::MappingReport> reports;        // one per mapped keyframe
  StageTimings timings;
  double seconds = 0.0;  // wall time of the whole run
};

// Called after every frame: frames done of the total.
using OfflineProgress = std::function<void(int done, int total)>;

// Runs every stage over the source into `mapper`. A frame that cannot be read stops the run
// (ok = false, error names it); what was mapped until then stays in the mapper.
OfflineResult run_offline_mapping(const FrameSource& source, const OfflineStages& stages,
                                  const OfflineMappingParams& params,
                                  mapping::GaussianMapper* mapper,
                                  const OfflineProgress& progress = {});

// The object stage replaced by ground truth: one detection per object ID of the frame's instance
// image (its box, the object's class, score 1), the instance image renumbered as a detector's
// (k+1 = detection k) and object IDs = the ground truth's. Objects: the ground-truth boxes as the
// ellipsoids inscribed in them. A frame without an instance image gives no detections.
ObjectStageOutput ground_truth_objects(const Frame& frame, const DatasetInfo& info);

// The ellipsoid inscribed in an oriented box (semi-axes = half extents), as an object record.
mapping::ObjectRecord object_record_from_box(uint64_t id, int class_id,
                                             const std::string& class_name, const OrientedBox& box);

}  // namespace dqo::system
