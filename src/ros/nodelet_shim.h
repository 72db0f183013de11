#pragma once
// The body of a node that is a nodelet in a process of its own (mapping_node, yolo_detector_node):
// image_pipeline's shim, a nodelet::Loader that loads the same nodelet, so that no logic is
// duplicated. Remappings and private parameters pass through. Header-only: each shim is one main().

#include <nodelet/loader.h>
#include <ros/ros.h>

namespace dqo::ros_bridge {

// Runs nodelet `type` (e.g. "dqo_map/MappingNodelet") as node `name` until shutdown; 1 when it
// cannot be loaded.
inline int run_nodelet_process(int argc, char** argv, const char* name, const char* type) {
  ros::init(argc, argv, name);
  nodelet::Loader loader(false);  // no manager services: this process holds one nodelet
  nodelet::M_string remappings(ros::names::getRemappings());
  nodelet::V_string args(argv + 1, argv + argc);
  if (!loader.load(ros::this_node::getName(), type, remappings, args)) {
    ROS_FATAL("%s: cannot load %s (is the package's nodelet_plugins.xml exported?)", name, type);
    return 1;
  }
  ros::spin();
  return 0;
}

}  // namespace dqo::ros_bridge
