#pragma once
// The object stage's configuration as YAML (ObjectMapperParams), read by dqo_objects --config and
// by association_node (from its private ROS parameters, which launch/association.launch loads from
// the same file). config/objects.yaml holds the defaults and lists every field.
//
//   objects:
//     filter: {...}       # DetectionFilterParams
//     visibility: {...}   # VisibilityParams
//     association: {...}  # AssociationParams (strategy: iou | qd | iou+qd; distance: {kind: qd|w2, ...})
//     merge: {...}        # MergeParams
//     lifecycle: {...}    # LifecycleParams, with box_init: {...} and depth_init: {...}
//     refinement: {...}   # RefinementParams
//     refine: true
//
// Strict, like tracking/params_yaml.h: an unknown key, a key given twice, a value of the wrong type
// or out of range is an error "SOURCE:LINE:COLUMN: message" naming the key's full path
// (objects.filter.min_score), and nothing is loaded. Absent keys keep their defaults.
// yaml-cpp stays in the .cpp file.
#include <optional>
#include <string>
#include "dqo_map/objects/object_params.h"

namespace dqo::objects {

// Reads a file; nullopt and *error ("FILE:LINE:COLUMN: ...") on any problem.
std::optional<ObjectMapperParams> load_object_params(const std::string& path, std::string* error);
// Parses YAML text (with the top-level `objects:` key) over `base`. `source` names the text in
// messages; with positions = false they carry no line and column (text generated from ROS
// parameters).
std::optional<ObjectMapperParams> parse_object_params(const std::string& text,
                                                      const std::string& source, std::string* error,
                                                      const ObjectMapperParams& base = {},
                                                      bool positions = true);
// Every parameter, as text that parse_object_params reads back to the same values.
std::string object_params_to_yaml(const ObjectMapperParams& params);

}  // namespace dqo::objects
