#include "dqo_map/ros/kinect_bag_writer.h"

#include <cstring>
#include <cmath>

#include <boost/make_shared.hpp>
#include <rosbag/bag.h>
#include <tf2_msgs/TFMessage.h>

#include "conversions.h"
#include "dqo_map/common/mask_detections.h"

namespace dqo::ros_bridge {
namespace {

// camera_base (x forward, y left, z up; REP-103 body) -> rgb_camera_link (optical: z forward,
// x right, y down), as the driver's URDF: the colour camera 32 mm left of the base origin and tilted
// 6 degrees down. The exact figures matter only in that the tree has this one static edge.
SE3 kinect_base_to_rgb() {
  Eigen::Matrix3d R_body_optical;
  R_body_optical << 0, 0, 1,  //
      -1, 0, 0,               //
      0, -1, 0;
  const Eigen::Matrix3d tilt = Eigen::AngleAxisd(6.0 * M_PI / 180.0, Eigen::Vector3d::UnitY()).toRotationMatrix();
  return SE3::from_rotation_translation(tilt * R_body_optical, Eigen::Vector3d(0.0, 0.032, 0.0));
}

geometry_msgs::TransformStamped stamped(const SE3& T, const std::string& parent, const std::string& child,
                                        const ros::Time& stamp) {
  geometry_msgs::TransformStamped tf;
  tf.header.stamp = stamp;
  tf.header.frame_id = parent;
  tf.child_frame_id = child;
  tf.transform = to_transform_msg(T);
  return tf;
}

}  // namespace

struct KinectBagWriter::Impl {
  rosbag::Bag bag;
  DatasetInfo info;
  KinectBagOptions options;
  SE3 T_base_rgb = kinect_base_to_rgb();
  bool wrote_static = false;
  uint32_t seq = 0;
};

KinectBagWriter::KinectBagWriter(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
KinectBagWriter::~KinectBagWriter() { close(); }

std::unique_ptr<KinectBagWriter> KinectBagWriter::open(const std::string& path, const DatasetInfo& info,
                                                       const KinectBagOptions& options, std::string* error) {
  auto impl = std::make_unique<Impl>();
  impl->info = info;
  impl->options = options;
  try {
    impl->bag.open(path, rosbag::bagmode::Write);
  } catch (const rosbag::BagException& e) {
    if (error) *error = "cannot open bag " + path + ": " + e.what();
    return nullptr;
  }
  return std::unique_ptr<KinectBagWriter>(new KinectBagWriter(std::move(impl)));
}

bool KinectBagWriter::write(const Frame& frame, std::string* error) {
  Impl& s = *impl_;
  const KinectBagOptions& o = s.options;
  if (frame.rgb.empty() || frame.depth.empty()) {
    if (error) *error = "frame " + std::to_string(frame.index) + " has no colour or depth image";
    return false;
  }
  const ros::Time stamp(o.start_time + frame.timestamp);
  std_msgs::Header header;
  header.stamp = stamp;
  header.frame_id = o.camera_frame;
  header.seq = s.seq++;
  try {
    if (!s.wrote_static) {
      tf2_msgs::TFMessage tf_static;
      tf_static.transforms.push_back(stamped(s.T_base_rgb, o.base_frame, o.camera_frame, stamp));
      // Latched, as tf2's static broadcaster publishes it: `rosbag play` then latches it too, so
      // a tf listener or rviz that starts late still gets camera_base -> rgb_camera_link.
      auto latched = boost::make_shared<ros::M_string>();
      (*latched)["type"] = ros::message_traits::datatype<tf2_msgs::TFMessage>();
      (*latched)["md5sum"] = ros::message_traits::md5sum<tf2_msgs::TFMessage>();
      (*latched)["message_definition"] = ros::message_traits::definition<tf2_msgs::TFMessage>();
      (*latched)["callerid"] = "/dqo_make_scene";
      (*latched)["latching"] = "1";
      s.bag.write("/tf_static", stamp, tf_static, latched);
      s.wrote_static = true;
    }
    s.bag.write(o.rgb_topic, stamp, to_bgra8_msg(frame.rgb, header));
    s.bag.write(o.depth_topic, stamp, to_depth_mm_msg(frame.depth, header));
    s.bag.write(o.camera_info_topic, stamp, to_camera_info_msg(s.info.camera, header, "rational_polynomial"));
    if (o.detections) {
      dqo_map::DetectionArray detections = to_detection_array_msg(frame.detections, header);
      // A segmenting detector's output: the instance masks numbered by detection (k+1 = detection k).
      if (o.instance_masks && !frame.instance.empty()) {
        const InstanceImage inst = instance_for_detections(frame.instance, frame.detections);
        detections.instance = image_msg(inst, "mono16", 2, header);
        std::memcpy(detections.instance.data.data(), inst.data.data(), detections.instance.data.size());
      }
      s.bag.write(o.detections_topic, stamp, detections);
    }
    if (o.ground_truth_tf && frame.has_pose) {
      tf2_msgs::TFMessage tf;
      const SE3 T_map_base = frame.T_wc * s.T_base_rgb.inverse();
      tf.transforms.push_back(stamped(T_map_base, o.map_frame, o.base_frame, stamp));
      s.bag.write("/tf", stamp, tf);
    }
  } catch (const rosbag::BagException& e) {
    if (error) *error = std::string("writing the bag failed: ") + e.what();
    return false;
  }
  return true;
}

void KinectBagWriter::close() {
  if (impl_ && impl_->bag.isOpen()) impl_->bag.close();
}

}  // namespace dqo::ros_bridge
