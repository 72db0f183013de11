#pragma once
// tracking_node's tf listener, made for bags that are replayed (looping, or played again without
// --clock): tf2 refuses a transform whose (frame, stamp) it already holds and says so on stderr
// (TF_REPEATED_DATA) for every such transform, which floods the log on every loop. tf2_ros's own
// listener clears its buffer only when ROS time jumps back, which does not happen without --clock.
// This one also clears it when the transforms' stamps go back by more than `jump_tolerance`, and
// when the node says its images did (clear_if_ahead_of); static transforms are kept across a clear
// (re-inserted), so the camera's tree stays known whether or not the bag sends them again.
// Messages are handled on a thread of their own, as tf2_ros's listener does, so that lookups with a
// timeout on the node's thread can wait for them.
#include <map>
#include <mutex>
#include <string>

#include <geometry_msgs/TransformStamped.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <tf2_msgs/TFMessage.h>
#include <tf2_ros/buffer.h>

namespace dqo::ros_bridge {

class ReplayTfListener {
 public:
  ReplayTfListener(tf2_ros::Buffer& buffer, const ros::NodeHandle& nh, double jump_tolerance = 1.0);
  ~ReplayTfListener();

  // Clears the buffer (static transforms kept) when it holds a transform stamped later than
  // `stamp` + jump_tolerance. Returns whether it did.
  bool clear_if_ahead_of(const ros::Time& stamp);

 private:
  void on_tf(const ros::MessageEvent<tf2_msgs::TFMessage const>& event, bool is_static);
  void clear_locked(double back_by, const char* why);

  tf2_ros::Buffer& buffer_;
  const double jump_tolerance_;
  ros::NodeHandle nh_;
  ros::CallbackQueue queue_;
  ros::AsyncSpinner spinner_;
  ros::Subscriber tf_sub_, static_sub_;
  std::mutex mutex_;
  std::map<std::string, geometry_msgs::TransformStamped> statics_;  // by child frame
  std::map<std::string, std::string> static_authority_;
  ros::Time newest_;    // the latest stamp of a dynamic transform in the buffer
  ros::Time last_now_;  // ROS time at the last message (sim time may go back too)
};

// Routes console_bridge's output (tf2's warnings, e.g. TF_REPEATED_DATA) into rosconsole, so that
// it reaches the node's log and /rosout instead of bare stderr.
void forward_console_bridge_to_rosconsole();

}  // namespace dqo::ros_bridge
