#pragma once
// Conversions between the core's value types and ROS messages. The ROS layer's only "maths": field
// copies and unit changes. Private to src/ros (ROS headers stay out of include/dqo_map).

#include <cstdint>
#include <string>
#include <vector>

#include <dqo_map/DetectionArray.h>
#include <geometry_msgs/Pose.h>
#include <geometry_msgs/Transform.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <std_msgs/Header.h>

#include "dqo_map/common/dataset.h"
#include "dqo_map/tracking/undistortion.h"

namespace dqo::ros_bridge {

geometry_msgs::Pose to_pose_msg(const SE3& T);
geometry_msgs::Transform to_transform_msg(const SE3& T);
SE3 from_pose_msg(const geometry_msgs::Pose& pose);

// RGB → bgra8 (the Azure Kinect driver's colour encoding).
sensor_msgs::Image to_bgra8_msg(const ImageRgb8& rgb, const std_msgs::Header& header);
// Metres → 16UC1 millimetres; NaN, ≤ 0 and beyond 65.535 m become 0 (no measurement).
sensor_msgs::Image to_depth_mm_msg(const DepthImage& depth, const std_msgs::Header& header);
// A pinhole camera as CameraInfo with zero distortion of the given model ("plumb_bob": 5 zeros,
// "rational_polynomial": 8 zeros, as the Azure Kinect driver publishes).
sensor_msgs::CameraInfo to_camera_info_msg(const PinholeCamera& camera, const std_msgs::Header& header,
                                           const std::string& distortion_model = "plumb_bob");
dqo_map::DetectionArray to_detection_array_msg(const std::vector<Detection2d>& detections,
                                               const std_msgs::Header& header);

// Colour images of the encodings cameras publish (bgra8, bgr8, rgb8, rgba8, mono8) as 3-channel
// RGB. False and *error (naming the encoding and those accepted) otherwise, or when the message's
// size fields do not match its data.
bool from_colour_msg(const sensor_msgs::Image& msg, ImageRgb8* rgb, std::string* error);
// Depth as metres: 16UC1 (or mono16) millimetres, 32FC1 metres. Anything that is not a positive
// finite depth (0, NaN, inf, negative) becomes 0, "no measurement". Big-endian data is swapped.
bool from_depth_msg(const sensor_msgs::Image& msg, DepthImage* depth, std::string* error);
// Whether an image message's size fields fit its data at `bytes_per_pixel`: false and *error
// ("<what> image WxH (encoding, step S) holds N bytes: malformed") otherwise. Every from_*_msg
// checks this before reading pixels, with the same words.
bool check_image_layout(const sensor_msgs::Image& msg, size_t bytes_per_pixel, const char* what,
                        std::string* error);
// Pixel count with a measurement (> 0).
size_t count_valid_depth(const DepthImage& depth);

// Rectified images for KeyFrame messages: rgb8, and 32FC1 metres (0 = no measurement).
sensor_msgs::Image to_rgb8_msg(const ImageRgb8& rgb, const std_msgs::Header& header);
sensor_msgs::Image to_depth_m_msg(const DepthImage& depth, const std_msgs::Header& header);

// The pinhole camera of a rectified CameraInfo (K and the size); false and *error when K is not
// a usable pinhole (non-positive or non-finite focal lengths, no size).
bool from_camera_info_msg(const sensor_msgs::CameraInfo& info, PinholeCamera* camera, std::string* error);
// An instance image (detection index + 1, or object IDs) as mono16.
sensor_msgs::Image to_mono16_msg(const InstanceImage& image, const std_msgs::Header& header);
// Label values as a uint16 instance image (values beyond 65535 saturate).
InstanceImage to_instance_image(const LabelImage& labels);

// The calibration of a CameraInfo, for the undistortion (ROS-free types).
tracking::CameraCalibration to_calibration(const sensor_msgs::CameraInfo& info);

// What every image message built here shares: `image`'s size and the header, `bytes_per_pixel`
// per pixel in packed rows, little-endian (is_bigendian = 0: the hosts ROS runs on are), and data
// zeroed at step x height for the caller to fill. One place, so the to_*_msg functions cannot
// disagree on step or byte order.
template <typename T>
sensor_msgs::Image image_msg(const Image<T>& image, const std::string& encoding, uint32_t bytes_per_pixel,
                             const std_msgs::Header& header) {
  sensor_msgs::Image msg;
  msg.header = header;
  msg.width = image.width;
  msg.height = image.height;
  msg.encoding = encoding;
  msg.is_bigendian = 0;
  msg.step = image.width * bytes_per_pixel;
  msg.data.resize(static_cast<size_t>(msg.step) * image.height);
  return msg;
}

}  // namespace dqo::ros_bridge
