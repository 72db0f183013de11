#include "conversions.h"

#include <algorithm>
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
  sensor_msgs::Image msg = image_msg(rgb, sensor_msgs::image_encodings::BGRA8, 4, header);
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
  sensor_msgs::Image msg = image_msg(depth, sensor_msgs::image_encodings::TYPE_16UC1, 2, header);
  const size_t n = static_cast<size_t>(depth.width) * depth.height;
  for (size_t i = 0; i < n; ++i) {
    const float z = depth.data[i];
    uint16_t mm = 0;
    if (std::isfinite(z) && z > 0.f && z * 1000.0 < 65535.5) mm = static_cast<uint16_t>(std::lround(z * 1000.0));
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

bool check_image_layout(const sensor_msgs::Image& msg, size_t bytes_per_pixel, const char* what,
                        std::string* error) {
  const size_t row = static_cast<size_t>(msg.width) * bytes_per_pixel;
  if (msg.width == 0 || msg.height == 0 || msg.step < row ||
      msg.data.size() < static_cast<size_t>(msg.step) * (msg.height - 1) + row) {
    if (error) {
      *error = std::string(what) + " image " + std::to_string(msg.width) + "x" + std::to_string(msg.height) +
               " (" + msg.encoding + ", step " + std::to_string(msg.step) + ") holds " +
               std::to_string(msg.data.size()) + " bytes: malformed";
    }
    return false;
  }
  return true;
}

namespace {

// The host is little-endian (x86, ARM as ROS runs on them): data marked big-endian is swapped.
template <typename T>
T read_scalar(const uint8_t* p, bool big_endian) {
  uint8_t b[sizeof(T)];
  std::memcpy(b, p, sizeof(T));
  if (big_endian) std::reverse(b, b + sizeof(T));
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

}  // namespace

bool from_colour_msg(const sensor_msgs::Image& msg, ImageRgb8* rgb, std::string* error) {
  namespace enc = sensor_msgs::image_encodings;
  // Source channel of R, G, B per encoding.
  int channels = 0, r = 0, g = 0, b = 0;
  if (msg.encoding == enc::BGRA8) {
    channels = 4, r = 2, g = 1, b = 0;
  } else if (msg.encoding == enc::BGR8) {
    channels = 3, r = 2, g = 1, b = 0;
  } else if (msg.encoding == enc::RGB8) {
    channels = 3, r = 0, g = 1, b = 2;
  } else if (msg.encoding == enc::RGBA8) {
    channels = 4, r = 0, g = 1, b = 2;
  } else if (msg.encoding == enc::MONO8 || msg.encoding == enc::TYPE_8UC1) {
    channels = 1, r = 0, g = 0, b = 0;
  } else {
    if (error) {
      *error = "colour encoding '" + msg.encoding + "' is not supported (bgra8, bgr8, rgb8, rgba8, mono8)";
    }
    return false;
  }
  if (!check_image_layout(msg, channels, "colour", error)) return false;
  *rgb = ImageRgb8(static_cast<int>(msg.width), static_cast<int>(msg.height), 3);
  uint8_t* out = rgb->data.data();
  for (uint32_t y = 0; y < msg.height; ++y) {
    const uint8_t* in = msg.data.data() + static_cast<size_t>(y) * msg.step;
    for (uint32_t x = 0; x < msg.width; ++x, in += channels, out += 3) {
      out[0] = in[r];
      out[1] = in[g];
      out[2] = in[b];
    }
  }
  return true;
}

bool from_depth_msg(const sensor_msgs::Image& msg, DepthImage* depth, std::string* error) {
  namespace enc = sensor_msgs::image_encodings;
  const bool mm = msg.encoding == enc::TYPE_16UC1 || msg.encoding == enc::MONO16;
  const bool metres = msg.encoding == enc::TYPE_32FC1;
  if (!mm && !metres) {
    if (error) *error = "depth encoding '" + msg.encoding + "' is not supported (16UC1 millimetres, 32FC1 metres)";
    return false;
  }
  if (!check_image_layout(msg, mm ? 2 : 4, "depth", error)) return false;
  *depth = DepthImage(static_cast<int>(msg.width), static_cast<int>(msg.height), 1);
  float* out = depth->data.data();
  const bool big = msg.is_bigendian != 0;
  for (uint32_t y = 0; y < msg.height; ++y) {
    const uint8_t* in = msg.data.data() + static_cast<size_t>(y) * msg.step;
    for (uint32_t x = 0; x < msg.width; ++x, ++out) {
      float z;
      if (mm) {
        // As dataset folders read their PNGs (io/image_io.cpp depth_from_u16): the same
        // millimetres give the same float, so a bag and its dataset folder map alike.
        z = static_cast<float>(static_cast<double>(read_scalar<uint16_t>(in + 2 * x, big)) / 1000.0);
      } else {
        z = read_scalar<float>(in + 4 * x, big);
      }
      *out = (std::isfinite(z) && z > 0.f) ? z : 0.f;
    }
  }
  return true;
}

size_t count_valid_depth(const DepthImage& depth) {
  return static_cast<size_t>(
      std::count_if(depth.data.begin(), depth.data.end(), [](float z) { return z > 0.f; }));
}

sensor_msgs::Image to_rgb8_msg(const ImageRgb8& rgb, const std_msgs::Header& header) {
  sensor_msgs::Image msg = image_msg(rgb, sensor_msgs::image_encodings::RGB8, 3, header);
  if (rgb.channels == 3) {
    msg.data = rgb.data;
  } else {
    const size_t n = static_cast<size_t>(rgb.width) * rgb.height;
    for (size_t i = 0; i < n; ++i) {
      for (int c = 0; c < 3; ++c) msg.data[3 * i + c] = rgb.data[i * rgb.channels + std::min(c, rgb.channels - 1)];
    }
  }
  return msg;
}

sensor_msgs::Image to_depth_m_msg(const DepthImage& depth, const std_msgs::Header& header) {
  sensor_msgs::Image msg = image_msg(depth, sensor_msgs::image_encodings::TYPE_32FC1, 4, header);
  std::memcpy(msg.data.data(), depth.data.data(), msg.data.size());
  return msg;
}

tracking::CameraCalibration to_calibration(const sensor_msgs::CameraInfo& info) {
  tracking::CameraCalibration c;
  c.width = static_cast<int>(info.width);
  c.height = static_cast<int>(info.height);
  std::copy(info.K.begin(), info.K.end(), c.K.begin());
  std::copy(info.P.begin(), info.P.end(), c.P.begin());
  c.distortion_model = info.distortion_model;
  c.D = info.D;
  return c;
}

bool from_camera_info_msg(const sensor_msgs::CameraInfo& info, PinholeCamera* camera, std::string* error) {
  const auto& K = info.K;
  *camera = PinholeCamera{K[0], K[4], K[2], K[5], static_cast<int>(info.width), static_cast<int>(info.height)};
  if (!(std::isfinite(K[0]) && std::isfinite(K[4]) && std::isfinite(K[2]) && std::isfinite(K[5]) && K[0] > 0.0 &&
        K[4] > 0.0) ||
      camera->width <= 0 || camera->height <= 0) {
    if (error) *error = "camera_info has no usable pinhole K and size";
    return false;
  }
  return true;
}

sensor_msgs::Image to_mono16_msg(const InstanceImage& image, const std_msgs::Header& header) {
  sensor_msgs::Image msg = image_msg(image, sensor_msgs::image_encodings::MONO16, 2, header);
  if (!image.data.empty()) std::memcpy(msg.data.data(), image.data.data(), msg.data.size());  // little-endian host
  return msg;
}

InstanceImage to_instance_image(const LabelImage& labels) {
  InstanceImage out(labels.width, labels.height, 1, 0);
  for (size_t i = 0; i < labels.data.size(); ++i) out.data[i] = static_cast<uint16_t>(std::min<uint32_t>(labels.data[i], 0xffff));
  return out;
}

}  // namespace dqo::ros_bridge
