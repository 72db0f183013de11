// yolo_detector_node: the YOLO detector nodelet (dqo_map/YoloDetectorNodelet) in a process of its
// own (rosrun dqo_map yolo_detector_node). Parameters and topics are the nodelet's.

#include "nodelet_shim.h"

int main(int argc, char** argv) {
  return dqo::ros_bridge::run_nodelet_process(argc, argv, "yolo_detector", "dqo_map/YoloDetectorNodelet");
}
