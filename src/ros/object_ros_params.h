#pragma once
// The object stage's parameters from the association node's private ROS parameters (~objects, as
// launch/association.launch loads config/objects.yaml), through the core's strict YAML loader, so
// that the launch file and `dqo_objects --config FILE` share one parser and one set of errors.

#include <optional>
#include <string>

#include <ros/node_handle.h>

#include "dqo_map/common/mask_detections.h"
#include "dqo_map/objects/object_params.h"

namespace dqo::ros_bridge {

// ~objects (optional: absent keys keep their defaults) through objects::parse_object_params.
std::optional<objects::ObjectMapperParams> read_object_params(const ros::NodeHandle& private_nh,
                                                              std::string* error);

// mask_detector's class table, ~classes: a list of {value: N, class_id: I, class_name: S} (mono8 /
// mono16 masks) or {colour: [r, g, b], class_id: I, class_name: S} (colour-coded masks). False
// and *error naming the entry when an entry is malformed or a label is given twice.
bool read_mask_classes(const ros::NodeHandle& private_nh, MaskDetectionParams* params,
                       std::string* error);

}  // namespace dqo::ros_bridge
