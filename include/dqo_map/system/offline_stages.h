#pragma once
// The OfflineStages callbacks of the full pipeline (system/offline_mapping.h): the tracker or a
// trajectory file for the poses, the object stage (ObjectMapper) for objects and pixel labels. The same
// classes the ROS nodes call: TrackingSession (tracking_node), ObjectMapper (association_node),
// GaussianMapper (the mapping nodelet).

#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "dqo_map/common/tum_trajectory.h"
#include "dqo_map/io/trajectory_io.h"
#include "dqo_map/objects/object_mapper.h"
#include "dqo_map/system/offline_mapping.h"
#include "dqo_map/tracking/object_landmarks.h"
#include "dqo_map/tracking/params_yaml.h"

namespace dqo::system {

// Poses from the tracker (TrackingSession: it also picks the mapping keyframes and reports the
// poses bundle adjustment moved). With `anchor` set and ground truth in the frames, the tracker's
// world (its first camera) is moved rigidly onto the ground truth at the first frame that has
// both, so objects and meshes compare with the ground truth; the tracker's drift still counts.
// Fills stages.pose and stages.corrected_poses, and with config.tracker.objects.enabled
// stages.object_feedback (the object stage's objects and sightings back to the tracker).
void add_tracking_stage(const tracking::TrackingConfig& config, const PinholeCamera& camera,
                        bool anchor, OfflineStages* stages);

// Poses from a trajectory (T_world_camera by time; dqo_track's output), anchored like the tracker's
// when `anchor`; keyframes picked by a KeyframeSelector.
void add_trajectory_stage(Trajectory trajectory, const PoseLookupParams& lookup,
                          const KeyframeSelectorParams& keyframes, bool anchor,
                          OfflineStages* stages);

enum class LabelSource {
  kMasks,     // the dataset's instance masks, renumbered to the object stage's detections
  kQuadrics,  // no instance image: the mapper labels depth points inside ellipsoid and box
};

// Where detections come from: the dataset's, boxes of its instance masks when it has none, or a
// detector run on each keyframe's colour image (dqo_map_offline --model).
enum class DetectionSource { kDataset, kMasks, kDetector };

// A detector's output for one frame: detections and, from segmenting models, the instance image
// (value k + 1 = detection k; empty without masks).
struct FrameDetections {
  std::vector<Detection2d> detections;
  InstanceImage instance;
};
using FrameDetector = std::function<FrameDetections(const Frame&)>;

// What the object stage saw and did on one keyframe, handed to an observer right after it (while
// the keyframe is being mapped, before the next): dqo_map_offline --overlays draws it.
struct ObjectStageView {
  const mapping::MappingKeyframe& keyframe;         // rectified images, pose
  const std::vector<Detection2d>& detections;       // the stage's input (dataset, masks, detector)
  const objects::KeyFrameAssociation& association;  // filtered detections and their objects
  const std::vector<objects::MapObject>& objects;   // confirmed and candidates, after this keyframe
};
using ObjectStageObserver = std::function<void(const ObjectStageView&)>;

// The object stage (ObjectMapper) on each keyframe's detections. Fills stages.objects; returns the
// mapper so that the caller can read its objects and next ID at the end. `detector` is required with
// DetectionSource::kDetector; its instance image (if any) labels the pixels with LabelSource::kMasks,
// never the dataset's ground-truth masks. `observer` (optional) sees every keyframe's outcome.
std::shared_ptr<objects::ObjectMapper> add_object_stage(const objects::ObjectMapperParams& params,
                                                        DetectionSource detections,
                                                        LabelSource labels,
                                                        const DatasetInfo& info,
                                                        OfflineStages* stages,
                                                        FrameDetector detector = {},
                                                        ObjectStageObserver observer = {});

// The object stage's confirmed objects as tracker landmarks, moved into the tracker's world by
// T_tracker_world, and one keyframe's associated detections as sightings (objects as landmarks).
std::vector<tracking::ObjectLandmark> object_landmarks(const std::vector<mapping::ObjectRecord>& objects,
                                                       const SE3& T_tracker_world);
std::vector<tracking::ObjectSighting> object_sightings(const mapping::KeyframeObjects& keyframe);

// The object stage's objects as mapping records.
std::vector<mapping::ObjectRecord> to_object_records(const std::vector<objects::MapObject>& objects);

}  // namespace dqo::system
