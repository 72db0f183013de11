#pragma once
// The OfflineStages callbacks of the full pipeline (system/offline_mapping.h): the tracker or a
// trajectory file for the poses, the object stage (ObjectMapper) for objects and pixel labels. The same
// classes the ROS nodes call: TrackingSession (tracking_node), ObjectMapper (association_node),
// GaussianMapper (the mapping nodelet).

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "dqo_map/common/tum_trajectory.h"
#include "dqo_map/io/trajectory_io.h"
#include "dqo_map/objects/object_mapper.h"
#include "dqo_map/system/offline_mapping.h"
#include "dqo_map/tracking/params_yaml.h"

namespace dqo::system {

// Poses from the tracker (TrackingSession: it also picks the mapping keyframes and reports the
// poses bundle adjustment moved). With `anchor` set and ground truth in the frames, the tracker's
// world (its first camera) is moved rigidly onto the ground truth at the first frame that has
// both, so objects and meshes compare with the ground truth; the tracker's drift still counts.
// Fills stages.pose and stages.corrected_poses.
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

// Where detections come from: the dataset's, or boxes of its instance masks when it has none.
enum class DetectionSource { kDataset, kMasks };

// The object stage (ObjectMapper) on each keyframe's detections. Fills stages.objects; returns the
// mapper so that the caller can read its objects and next ID at the end.
std::shared_ptr<objects::ObjectMapper> add_object_stage(const objects::ObjectMapperParams& params,
                                                        DetectionSource detections,
                                                        LabelSource labels,
                                                        const DatasetInfo& info,
                                                        OfflineStages* stages);

// The object stage's objects as mapping records.
std::vector<mapping::ObjectRecord> to_object_records(const std::vector<objects::MapObject>& objects);

}  // namespace dqo::system
