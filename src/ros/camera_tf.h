#pragma once
// Where the tracker's pose goes in tf without ever giving a frame a second parent (REP-105).
//
// The tracker knows T_map_camera. It publishes one edge, map -> X, chosen so that the chain
// map -> X -> ... -> camera equals that pose:
//   - X = odom_frame when one is configured: T_map_odom = T_map_cam * T_cam_odom (odom must lie
//     above the camera in tf, e.g. odom -> base_link -> camera_link -> camera);
//   - X = base_frame when one is configured;
//   - otherwise X = the root of the camera frame's tf tree (the Azure Kinect driver's camera_base,
//     above rgb_camera_link through its static tf), found by walking up the parents. A camera
//     frame without a parent is its own root, but only after `root_wait` seconds without a parent
//     appearing: a static tf that arrives late must not be preceded by map -> camera.
// X must have no parent other than map; otherwise nothing is published and the reason is given.

#include <optional>
#include <string>

#include <geometry_msgs/TransformStamped.h>
#include <ros/time.h>
#include <tf2_ros/buffer.h>

#include "dqo_map/geometry/se3.h"

namespace dqo::ros_bridge {

struct CameraTfOptions {
  std::string map_frame = "map";
  std::string odom_frame;  // empty: none
  std::string base_frame;  // empty: the root of the camera's tree
  double timeout = 0.1;    // wall seconds to wait for a transform at the image stamp (never ROS
                           // time: a paused bag stops it)
  double root_wait = 2.0;  // seconds (ROS time) before a parentless camera frame counts as the root
};

class CameraTf {
 public:
  CameraTf(const tf2_ros::Buffer& buffer, CameraTfOptions options);

  // The edge map -> X for the camera at `stamp` with pose T_map_cam, or nullopt and *error (the
  // reason: a missing transform, a frame with another parent, still waiting for the tree).
  std::optional<geometry_msgs::TransformStamped> edge(const std::string& camera_frame,
                                                      const ros::Time& stamp, const SE3& T_map_cam,
                                                      std::string* error);

  // The frame the map edge goes to (X above), or nullopt and *error (still waiting for the tree,
  // a configured frame that is not above the camera). tracking_node anchors its map at this frame's
  // first pose.
  std::optional<std::string> anchor_frame(const std::string& camera_frame, const ros::Time& stamp,
                                          std::string* error);
  // T_frame_cam from tf (identity when frame is the camera frame).
  std::optional<SE3> frame_to_camera(const std::string& frame, const std::string& camera_frame,
                                     const ros::Time& stamp, std::string* error) const;

  // The camera's pose T_map_cam read from tf (pose_source: tf).
  std::optional<SE3> camera_pose(const std::string& camera_frame, const ros::Time& stamp,
                                 std::string* error) const;

  // Forget the root wait (after a time jump: the tf buffer was cleared and refills).
  void reset() { wait_started_ = ros::Time(); }

 private:
  // The topmost ancestor of `frame` below map (frame itself when it has no parent).
  std::string root_of(const std::string& frame) const;
  bool is_ancestor(const std::string& ancestor, const std::string& frame) const;
  std::optional<SE3> lookup(const std::string& target, const std::string& source, const ros::Time& stamp,
                            std::string* error) const;

  const tf2_ros::Buffer& buffer_;
  CameraTfOptions options_;
  std::string root_;        // a root found above the camera: kept, so a cleared buffer cannot
                            // make the camera look parentless
  ros::Time wait_started_;  // first frame whose camera had no parent
};

}  // namespace dqo::ros_bridge
