// yolo_detector_node: the YOLO detector nodelet (dqo_map/YoloDetectorNodelet) in a process of its
// own (rosrun dqo_map yolo_detector_node). Parameters and topics are the nodelet's.

#include <nodelet/loader.h>
#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "yolo_detector");
  nodelet::Loader loader(false);
  nodelet::M_string remappings(ros::names::getRemappings());
  nodelet::V_string args(argv + 1, argv + argc);
  if (!loader.load(ros::this_node::getName(), "dqo_map/YoloDetectorNodelet", remappings, args)) {
    ROS_FATAL("yolo_detector_node: cannot load dqo_map/YoloDetectorNodelet (is nodelet_plugins.xml exported?)");
    return 1;
  }
  ros::spin();
  return 0;
}
