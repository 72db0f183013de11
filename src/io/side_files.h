#pragma once
// Private to io/: the per-sequence side files of the own format, read by the own reader and (when
// present beside rgb.txt) by the TUM reader, so that a real sequence with boxes runs the object
// stage:
//   classes.txt     class_id class_name (the name may hold blanks)
//   detections.txt  frame x1 y1 x2 y2 class_id score [gt_id]; `frame` is a frame index (a whole
//                   number) or, where the reader can map one, a timestamp (a number with a point)
//   objects_gt.txt  an object list (common/object_list.h) with box half extents
//   instance/       uint16 PNGs of ground-truth object IDs (0 = none)
// Each file is optional: absent means "none".

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "dqo_map/common/dataset.h"

namespace dqo {
namespace io_detail {

bool read_classes_file(const std::string& path, std::map<int, std::string>* class_names,
                       std::string* error);

// A timestamp's frame, or nullopt when no frame is close enough (the line is then an error).
// Null: the `frame` column must be an index.
using FrameOfStamp = std::function<std::optional<int>(double)>;

// detections->size() is the frame count; detections land in (*detections)[frame].
bool read_detections_file(const std::string& path, const std::map<int, std::string>& class_names,
                          const FrameOfStamp& frame_of_stamp,
                          std::vector<std::vector<Detection2d>>* detections, std::string* error);

// Meshes from `dir`/meshes_gt/<id>.ply when load_meshes and the file exists.
bool read_gt_objects_file(const std::string& path, const std::string& dir, bool load_meshes,
                          const std::map<int, std::string>& class_names,
                          std::vector<GtObject>* objects, std::string* error);

// `path` if it exists (checked against the camera's size) into *instance; true and *instance
// untouched when it does not exist.
bool read_instance_if_present(const std::string& path, const PinholeCamera& camera,
                              InstanceImage* instance, std::string* error);

}  // namespace io_detail
}  // namespace dqo
