#pragma once
// Per-keyframe overlay images of an offline run (dqo_map_offline --overlays DIR): each keyframe's
// rectified image with the object stage's filtered detections and its objects (confirmed and
// candidates) as they stood right after that keyframe (objects/object_overlay.h draws them), and
// the object table a person reads at the end of a run.

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "dqo_map/common/image.h"
#include "dqo_map/objects/object_types.h"
#include "dqo_map/system/offline_stages.h"

namespace dqo::system {

// The overlay of one keyframe (draw_object_overlay of its filtered detections and the objects),
// drawn on the keyframe's image enlarged (bilinear) by the smallest whole factor that makes it at
// least `min_width` wide, so that labels stay readable on keyframes mapped at a reduced --scale.
ImageRgb8 keyframe_overlay(const ObjectStageView& view, int min_width = 640);

// The file a keyframe's overlay goes to: keyframe_<id, 6 digits>.png.
std::string keyframe_overlay_name(mapping::KeyframeId id);

struct OverlayLog {
  int written = 0;
  std::string error;  // the first failure (the folder stops being written to after it)
};

// An observer (add_object_stage) that writes keyframe_overlay into `folder` (created), counting
// into *log. The folder's older keyframe_*.png files are removed first, so that a second run into
// it leaves only its own. Returns an empty observer and *error when the folder cannot be made.
ObjectStageObserver overlay_writer(const std::string& folder, std::shared_ptr<OverlayLog> log,
                                   std::string* error, int min_width = 640);

// Class names by ID as the detections of a run name them (the object table names the classes of
// an object's vote): an observer that collects them into *names.
ObjectStageObserver class_name_collector(std::shared_ptr<std::map<int, std::string>> names);

// The objects as a table (one row each, by ID): id, class, the `top` classes of its vote with
// their shares (objects::top_classes), centre (m), box size (full extents along its axes, m),
// observations, P(exists).
std::string object_table(const std::vector<objects::MapObject>& objects,
                         const std::map<int, std::string>& class_names, int top = 3);

}  // namespace dqo::system
