#include "conversions.h"

#include <cmath>
#include <cstring>

#include <sensor_msgs/image_encodings.h>

namespace dqo::ros_bridge {

geometry_msgs::Pose to_pose_msg(const SE3& T) {
  geometry_msgs::Pose pose;
  pose.position.x = T.translation().x();
  pose.position.y = T.translation().y();
  pose.position.z = T.translation().z();
  pose.orientation.w = T.quaternion().w();
  pose.orientation.x = T.quaternion().x();
  pose.orientation.y = T.quaternion().y();
  pose.orientation.z = T.quaternion().z();
  return pose;
}

geometry_msgs::Transform to_transform_msg(const SE3& T) {
  const geometry_msgs::Pose pose = to_pose_msg(T);
  geometry_msgs::Transform tf;
  tf.translation.x = pose.position.x;
  tf.translation.y = pose.position.y;
  tf.translation.z = pose.position.z;
  tf.rotation = pose.orientation;
  return tf;
}

SE3 from_pose_msg(const geometry_msgs::Pose& pose) {
  const Eigen::Quaterniond q(pose.orientation.w, pose.orientation.x, pose.orientation.y,
                             pose.orientation.z);
  return SE3(q, Eigen::Vector3d(pose.position.x, pose.position.y, pose.position.z));
}

sensor_msgs::Image to_bgra8_msg(const ImageRgb8& rgb, const std_msgs::Header& header) {
  sensor_msgs::Image msg;
  msg.header = header;
  msg.width = rgb.width;
  msg.height = rgb.height;
  msg.encoding = sensor_msgs::image_encodings::BGRA8;
  msg.is_bigendian = 0;
  msg.step = rgb.width * 4;
  msg.data.resize(static_cast<size_t>(msg.step) * rgb.height);
  const size_t n = static_cast<size_t>(rgb.width) * rgb.height;
  for (size_t i = 0; i < n; ++i) {
    msg.data[4 * i + 0] = rgb.data[3 * i + 2];
    msg.data[4 * i + 1] = rgb.data[3 * i + 1];
    msg.data[4 * i + 2] = rgb.data[3 * i + 0];
    msg.data[4 * i + 3] = 255;
  }
  return msg;
}

sensor_msgs::Image to_depth_mm_msg(const DepthImage& depth, const std_msgs::Header& header) {
  sensor_msgs::Image msg;
  msg.header = header;
  msg.width = depth.width;
  msg.height = depth.height;
  msg.encoding = sensor_msgs::image_encodings::TYPE_16UC1;
  msg.is_bigendian = 0;
  msg.step = depth.width * 2;
  msg.data.resize(static_cast<size_t>(msg.step) * depth.height);
  const size_t n = static_cast<size_t>(depth.width) * depth.height;
  for (size_t i = 0; i < n; ++i) {
    const float z = depth.data[i];
    uint16_t mm = 0;
    if (std::isfinite(z) && z > 0.f && z * 1000.f < 65535.5f) mm = static_cast<uint16_t>(std::lround(z * 1000.f));
    std::memcpy(&msg.data[2 * i], &mm, 2);  // little-endian host, is_bigendian = 0
  }
  return msg;
}

sensor_msgs::CameraInfo to_camera_info_msg(const PinholeCamera& camera, const std_msgs::Header& header,
                                           const std::string& distortion_model) {
  sensor_msgs::CameraInfo info;
  info.header = header;
  info.width = camera.width;
  info.height = camera.height;
  info.distortion_model = distortion_model;
  info.D.assign(distortion_model == "rational_polynomial" ? 8 : 5, 0.0);
  info.K = {camera.fx, 0.0, camera.cx, 0.0, camera.fy, camera.cy, 0.0, 0.0, 1.0};
  info.R = {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
  info.P = {camera.fx, 0.0, camera.cx, 0.0, 0.0, camera.fy, camera.cy, 0.0, 0.0, 0.0, 1.0, 0.0};
  return info;
}

dqo_map::DetectionArray to_detection_array_msg(const std::vector<Detection2d>& detections,
                                               const std_msgs::Header& header) {
  dqo_map::DetectionArray msg;
  msg.header = header;
  msg.detections.reserve(detections.size());
  for (const auto& d : detections) {
    dqo_map::Detection det;
    det.class_id = d.class_id;
    det.class_name = d.class_name;
    det.score = d.score;
    det.x_min = static_cast<float>(d.box.x_min);
    det.y_min = static_cast<float>(d.box.y_min);
    det.x_max = static_cast<float>(d.box.x_max);
    det.y_max = static_cast<float>(d.box.y_max);
    msg.detections.push_back(det);
  }
  return msg;
}

}  // namespace dqo::ros_bridge
