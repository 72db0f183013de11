#include "replay_tf_listener.h"

#include <console_bridge/console.h>

namespace dqo::ros_bridge {

ReplayTfListener::ReplayTfListener(tf2_ros::Buffer& buffer, const ros::NodeHandle& nh, double jump_tolerance)
    : buffer_(buffer), jump_tolerance_(jump_tolerance), nh_(nh), spinner_(1, &queue_) {
  buffer_.setUsingDedicatedThread(true);  // lookups with a timeout may wait: this thread fills it
  nh_.setCallbackQueue(&queue_);
  tf_sub_ = nh_.subscribe<tf2_msgs::TFMessage>(
      "/tf", 100, boost::bind(&ReplayTfListener::on_tf, this, boost::placeholders::_1, false));
  static_sub_ = nh_.subscribe<tf2_msgs::TFMessage>(
      "/tf_static", 100, boost::bind(&ReplayTfListener::on_tf, this, boost::placeholders::_1, true));
  spinner_.start();
}

ReplayTfListener::~ReplayTfListener() { spinner_.stop(); }

void ReplayTfListener::clear_locked(double back_by, const char* why) {
  buffer_.clear();
  for (const auto& [child, t] : statics_) buffer_.setTransform(t, static_authority_[child], true);
  newest_ = ros::Time();
  ROS_INFO("tf: %s went back by %.3f s (a replayed bag?): tf buffer cleared, static transforms kept", why, back_by);
}

bool ReplayTfListener::clear_if_ahead_of(const ros::Time& stamp) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (newest_.isZero() || newest_ <= stamp + ros::Duration(jump_tolerance_)) return false;
  clear_locked((newest_ - stamp).toSec(), "image time");
  return true;
}

void ReplayTfListener::on_tf(const ros::MessageEvent<tf2_msgs::TFMessage const>& event, bool is_static) {
  const std::string authority = event.getPublisherName();
  std::lock_guard<std::mutex> lock(mutex_);
  const ros::Time now = ros::Time::now();
  if (!last_now_.isZero() && now < last_now_) clear_locked((last_now_ - now).toSec(), "ROS time");
  last_now_ = now;
  for (const geometry_msgs::TransformStamped& t : event.getMessage()->transforms) {
    if (is_static) {
      statics_[t.child_frame_id] = t;
      static_authority_[t.child_frame_id] = authority;
    } else {
      if (!newest_.isZero() && t.header.stamp + ros::Duration(jump_tolerance_) < newest_) {
        clear_locked((newest_ - t.header.stamp).toSec(), "tf time");
      }
      if (t.header.stamp > newest_) newest_ = t.header.stamp;
    }
    try {
      buffer_.setTransform(t, authority, is_static);
    } catch (const std::exception& e) {
      ROS_WARN_THROTTLE(5.0, "tf: transform %s -> %s from %s refused: %s", t.header.frame_id.c_str(),
                        t.child_frame_id.c_str(), authority.c_str(), e.what());
    }
  }
}

namespace {

class RosconsoleOutput : public console_bridge::OutputHandler {
 public:
  void log(const std::string& text, console_bridge::LogLevel level, const char* /*filename*/, int /*line*/) override {
    switch (level) {
      case console_bridge::CONSOLE_BRIDGE_LOG_DEBUG: ROS_DEBUG("%s", text.c_str()); break;
      case console_bridge::CONSOLE_BRIDGE_LOG_INFO: ROS_INFO("%s", text.c_str()); break;
      case console_bridge::CONSOLE_BRIDGE_LOG_WARN: ROS_WARN("%s", text.c_str()); break;
      default: ROS_ERROR("%s", text.c_str()); break;
    }
  }
};

}  // namespace

void forward_console_bridge_to_rosconsole() {
  static RosconsoleOutput output;  // lives as long as the process: console_bridge keeps the pointer
  console_bridge::useOutputHandler(&output);
}

}  // namespace dqo::ros_bridge
