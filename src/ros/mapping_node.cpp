// mapping_node: the mapping nodelet (dqo_map/MappingNodelet) in a process of its own, for those who
// run it without a nodelet manager (rosrun dqo_map mapping_node). Parameters, topics and services
// are the nodelet's; remappings and private parameters pass through.

#include <nodelet/loader.h>
#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "mapping");
  nodelet::Loader loader(false);  // no manager services: this process holds one nodelet
  nodelet::M_string remappings(ros::names::getRemappings());
  nodelet::V_string args(argv + 1, argv + argc);
  if (!loader.load(ros::this_node::getName(), "dqo_map/MappingNodelet", remappings, args)) {
    ROS_FATAL("mapping_node: cannot load dqo_map/MappingNodelet (is the package's nodelet_plugins.xml exported?)");
    return 1;
  }
  ros::spin();
  return 0;
}
