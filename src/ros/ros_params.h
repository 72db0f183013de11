#pragma once
// Reading a core module's parameters from the node's private ROS parameters with the module's own
// strict YAML loader, so that a launch file's `rosparam load` of config/*.yaml and a CLI's
// --config FILE go through one parser (one source of truth, the same errors).

#include <optional>
#include <set>
#include <string>

#include <ros/node_handle.h>
#include <xmlrpcpp/XmlRpcValue.h>

#include "dqo_map/tracking/params_yaml.h"

namespace dqo::ros_bridge {

// A parameter tree as YAML (flow style, valid JSON): maps, lists, numbers, booleans, strings.
std::string to_yaml(const XmlRpc::XmlRpcValue& value);

// ~tracker and ~mapping_keyframes (each optional: absent keys keep their defaults) through
// tracking::parse_tracking_config. Errors name the node's namespace and the key's path.
std::optional<tracking::TrackingConfig> read_tracking_config(const ros::NodeHandle& private_nh,
                                                             std::string* error);

// Where a node keeps its files when its output_dir parameter is empty: $ROS_HOME/dqo_map, else
// ~/.ros/dqo_map (ROS's own log folder rule).
std::string default_output_dir();

// Private parameters of the node that are neither in `known` nor under one of its sections
// (e.g. "tracker/..."), for a warning about misspelt names.
std::set<std::string> unknown_private_params(const ros::NodeHandle& private_nh,
                                             const std::set<std::string>& known);

}  // namespace dqo::ros_bridge
