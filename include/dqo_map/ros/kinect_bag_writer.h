#pragma once
// Writes frames of a dataset (synthetic or read from disk) into a rosbag laid out as the Azure Kinect
// ROS driver records: what `rosbag play` then feeds to the nodes as if the camera were live.
// ROS-free interface (pimpl): no ROS header leaks to whoever includes this.

#include <memory>
#include <string>

#include "dqo_map/common/dataset.h"

namespace dqo::ros_bridge {

struct KinectBagOptions {
  std::string rgb_topic = "/rgb/image_raw";                 // bgra8
  std::string depth_topic = "/depth_to_rgb/image_raw";      // 16UC1, millimetres
  std::string camera_info_topic = "/rgb/camera_info";
  std::string detections_topic = "/detections";             // dqo_map/DetectionArray
  std::string camera_frame = "rgb_camera_link";             // optical frame of the colour camera
  std::string base_frame = "camera_base";                   // root of the driver's tf tree
  std::string map_frame = "map";
  bool detections = true;
  bool instance_masks = false;   // attach each frame's instance masks to its detections (mono16)
  bool ground_truth_tf = false;  // map -> camera_base from the ground-truth poses, on /tf
  double start_time = 1000.0;    // stamp of timestamp 0 (seconds; ROS time must be > 0)
};

class KinectBagWriter {
 public:
  // Opens (truncates) the bag; nullptr and *error on failure.
  static std::unique_ptr<KinectBagWriter> open(const std::string& path, const DatasetInfo& info,
                                               const KinectBagOptions& options, std::string* error);
  ~KinectBagWriter();
  KinectBagWriter(const KinectBagWriter&) = delete;
  KinectBagWriter& operator=(const KinectBagWriter&) = delete;

  // One capture: colour, depth, camera_info and detections under one stamp (frame.timestamp +
  // start_time); the static tf is written with the first frame.
  bool write(const Frame& frame, std::string* error);
  void close();

 private:
  struct Impl;
  explicit KinectBagWriter(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace dqo::ros_bridge
