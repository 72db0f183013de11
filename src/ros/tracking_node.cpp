// tracking_node: the ROS skin of the tracking stage (dqo::tracking::TrackingSession). Synchronises
// colour, depth and camera_info, converts and undistorts them, tracks, and publishes mapping
// keyframes, their bundle-adjusted poses, the path, the tracking state and tf. No tracking maths
// lives here. Parameters and topics: README ("tracking_node"), launch/tracking.launch.
//
// Bad input never stops the node: a frame it cannot use is skipped with a throttled log line that
// says why (unsupported encoding, sizes that disagree, no depth, a camera it cannot undistort);
// missing topics are reported from a timer; time going backwards (a looping bag) resets tracking.
#include <algorithm>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>

#include <message_filters/subscriber.h>
#include <message_filters/sync_policies/approximate_time.h>
#include <message_filters/synchronizer.h>
#include <nav_msgs/Path.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <std_msgs/String.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>

#include <dqo_map/KeyFrame.h>
#include <dqo_map/KeyFramePoses.h>

#include "camera_tf.h"
#include "conversions.h"
#include "dqo_map/tracking/tracking_session.h"
#include "dqo_map/tracking/undistortion.h"
#include "ros_params.h"

namespace dqo::ros_bridge {
namespace {

using sensor_msgs::CameraInfoConstPtr;
using sensor_msgs::ImageConstPtr;
using tracking::TrackingState;
using SyncPolicy = message_filters::sync_policies::ApproximateTime<sensor_msgs::Image, sensor_msgs::Image,
                                                                   sensor_msgs::CameraInfo>;

constexpr double kThrottle = 5.0;  // seconds between repeats of one complaint

struct NodeParams {
  std::string rgb_topic = "rgb/image_raw";
  std::string depth_topic = "depth_to_rgb/image_raw";
  std::string camera_info_topic = "rgb/camera_info";
  int queue_size = 10;
  double sync_slop = 0.05;          // seconds between the stamps of one synchronised triple
  std::string pose_source = "tracker";  // or "tf"
  std::string camera_frame;         // empty: the colour image's frame_id
  bool publish_tf = true;
  double min_valid_depth = 0.01;    // fraction of pixels with depth below which a frame is skipped
  int path_max_poses = 10000;
  double path_period = 0.2;         // seconds of image time between path messages
  CameraTfOptions tf;
};

class TrackingNode {
 public:
  TrackingNode(ros::NodeHandle nh, ros::NodeHandle pnh);
  bool ok() const { return session_ != nullptr; }

 private:
  void on_frame(const ImageConstPtr& rgb, const ImageConstPtr& depth, const CameraInfoConstPtr& info);
  void track_frame(const ImageConstPtr& rgb, const ImageConstPtr& depth, const CameraInfoConstPtr& info);
  bool prepare_camera(const sensor_msgs::CameraInfo& info);
  void handle_result(const tracking::SessionResult& r, const std_msgs::Header& image_header,
                     const std::string& camera_frame);
  void publish_corrections(const ros::Time& stamp);
  void publish_state(TrackingState state);
  void check_inputs(const ros::WallTimerEvent&);
  // ROS_*_THROTTLE counts in ROS time, which a looping bag sends backwards, silencing a message
  // until the bag catches up again: complaints are throttled in wall time instead, per kind.
  bool throttled(const std::string& kind, double period = kThrottle);

  ros::NodeHandle nh_, pnh_;
  NodeParams p_;
  std::unique_ptr<tracking::TrackingSession> session_;

  message_filters::Subscriber<sensor_msgs::Image> rgb_sub_, depth_sub_;
  message_filters::Subscriber<sensor_msgs::CameraInfo> info_sub_;
  std::unique_ptr<message_filters::Synchronizer<SyncPolicy>> sync_;
  ros::Publisher keyframe_pub_, poses_pub_, path_pub_, state_pub_;
  tf2_ros::Buffer tf_buffer_;
  tf2_ros::TransformListener tf_listener_;
  tf2_ros::TransformBroadcaster tf_broadcaster_;
  std::unique_ptr<CameraTf> camera_tf_;
  ros::WallTimer input_timer_;

  // The undistortion of the current camera, rebuilt when its calibration changes.
  std::optional<tracking::CameraCalibration> calibration_;
  std::optional<tracking::Undistorter> undistorter_;

