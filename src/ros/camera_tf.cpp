#include "camera_tf.h"

#include <tf2/exceptions.h>

#include "conversions.h"

namespace dqo::ros_bridge {
namespace {

constexpr int kMaxDepth = 64;  // tf trees are shallow; this only guards against a cycle

SE3 from_transform_msg(const geometry_msgs::Transform& t) {
  geometry_msgs::Pose pose;
  pose.position.x = t.translation.x;
  pose.position.y = t.translation.y;
  pose.position.z = t.translation.z;
  pose.orientation = t.rotation;
  return from_pose_msg(pose);
}

}  // namespace

CameraTf::CameraTf(const tf2_ros::Buffer& buffer, CameraTfOptions options)
    : buffer_(buffer), options_(std::move(options)) {}

std::string CameraTf::root_of(const std::string& frame) const {
  std::string current = frame, parent;
  for (int i = 0; i < kMaxDepth && buffer_._getParent(current, ros::Time(), parent); ++i) {
    if (parent == options_.map_frame) break;  // our own edge: current is the root below map
    current = parent;
  }
  return current;
}

bool CameraTf::is_ancestor(const std::string& ancestor, const std::string& frame) const {
  std::string current = frame, parent;
  for (int i = 0; i < kMaxDepth && buffer_._getParent(current, ros::Time(), parent); ++i) {
    if (parent == options_.map_frame) return false;
    if (parent == ancestor) return true;
    current = parent;
  }
  return false;
}

std::optional<SE3> CameraTf::lookup(const std::string& target, const std::string& source,
                                    const ros::Time& stamp, std::string* error) const {
  // The wait is in wall time. tf2's own timeout polls with sleeps of ROS time, which stands still
  // when /clock does (a paused bag, a bag at its end, a test that stops the clock): a frame whose
  // image beat its transform into the node would then hold the callback thread until time moved
  // on, and every frame behind it with it (seen: a rostest's last keyframes never came).
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(options_.timeout);
  while (!buffer_.canTransform(target, source, stamp) && ros::WallTime::now() < deadline) {
    ros::WallDuration(0.002).sleep();
  }
  try {
    const auto tf = buffer_.lookupTransform(target, source, stamp);
    return from_transform_msg(tf.transform);
  } catch (const tf2::TransformException& e) {
    if (error) *error = "no transform " + target + " <- " + source + " at " + std::to_string(stamp.toSec()) + ": " + e.what();
    return std::nullopt;
  }
}

std::optional<std::string> CameraTf::anchor_frame(const std::string& camera_frame, const ros::Time& stamp,
                                                  std::string* error) {
  std::string child;
  if (!options_.odom_frame.empty()) {
    child = options_.odom_frame;
    if (child != camera_frame && !is_ancestor(child, camera_frame)) {
      if (error) *error = "odom frame '" + child + "' is not above the camera frame '" + camera_frame + "' in tf";
      return std::nullopt;
    }
  } else if (!options_.base_frame.empty()) {
    child = options_.base_frame;
    if (child != camera_frame && !is_ancestor(child, camera_frame)) {
      if (error) *error = "base frame '" + child + "' is not above the camera frame '" + camera_frame + "' in tf";
      return std::nullopt;
    }
  } else {
    const std::string found = root_of(camera_frame);
    if (found != camera_frame) {
      root_ = found;  // a tree above the camera: remember it
    } else if (root_.empty()) {
      if (wait_started_.isZero()) wait_started_ = stamp;
      if ((stamp - wait_started_).toSec() < options_.root_wait) {
        if (error) *error = "waiting for the tf tree above '" + camera_frame + "'";
        return std::nullopt;
      }
      root_ = camera_frame;  // no parent appeared: the camera is its own root
    }
    child = root_;
  }
  return child;
}

std::optional<SE3> CameraTf::frame_to_camera(const std::string& frame, const std::string& camera_frame,
                                             const ros::Time& stamp, std::string* error) const {
  if (frame == camera_frame) return SE3::identity();
  return lookup(frame, camera_frame, stamp, error);
}

std::optional<geometry_msgs::TransformStamped> CameraTf::edge(const std::string& camera_frame,
                                                              const ros::Time& stamp,
                                                              const SE3& T_map_cam, std::string* error) {
  const std::optional<std::string> anchor = anchor_frame(camera_frame, stamp, error);
  if (!anchor) return std::nullopt;
  const std::string& child = *anchor;

  // Never a second parent: the frame we attach to map must have none other.
  std::string parent;
  if (buffer_._getParent(child, ros::Time(), parent) && parent != options_.map_frame) {
    if (error) {
      *error = "frame '" + child + "' already has the parent '" + parent + "' in tf: not publishing " +
               options_.map_frame + " -> " + child + " (set odom_frame or base_frame)";
    }
    return std::nullopt;
  }

  SE3 T_map_child = T_map_cam;
  if (child != camera_frame) {
    const auto T_child_cam = lookup(child, camera_frame, stamp, error);
    if (!T_child_cam) return std::nullopt;
    T_map_child = T_map_cam * T_child_cam->inverse();
  }
  geometry_msgs::TransformStamped tf;
  tf.header.stamp = stamp;
  tf.header.frame_id = options_.map_frame;
  tf.child_frame_id = child;
  tf.transform = to_transform_msg(T_map_child);
  return tf;
}

std::optional<SE3> CameraTf::camera_pose(const std::string& camera_frame, const ros::Time& stamp,
                                         std::string* error) const {
  return lookup(options_.map_frame, camera_frame, stamp, error);
}

}  // namespace dqo::ros_bridge
