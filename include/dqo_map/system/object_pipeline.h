#pragma once
// The object stage over a dataset, without ROS (DESIGN.md "Layers": system/ wires the stages
// in-process for the offline runner and the benchmarks). For each frame with a pose: the
// keyframe selector of the mapping stage (KeyframeSelector) decides whether it is a
// keyframe; each keyframe goes to the ObjectMapper with the dataset's detections and, for the
// single-view fallback, its depth. Poses are the dataset's ground truth or a trajectory (for
// example dqo_track's output) matched to the frames by timestamp.
#include <functional>
#include <map>
#include <string>
#include <vector>
#include "dqo_map/common/tum_trajectory.h"
#include "dqo_map/io/dataset_reader.h"
#include "dqo_map/io/trajectory_io.h"
#include "dqo_map/objects/object_mapper.h"
#include "dqo_map/common/keyframe_selector.h"

namespace dqo::system {

struct ObjectPipelineParams {
  objects::ObjectMapperParams mapper;
  KeyframeSelectorParams keyframes;
  PoseLookupParams pose_lookup;  // trajectory poses at the frames' timestamps
  bool use_depth = true;         // hand the keyframes' depth to the mapper (single-view fallback)
  int max_frames = -1;           // < 0: all frames
  // A tracker's trajectory starts in its own world frame (dqo_track: the first camera at the
  // origin). With this set, the trajectory is moved rigidly so that its pose at the first frame
  // that has both equals the ground truth there: objects then come out in the ground truth's
  // frame, comparable with objects_gt.txt, and the tracker's drift still counts in full.
  bool anchor_to_ground_truth = false;
  // Called after each keyframe with what went in and what the mapper made of it (a benchmark's
  // trace, an overlay writer); empty: nothing is called.
  std::function<void(const objects::ObjectKeyFrame&, const objects::KeyFrameAssociation&,
                     const objects::ObjectMapper&)>
      on_keyframe;
};

struct ObjectPipelineResult {
  bool ok = false;
  std::string error;                          // empty when ok
  std::vector<objects::MapObject> objects;    // confirmed objects, by ID
  std::map<int, std::string> class_names;     // class ID -> name, as the detections named them
  std::vector<objects::ObjectEvent> events;   // in the order they happened
  std::vector<double> association_ms;         // [keyframe] filter + association + merge + init
  std::vector<double> refinement_ms;          // [refinement run] one object's refinement
  std::vector<SE3> keyframe_T_wc;             // the keyframes' poses (for 2D metrics)
  PinholeCamera camera;
  int frames = 0;                             // frames read
  int frames_without_pose = 0;                // skipped: no ground truth / no trajectory pose
  int keyframes = 0;
  bool anchored = false;                      // anchor_to_ground_truth was applied
  int detections = 0;                         // input detections of the keyframes
  int rejected_detections = 0;                // of those, dropped by the filter or without init
  double seconds = 0.0;                       // wall time of the whole run
};

// done = frames processed so far, total = frames to process.
using ProgressCallback = std::function<void(int done, int total)>;

// trajectory: nullptr for the dataset's ground-truth poses; otherwise T_world_camera by time
// (frames it cannot give a pose for are skipped). A frame that cannot be read stops the run
// (ok = false, error names the frame); what was mapped until then is returned.
ObjectPipelineResult run_object_pipeline(const FrameSource& reader, const ObjectPipelineParams& params,
                                         const Trajectory* trajectory = nullptr,
                                         const ProgressCallback& progress = {});

}  // namespace dqo::system