  nav_msgs::Path path_;
  ros::Time last_path_stamp_;
  ros::Time last_stamp_;
  std::optional<TrackingState> published_state_;
  uint64_t lost_since_frame_ = 0;
  uint64_t frames_ = 0;
  std::deque<double> recent_ms_;

  // Arrival times (wall clock) per input topic and of the last synchronised frame.
  ros::WallTime last_rgb_, last_depth_, last_info_, last_frame_;
  std::map<std::string, ros::WallTime> last_complaint_;
  std::string tf_child_;  // the frame map's edge goes to, once known
};

bool TrackingNode::throttled(const std::string& kind, double period) {
  const ros::WallTime now = ros::WallTime::now();
  ros::WallTime& last = last_complaint_[kind];
  if (!last.isZero() && (now - last).toSec() < period) return true;
  last = now;
  return false;
}

TrackingNode::TrackingNode(ros::NodeHandle nh, ros::NodeHandle pnh)
    : nh_(nh), pnh_(pnh), tf_listener_(tf_buffer_) {
  pnh_.param("rgb_topic", p_.rgb_topic, p_.rgb_topic);
  pnh_.param("depth_topic", p_.depth_topic, p_.depth_topic);
  pnh_.param("camera_info_topic", p_.camera_info_topic, p_.camera_info_topic);
  pnh_.param("queue_size", p_.queue_size, p_.queue_size);
  pnh_.param("sync_slop", p_.sync_slop, p_.sync_slop);
  pnh_.param("pose_source", p_.pose_source, p_.pose_source);
  pnh_.param("camera_frame", p_.camera_frame, p_.camera_frame);
  pnh_.param("publish_tf", p_.publish_tf, p_.publish_tf);
  pnh_.param("min_valid_depth", p_.min_valid_depth, p_.min_valid_depth);
  pnh_.param("path_max_poses", p_.path_max_poses, p_.path_max_poses);
  pnh_.param("path_period", p_.path_period, p_.path_period);
  pnh_.param("map_frame", p_.tf.map_frame, p_.tf.map_frame);
  pnh_.param("odom_frame", p_.tf.odom_frame, p_.tf.odom_frame);
  pnh_.param("base_frame", p_.tf.base_frame, p_.tf.base_frame);
  pnh_.param("tf_timeout", p_.tf.timeout, p_.tf.timeout);
  pnh_.param("root_wait", p_.tf.root_wait, p_.tf.root_wait);

  const std::set<std::string> known = {
      "rgb_topic",  "depth_topic",     "camera_info_topic", "queue_size", "sync_slop",  "pose_source",
      "camera_frame", "publish_tf",    "min_valid_depth",   "path_max_poses", "path_period", "map_frame",
      "odom_frame", "base_frame",      "tf_timeout",        "root_wait",  "tracker",    "mapping_keyframes"};
  for (const std::string& name : unknown_private_params(pnh_, known)) {
    ROS_WARN("tracking: ignoring unknown parameter %s/%s", pnh_.getNamespace().c_str(), name.c_str());
  }
  if (p_.pose_source != "tracker" && p_.pose_source != "tf") {
    ROS_FATAL("tracking: pose_source must be 'tracker' or 'tf', not '%s'", p_.pose_source.c_str());
    return;
  }
  if (p_.queue_size < 1 || p_.sync_slop < 0.0 || p_.tf.timeout < 0.0 || p_.min_valid_depth < 0.0 ||
      p_.min_valid_depth > 1.0) {
    ROS_FATAL("tracking: queue_size must be >= 1, sync_slop and tf_timeout >= 0, min_valid_depth in [0, 1]");
    return;
  }
  std::string error;
  const auto config = read_tracking_config(pnh_, &error);
  if (!config) {
    ROS_FATAL("tracking: %s", error.c_str());
    return;
  }
  session_ = std::make_unique<tracking::TrackingSession>(*config);
  camera_tf_ = std::make_unique<CameraTf>(tf_buffer_, p_.tf);

  keyframe_pub_ = nh_.advertise<dqo_map::KeyFrame>("keyframes", 10);
  poses_pub_ = nh_.advertise<dqo_map::KeyFramePoses>("keyframe_poses", 10);
  path_pub_ = nh_.advertise<nav_msgs::Path>("path", 1);
  state_pub_ = nh_.advertise<std_msgs::String>("tracking_state", 1, /*latch=*/true);
  path_.header.frame_id = p_.tf.map_frame;

  const ros::TransportHints hints = ros::TransportHints().tcpNoDelay();
  rgb_sub_.subscribe(nh_, p_.rgb_topic, p_.queue_size, hints);
  depth_sub_.subscribe(nh_, p_.depth_topic, p_.queue_size, hints);
  info_sub_.subscribe(nh_, p_.camera_info_topic, p_.queue_size, hints);
  rgb_sub_.registerCallback(boost::function<void(const ImageConstPtr&)>(
      [this](const ImageConstPtr&) { last_rgb_ = ros::WallTime::now(); }));
  depth_sub_.registerCallback(boost::function<void(const ImageConstPtr&)>(
      [this](const ImageConstPtr&) { last_depth_ = ros::WallTime::now(); }));
  info_sub_.registerCallback(boost::function<void(const CameraInfoConstPtr&)>(
      [this](const CameraInfoConstPtr&) { last_info_ = ros::WallTime::now(); }));
  SyncPolicy policy(static_cast<uint32_t>(p_.queue_size));
  if (p_.sync_slop > 0.0) policy.setMaxIntervalDuration(ros::Duration(p_.sync_slop));
  sync_ = std::make_unique<message_filters::Synchronizer<SyncPolicy>>(std::as_const(policy), rgb_sub_, depth_sub_, info_sub_);
  sync_->registerCallback(&TrackingNode::on_frame, this);
  input_timer_ = nh_.createWallTimer(ros::WallDuration(1.0), &TrackingNode::check_inputs, this);
  publish_state(TrackingState::kNotInitialised);

  ROS_INFO("tracking: poses from %s; colour %s, depth %s, camera_info %s; keyframes on %s",
           p_.pose_source.c_str(), rgb_sub_.getTopic().c_str(), depth_sub_.getTopic().c_str(),
           info_sub_.getTopic().c_str(), keyframe_pub_.getTopic().c_str());
}

// Says which input is missing when frames stop coming (no camera_info yet, no depth, a wrong
// topic name): the synchroniser alone would stay silent.
void TrackingNode::check_inputs(const ros::WallTimerEvent&) {
  // Bundle adjustment runs on after the last frame (the end of a bag): its corrections go out here.
  if (!last_stamp_.isZero()) publish_corrections(last_stamp_);
  const ros::WallTime now = ros::WallTime::now();
  auto recent = [&](const ros::WallTime& t) { return !t.isZero() && (now - t).toSec() < 3.0; };
  const bool any = recent(last_rgb_) || recent(last_depth_) || recent(last_info_);
  if (!any || recent(last_frame_)) return;
  std::string missing;
  if (!recent(last_rgb_)) missing += " colour (" + rgb_sub_.getTopic() + ")";
  if (!recent(last_depth_)) missing += " depth (" + depth_sub_.getTopic() + ")";
  if (!recent(last_info_)) missing += " camera_info (" + info_sub_.getTopic() + ")";
  if (missing.empty()) missing = " none, but their stamps do not pair up (further apart than sync_slop, or out of order)";
  if (!throttled("sync")) ROS_WARN("tracking: inputs arrive but no synchronised frame; missing:%s", missing.c_str());
}

bool TrackingNode::prepare_camera(const sensor_msgs::CameraInfo& info) {
  const tracking::CameraCalibration c = to_calibration(info);
  if (calibration_ && *calibration_ == c) return undistorter_.has_value();
  calibration_ = c;
  std::string error;
  undistorter_ = tracking::Undistorter::create(c, &error);
  if (!undistorter_) {
    ROS_ERROR("tracking: cannot use camera_info (%s): %s; frames skipped until it changes",
              info_sub_.getTopic().c_str(), error.c_str());
    return false;
  }
  ROS_INFO("tracking: camera %dx%d, %s%s", c.width, c.height,
           c.distortion_model.empty() ? "no distortion model" : c.distortion_model.c_str(),
           undistorter_->is_identity() ? ", no distortion" : ": undistortion maps built");
  return true;
}

void TrackingNode::on_frame(const ImageConstPtr& rgb_msg, const ImageConstPtr& depth_msg,
                            const CameraInfoConstPtr& info) {
  // Whatever a frame holds, the node keeps running: anything thrown below skips this frame only.
  try {
    track_frame(rgb_msg, depth_msg, info);
  } catch (const std::exception& e) {
    if (!throttled("exception")) ROS_ERROR("tracking: frame at %.6f failed: %s: skipped", rgb_msg->header.stamp.toSec(),
                       e.what());
  }
}

void TrackingNode::track_frame(const ImageConstPtr& rgb_msg, const ImageConstPtr& depth_msg,
                               const CameraInfoConstPtr& info) {
  last_frame_ = ros::WallTime::now();
  const ros::Time stamp = rgb_msg->header.stamp;
  const std::string camera_frame = p_.camera_frame.empty() ? rgb_msg->header.frame_id : p_.camera_frame;
  if (camera_frame.empty()) {
    if (!throttled("frame_id")) ROS_ERROR("tracking: the colour image has no frame_id and camera_frame is not set: frame skipped");
    return;
  }
  if (!prepare_camera(*info)) return;

  std::string error;
  ImageRgb8 rgb_raw, rgb;
  DepthImage depth_raw, depth;
  if (!from_colour_msg(*rgb_msg, &rgb_raw, &error) || !from_depth_msg(*depth_msg, &depth_raw, &error)) {
    if (!throttled("encoding")) ROS_ERROR("tracking: %s: frame skipped", error.c_str());
    return;
  }
  if (!rgb_raw.same_size(depth_raw.width, depth_raw.height)) {
    if (!throttled("size")) ROS_ERROR(
                       "tracking: colour is %dx%d but depth %dx%d: depth must be registered to colour "
                       "(the driver's depth_to_rgb): frame skipped",
                       rgb_raw.width, rgb_raw.height, depth_raw.width, depth_raw.height);
    return;
  }
  if (!undistorter_->rectify_rgb(rgb_raw, &rgb, &error) || !undistorter_->rectify_depth(depth_raw, &depth, &error)) {
    if (!throttled("rectify")) ROS_ERROR("tracking: %s (camera_info disagrees with the images): frame skipped", error.c_str());
    return;
  }
  const size_t valid = count_valid_depth(depth);
  if (static_cast<double>(valid) < p_.min_valid_depth * depth.data.size() || valid == 0) {
    if (!throttled("depth")) ROS_WARN("tracking: only %zu of %zu pixels have depth (0, NaN or missing): frame skipped",
                      valid, depth.data.size());
    return;
  }

  tracking::SessionResult r;
  if (p_.pose_source == "tf") {
    const auto T_map_cam = camera_tf_->camera_pose(camera_frame, stamp, &error);
    if (!T_map_cam) {
      if (!throttled("pose_tf")) ROS_WARN("tracking: pose_source tf: %s: frame skipped", error.c_str());
      return;
    }
    r = session_->add_pose(stamp.toSec(), *T_map_cam);
  } else {
    const tracking::RgbdInput input{stamp.toSec(), &rgb, &depth};
    r = session_->track(undistorter_->camera(), input);
  }
  if (r.skipped != tracking::SessionResult::Skip::kNone) {
    ROS_DEBUG("tracking: frame at %.6f repeats the last stamp: skipped", stamp.toSec());
    return;
  }
  ++frames_;
  last_stamp_ = stamp;
  handle_result(r, rgb_msg->header, camera_frame);
  if (r.keyframe_id) {
    std_msgs::Header header = rgb_msg->header;
    header.frame_id = camera_frame;
    // The KeyFrame carries the rectified images: build their messages only for keyframes.
    dqo_map::KeyFrame kf;
    kf.header.stamp = stamp;
    kf.header.frame_id = p_.tf.map_frame;
    kf.id = *r.keyframe_id;
    kf.pose = to_pose_msg(r.track.T_wc);
    kf.camera_info = to_camera_info_msg(undistorter_->camera(), header, "plumb_bob");
    kf.rgb = to_rgb8_msg(rgb, header);
    kf.depth = to_depth_m_msg(depth, header);
    keyframe_pub_.publish(kf);
    ROS_DEBUG("tracking: keyframe %llu at %.6f", static_cast<unsigned long long>(kf.id), stamp.toSec());
  }
  publish_corrections(stamp);
}

void TrackingNode::handle_result(const tracking::SessionResult& r, const std_msgs::Header& image_header,
                                 const std::string& camera_frame) {
  const ros::Time stamp = image_header.stamp;
  if (r.reset) {
    ROS_WARN("tracking: time went back by %.3f s (a looping bag?): tracker and keyframe selection "
             "restarted, path cleared", r.time_jump);
    path_.poses.clear();
    last_path_stamp_ = ros::Time();
    camera_tf_->reset();
  }
  if (r.new_camera && frames_ > 1) ROS_WARN("tracking: the camera changed: tracking restarted");
  if (r.state_changed) {
    switch (r.track.state) {
      case TrackingState::kOk:
        if (r.previous_state == TrackingState::kLost) {
          ROS_INFO("tracking: relocalised at %.3f after %llu frames lost", stamp.toSec(),
                   static_cast<unsigned long long>(frames_ - lost_since_frame_));
        } else {
          if (p_.pose_source == "tf") {
            ROS_INFO("tracking: first camera pose from tf at %.3f", stamp.toSec());
          } else {
            ROS_INFO("tracking: initialised at %.3f (%d features)", stamp.toSec(), r.track.features);
          }
        }
        break;
      case TrackingState::kLost:
        lost_since_frame_ = frames_;
        ROS_WARN("tracking: lost at %.3f (%d features, %d inliers): relocalising", stamp.toSec(),
                 r.track.features, r.track.inliers);
        break;
      case TrackingState::kNotInitialised:
        ROS_INFO("tracking: waiting for a frame with enough depth to initialise");
        break;
    }
  }
  publish_state(r.track.state);

  if (p_.pose_source == "tracker") {
    recent_ms_.push_back(r.track.milliseconds);
    if (recent_ms_.size() > 300) recent_ms_.pop_front();
    std::vector<double> sorted(recent_ms_.begin(), recent_ms_.end());
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    if (!throttled("stats", 30.0)) ROS_INFO("tracking: %llu frames, %llu keyframes, %.1f ms per frame (median of the last %zu)",
                      static_cast<unsigned long long>(frames_), static_cast<unsigned long long>(session_->keyframes()),
                      sorted[sorted.size() / 2], sorted.size());
  }
  if (r.track.state != TrackingState::kOk) return;

  if (p_.publish_tf && p_.pose_source == "tracker") {
    std::string error;
    const auto edge = camera_tf_->edge(camera_frame, stamp, r.track.T_wc, &error);
    if (edge) {
      if (edge->child_frame_id != tf_child_) {
        ROS_INFO("tracking: publishing tf %s -> %s (so that %s -> %s is the camera pose)", edge->header.frame_id.c_str(),
                 edge->child_frame_id.c_str(), p_.tf.map_frame.c_str(), camera_frame.c_str());
        tf_child_ = edge->child_frame_id;
      }
      tf_broadcaster_.sendTransform(*edge);
    } else {
      if (!throttled("tf")) ROS_WARN("tracking: no tf published: %s", error.c_str());
    }
  }

  geometry_msgs::PoseStamped pose;
  pose.header.stamp = stamp;
  pose.header.frame_id = p_.tf.map_frame;
  pose.pose = to_pose_msg(r.track.T_wc);
  path_.poses.push_back(pose);
  if (p_.path_max_poses > 0 && static_cast<int>(path_.poses.size()) > p_.path_max_poses) {
    path_.poses.erase(path_.poses.begin(), path_.poses.begin() + (path_.poses.size() - p_.path_max_poses));
  }
  if (path_pub_.getNumSubscribers() > 0 &&
      (last_path_stamp_.isZero() || (stamp - last_path_stamp_).toSec() >= p_.path_period || r.keyframe_id)) {
    path_.header.stamp = stamp;
    path_pub_.publish(path_);
    last_path_stamp_ = stamp;
  }
}

void TrackingNode::publish_corrections(const ros::Time& stamp) {
  const auto corrected = session_->corrected_keyframes();
  if (corrected.empty()) return;
  dqo_map::KeyFramePoses msg;
  msg.header.stamp = stamp;
  msg.header.frame_id = p_.tf.map_frame;
  for (const auto& c : corrected) {
    msg.ids.push_back(c.id);
    msg.poses.push_back(to_pose_msg(c.T_wc));
  }
  poses_pub_.publish(msg);
}

void TrackingNode::publish_state(TrackingState state) {
  if (published_state_ == state) return;
  published_state_ = state;
  std_msgs::String msg;
  msg.data = tracking::to_string(state);
  state_pub_.publish(msg);
}

}  // namespace
}  // namespace dqo::ros_bridge

int main(int argc, char** argv) {
  ros::init(argc, argv, "tracking");
  dqo::ros_bridge::TrackingNode node(ros::NodeHandle(), ros::NodeHandle("~"));
  if (!node.ok()) return 1;
  ros::spin();
  return 0;
}
