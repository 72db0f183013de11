// mapping_node: the mapping nodelet (dqo_map/MappingNodelet) in a process of its own, for those who
// run it without a nodelet manager (rosrun dqo_map mapping_node). Parameters, topics and services
// are the nodelet's; remappings and private parameters pass through.

#include "nodelet_shim.h"

int main(int argc, char** argv) {
  return dqo::ros_bridge::run_nodelet_process(argc, argv, "mapping", "dqo_map/MappingNodelet");
}
