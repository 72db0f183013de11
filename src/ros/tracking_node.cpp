// tracking_node: the ROS skin of the tracking stage (dqo::tracking::TrackingSession). Synchronises
// colour, depth and camera_info, converts and undistorts them, tracks, and publishes mapping
// keyframes, their bundle-adjusted poses, the path, the tracking state (ok / degraded / lost) and
// its evidence and reasons on /diagnostics, the map's identity and tf. Degraded frames publish a
// pose (tf, path) but make no keyframes; lost frames publish none.
// No tracking maths lives here. Parameters and topics: README ("tracking_node"), launch/tracking.launch.
//
// The map (REP-103, z up): anchored at the first pose of the camera's body frame (the root of its tf
// tree, camera_base for the Azure Kinect), levelled by gravity from the `imu` topic or the floor in
// the first frame's depth (map_level; the maths in tracking/map_levelling.h). The tracker's own frame
// (its first camera's optical frame) goes into this map by one fixed transform, T_map_tracker.
//
// Bad input never stops the node: a frame it cannot use is skipped with a throttled log line that
// says why (unsupported encoding, sizes that disagree, no depth before tracking started, a camera it
// cannot undistort); a frame without depth once tracking goes to the tracker, which reports it
// degraded or lost with its reasons; a frame out of order (stamped before the last one by at most
// stream/out_of_order_s) is skipped; missing topics are reported from a timer; time going further
// backwards (a looping bag) resets tracking and clears the tf buffer (replay_tf_listener.h: no
// TF_REPEATED_DATA flood).
//
// Objects as landmarks (tracker/object_landmarks/enabled): association_node's latched `objects`
// (its confirmed objects, map frame) and `keyframe_objects` (each keyframe's detections and the
// object each became) come back here and go to the tracker (Tracker::set_object_landmarks /
// add_object_sightings, the calls the offline pipeline makes). Which version a keyframe uses: the
// latest `objects` message received before its bundle adjustment is set up; objects arriving
// before the tracker's frame is in the map (T_map_tracker) are ignored, the next message counts.
#include <algorithm>
#include <cstdio>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <message_filters/subscriber.h>
#include <message_filters/sync_policies/approximate_time.h>
#include <message_filters/synchronizer.h>
#include <nav_msgs/Path.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <std_msgs/String.h>
#include <tf2_ros/transform_broadcaster.h>
#include <unistd.h>

#include <dqo_map/KeyFrame.h>
#include <dqo_map/KeyFrameObjects.h>
#include <dqo_map/KeyFramePoses.h>
#include <dqo_map/ObjectArray.h>

#include "camera_tf.h"
#include "conversions.h"
#include "dqo_map/tracking/map_identity.h"
#include "dqo_map/tracking/map_levelling.h"
#include "dqo_map/tracking/tracking_session.h"
#include "dqo_map/tracking/undistortion.h"
#include "replay_tf_listener.h"
#include "ros_params.h"
#include "sim_clock_watch.h"

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
  std::string map_level = "auto";   // auto | imu | floor | none: how the map is levelled
  int imu_samples = 200;            // accelerometer samples averaged for gravity
  double imu_wait = 1.0;            // auto: seconds (image time) to wait for them where imu has a publisher
  double level_timeout = 5.0;       // seconds without a gravity estimate before the map stays unlevelled
  double floor_max_tilt_deg = 45.0; // the floor's normal within this of the expected up
  double no_input_warn = 10.0;      // wall seconds without any image or camera_info before a WARN (<= 0: never)
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
  void on_objects(const dqo_map::ObjectArrayConstPtr& msg);
  void on_keyframe_objects(const dqo_map::KeyFrameObjectsConstPtr& msg);
  void publish_diagnostics(const tracking::SessionResult& r, const ros::Time& stamp);
  void on_imu(const sensor_msgs::ImuConstPtr& imu);
  // Decides the map's levelling (R_map_body_) from this frame; false (and why) while it must wait.
  bool decide_levelling(const std::string& camera_frame, const ros::Time& stamp, const DepthImage& depth,
                        std::string* why);
  std::optional<Eigen::Vector3d> imu_up(const std::string& body, const ros::Time& stamp, std::string* error) const;
  SE3 to_map(const SE3& T_tracker_cam) const { return T_map_tracker_ ? *T_map_tracker_ * T_tracker_cam : T_tracker_cam; }
  void check_inputs(const ros::WallTimerEvent&);
  void warn_no_input(const ros::WallTime& now);
  // ROS_*_THROTTLE counts in ROS time, which a looping bag sends backwards, silencing a message
  // until the bag catches up again: complaints are throttled in wall time instead, per kind.
  bool throttled(const std::string& kind, double period = kThrottle);

  ros::NodeHandle nh_, pnh_;
  NodeParams p_;
  std::unique_ptr<tracking::TrackingSession> session_;
  std::optional<tracking::MapIdentity> map_identity_;  // published on map_id (latched)

  message_filters::Subscriber<sensor_msgs::Image> rgb_sub_, depth_sub_;
  message_filters::Subscriber<sensor_msgs::CameraInfo> info_sub_;
  std::unique_ptr<message_filters::Synchronizer<SyncPolicy>> sync_;
  ros::Publisher keyframe_pub_, poses_pub_, path_pub_, state_pub_, map_id_pub_, diag_pub_;
  ros::Subscriber imu_sub_;
  ros::Subscriber objects_sub_, kf_objects_sub_;  // objects as landmarks (when enabled)
  size_t object_landmarks_ = 0;                   // objects in the last set given to the tracker
  uint64_t object_sightings_ = 0;                 // associated detections given to it
  bool objects_changed_ = false;                  // the next frame's diagnostics go out at once
  tf2_ros::Buffer tf_buffer_;
  std::unique_ptr<ReplayTfListener> tf_listener_;
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
  std::map<std::string, uint64_t> frames_per_state_;
  ros::WallTime last_diag_;

  // Arrival times (wall clock) per input topic and of the last synchronised frame.
  ros::WallTime last_rgb_, last_depth_, last_info_, last_frame_;
  ros::WallTime started_ = ros::WallTime::now();
  SimClockWatch clock_;  // a bag's stopped /clock, seen from the input checks
  bool bag_end_said_ = false;
  std::map<std::string, ros::WallTime> last_complaint_;
  std::string tf_child_;  // the frame map's edge goes to, once known

  // The map: levelling (decided once), the body frame's pose in the camera, and the tracker's frame
  // in the map (set at the first tracked frame of each tracker run; identity with pose_source tf).
  tracking::MapLevel level_ = tracking::MapLevel::kAuto;
  tracking::GravityEstimator gravity_{200};
  std::string imu_frame_;
  ros::Time level_wait_start_;
  std::optional<Eigen::Matrix3d> R_map_body_;
  SE3 T_body_cam_;
  std::optional<SE3> T_map_tracker_;
};

bool TrackingNode::throttled(const std::string& kind, double period) {
  const ros::WallTime now = ros::WallTime::now();
  ros::WallTime& last = last_complaint_[kind];
  if (!last.isZero() && (now - last).toSec() < period) return true;
  last = now;
  return false;
}

TrackingNode::TrackingNode(ros::NodeHandle nh, ros::NodeHandle pnh)
    : nh_(nh), pnh_(pnh) {
  forward_console_bridge_to_rosconsole();
  tf_listener_ = std::make_unique<ReplayTfListener>(tf_buffer_, ros::NodeHandle());
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
  pnh_.param("map_level", p_.map_level, p_.map_level);
  pnh_.param("imu_samples", p_.imu_samples, p_.imu_samples);
  pnh_.param("imu_wait", p_.imu_wait, p_.imu_wait);
  pnh_.param("level_timeout", p_.level_timeout, p_.level_timeout);
  pnh_.param("floor_max_tilt_deg", p_.floor_max_tilt_deg, p_.floor_max_tilt_deg);
  pnh_.param("no_input_warn", p_.no_input_warn, p_.no_input_warn);

  const std::set<std::string> known = {
      "rgb_topic",  "depth_topic",     "camera_info_topic", "queue_size", "sync_slop",  "pose_source",
      "camera_frame", "publish_tf",    "min_valid_depth",   "path_max_poses", "path_period", "map_frame",
      "odom_frame", "base_frame",      "tf_timeout",        "root_wait",  "tracker",    "mapping_keyframes", "stream",
      "map_level",  "imu_samples",     "imu_wait",          "level_timeout", "floor_max_tilt_deg", "no_input_warn"};
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
  const auto level = tracking::map_level_from_string(p_.map_level);
  if (!level || p_.imu_samples < 1 || p_.imu_wait < 0.0 || p_.level_timeout < 0.0 || !(p_.floor_max_tilt_deg > 0.0) ||
      p_.floor_max_tilt_deg > 90.0) {
    ROS_FATAL("tracking: map_level must be auto, imu, floor or none (not '%s'), imu_samples >= 1, imu_wait and "
              "level_timeout >= 0, floor_max_tilt_deg in (0, 90]", p_.map_level.c_str());
    return;
  }
  level_ = *level;
  gravity_ = tracking::GravityEstimator(p_.imu_samples);
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
  path_pub_ = nh_.advertise<nav_msgs::Path>("path", 1, /*latch=*/true);
  state_pub_ = nh_.advertise<std_msgs::String>("tracking_state", 10, /*latch=*/true);
  map_id_pub_ = nh_.advertise<std_msgs::String>("map_id", 1, /*latch=*/true);
  diag_pub_ = nh_.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10);
  path_.header.frame_id = p_.tf.map_frame;
  // The map's identity: objects made in one map mean nothing in another. A tracker run makes a map
  // of its own (its origin is where this run began); a map read from tf is whoever publishes it.
  // A re-anchored tracker (time going back, another camera) makes a new map: tracking::MapIdentity.
  std_msgs::String map_id;
  if (p_.pose_source == "tf") {
    map_identity_.emplace("tf:" + p_.tf.map_frame, /*external=*/true);
    T_map_tracker_ = SE3::identity();
  } else {
    char host[64] = {0};
    gethostname(host, sizeof(host) - 1);
    map_identity_.emplace("tracker:" + p_.tf.map_frame + ":" + std::string(host) + ":" + std::to_string(getpid()) +
                              ":" + std::to_string(ros::WallTime::now().toNSec()),
                          /*external=*/false);
    if (level_ == tracking::MapLevel::kAuto || level_ == tracking::MapLevel::kImu) {
      imu_sub_ = nh_.subscribe("imu", 400, &TrackingNode::on_imu, this);
    }
  }
  map_id.data = map_identity_->id();
  map_id_pub_.publish(map_id);
  if (config->tracker.objects.enabled && p_.pose_source == "tracker") {
    objects_sub_ = nh_.subscribe("objects", 1, &TrackingNode::on_objects, this);
    kf_objects_sub_ = nh_.subscribe("keyframe_objects", 20, &TrackingNode::on_keyframe_objects, this);
  }

  const ros::TransportHints hints = ros::TransportHints().tcpNoDelay();
  rgb_sub_.subscribe(nh_, p_.rgb_topic, p_.queue_size, hints);
  depth_sub_.subscribe(nh_, p_.depth_topic, p_.queue_size, hints);
  info_sub_.subscribe(nh_, p_.camera_info_topic, p_.queue_size, hints);
  rgb_sub_.registerCallback(boost::function<void(const ImageConstPtr&)>(
      [this](const ImageConstPtr&) {
        last_rgb_ = ros::WallTime::now();
        bag_end_said_ = false;
      }));
  depth_sub_.registerCallback(boost::function<void(const ImageConstPtr&)>(
      [this](const ImageConstPtr&) { last_depth_ = ros::WallTime::now(); }));
  info_sub_.registerCallback(boost::function<void(const CameraInfoConstPtr&)>(
      [this](const CameraInfoConstPtr&) { last_info_ = ros::WallTime::now(); }));
  SyncPolicy policy(static_cast<uint32_t>(p_.queue_size));
  if (p_.sync_slop > 0.0) policy.setMaxIntervalDuration(ros::Duration(p_.sync_slop));
  // A looping bag (sim time jumping back) clears the synchroniser's queues: otherwise the frames
  // it holds from before the jump stay ahead of the new ones, whose stamps are older, and the
  // policy (which assumes stamps only grow) drops or holds new frames until its queues overflow.
  policy.setReset(true);
  sync_ = std::make_unique<message_filters::Synchronizer<SyncPolicy>>(std::as_const(policy), rgb_sub_, depth_sub_, info_sub_);
  sync_->registerCallback(&TrackingNode::on_frame, this);
  input_timer_ = nh_.createWallTimer(ros::WallDuration(1.0), &TrackingNode::check_inputs, this);
  publish_state(TrackingState::kNotInitialised);

  ROS_INFO("tracking: poses from %s; colour %s, depth %s, camera_info %s; keyframes on %s; map '%s'",
           p_.pose_source.c_str(), rgb_sub_.getTopic().c_str(), depth_sub_.getTopic().c_str(),
           info_sub_.getTopic().c_str(), keyframe_pub_.getTopic().c_str(), map_id.data.c_str());
}

void TrackingNode::on_imu(const sensor_msgs::ImuConstPtr& imu) {
  if (gravity_.ready()) return;
  if (imu_frame_.empty()) imu_frame_ = imu->header.frame_id;
  const auto& a = imu->linear_acceleration;
  gravity_.add(Eigen::Vector3d(a.x, a.y, a.z));
}

std::optional<Eigen::Vector3d> TrackingNode::imu_up(const std::string& body, const ros::Time& stamp,
                                                    std::string* error) const {
  const auto up_imu = gravity_.up();
  if (!up_imu) {
    if (error) *error = "the accelerometer gave no direction";
    return std::nullopt;
  }
  const std::string frame = imu_frame_.empty() ? body : imu_frame_;
  const auto T_body_imu = camera_tf_->frame_to_camera(body, frame, stamp, error);
  if (!T_body_imu) return std::nullopt;
  return T_body_imu->rotation() * *up_imu;
}

bool TrackingNode::decide_levelling(const std::string& camera_frame, const ros::Time& stamp, const DepthImage& depth,
                                    std::string* why) {
  using tracking::MapLevel;
  const auto body = camera_tf_->anchor_frame(camera_frame, stamp, why);
  if (!body) return false;
  const auto T_body_cam = camera_tf_->frame_to_camera(*body, camera_frame, stamp, why);
  if (!T_body_cam) return false;
  if (level_wait_start_.isZero()) level_wait_start_ = stamp;
  const bool timed_out = (stamp - level_wait_start_).toSec() >= p_.level_timeout;
  const bool imu_expected =
      level_ == MapLevel::kImu || (level_ == MapLevel::kAuto && imu_sub_.getNumPublishers() > 0);

  std::optional<Eigen::Vector3d> up_b;
  std::string source = "nothing (map_level none)";
  std::string error;
  if (level_ != MapLevel::kNone && imu_expected) {
    if (gravity_.ready()) {
      up_b = imu_up(*body, stamp, &error);
      double g = 0.0;
      gravity_.up(&g);
      source = "the accelerometer (" + std::to_string(gravity_.count()) + " samples, " + std::to_string(g) + " m/s^2)";
      if (up_b && std::abs(g - 9.81) > 1.0) ROS_WARN("tracking: the accelerometer's mean is %.2f m/s^2, not 9.81: was the camera moving?", g);
    } else if (level_ == MapLevel::kImu || (stamp - level_wait_start_).toSec() < p_.imu_wait) {
      error = "waiting for accelerometer samples on " + imu_sub_.getTopic() + " (" + std::to_string(gravity_.count()) +
              " of " + std::to_string(p_.imu_samples) + ")";
    }
  }
  const bool floor_allowed = level_ == MapLevel::kFloor || (level_ == MapLevel::kAuto && !up_b && error.empty()) ||
                             (level_ == MapLevel::kAuto && !up_b && imu_expected && !gravity_.ready() &&
                              (stamp - level_wait_start_).toSec() >= p_.imu_wait);
  if (!up_b && floor_allowed) {
    // Where the camera has a body frame above it (REP-103: z up), its z is the guess for up; a bare
    // optical frame looks roughly level: up is its -y.
    const Eigen::Vector3d expected_up_c = *body == camera_frame ? Eigen::Vector3d(0, -1, 0)
                                                                : T_body_cam->inverse().rotation() * Eigen::Vector3d::UnitZ();
    tracking::FloorParams fp;
    fp.max_tilt_deg = p_.floor_max_tilt_deg;
    error.clear();
    const auto floor = tracking::find_floor(undistorter_->camera(), depth, expected_up_c, fp, &error);
    if (floor) {
      up_b = T_body_cam->rotation() * floor->up_c;
      source = "the floor (" + std::to_string(floor->inliers) + " of " + std::to_string(floor->points) +
               " depth points, camera " + std::to_string(floor->height) + " m above it)";
    } else {
      error = "no floor in the first frames' depth: " + error;
    }
  }
  if (!up_b && level_ != MapLevel::kNone) {
    if (!timed_out) {
      *why = error;
      return false;
    }
    ROS_WARN("tracking: the map is not levelled (%s for %.1f s, level_timeout): its z is %s's", error.c_str(),
             p_.level_timeout, body->c_str());
    source = "nothing";
  }
  R_map_body_ = up_b ? tracking::level_rotation(*up_b) : Eigen::Matrix3d::Identity();
  T_body_cam_ = *T_body_cam;
  const double tilt = up_b ? std::acos(std::clamp(up_b->normalized().z(), -1.0, 1.0)) * 180.0 / M_PI : 0.0;
  ROS_INFO("tracking: map anchored at the first pose of %s, levelled by %s: %.1f degrees of tilt taken out",
           body->c_str(), source.c_str(), tilt);
  return true;
}

// Says which input is missing when frames stop coming (no camera_info yet, no depth, a wrong
// topic name): the synchroniser alone would stay silent.
void TrackingNode::check_inputs(const ros::WallTimerEvent&) {
  // Bundle adjustment runs on after the last frame (the end of a bag): its corrections go out here.
  if (!last_stamp_.isZero()) publish_corrections(last_stamp_);
  const ros::WallTime now = ros::WallTime::now();
  auto recent = [&](const ros::WallTime& t) { return !t.isZero() && (now - t).toSec() < 3.0; };
  const bool any = recent(last_rgb_) || recent(last_depth_) || recent(last_info_);
  if (!any) {
    warn_no_input(now);
    return;
  }
  if (recent(last_frame_)) return;
  std::string missing;
  if (!recent(last_rgb_)) missing += " colour (" + rgb_sub_.getTopic() + ")";
  if (!recent(last_depth_)) missing += " depth (" + depth_sub_.getTopic() + ")";
  if (!recent(last_info_)) missing += " camera_info (" + info_sub_.getTopic() + ")";
  if (missing.empty()) missing = " none, but their stamps do not pair up (further apart than sync_slop, or out of order)";
  if (!throttled("sync")) ROS_WARN("tracking: inputs arrive but no synchronised frame; missing:%s", missing.c_str());
}

// Nothing at all arrives (no camera driver, topics under other names, a bag that ended): the
// synchroniser is silent and the state stays what it was (not_initialised before the first frame),
// so say it in the log and as a WARN on /diagnostics, where a robot's monitor looks.
void TrackingNode::warn_no_input(const ros::WallTime& now) {
  const bool clock_stopped_now = clock_.stopped();
  if (p_.no_input_warn <= 0.0) return;
  const ros::WallTime last = std::max({last_rgb_, last_depth_, last_info_, started_});
  const double quiet = (now - last).toSec();
  if (quiet < p_.no_input_warn) return;
  const std::string topics = rgb_sub_.getTopic() + ", " + depth_sub_.getTopic() + ", " + info_sub_.getTopic();
  const bool never = last_rgb_.isZero() && last_depth_.isZero() && last_info_.isZero();
  // A bag that ended (or is paused) stops the clock with its images: say that once, not a WARN a
  // minute for as long as mapping goes on after it.
  const bool clock_stopped = !never && clock_stopped_now;
  char text[512];
  std::snprintf(text, sizeof(text), "no images for %.0f s%s on %s%s", quiet, never ? " (none yet)" : "",
                topics.c_str(), clock_stopped ? " (the clock stopped too: a bag that ended or is paused)" : "");
  if (clock_stopped) {
    if (!bag_end_said_) ROS_INFO("tracking: %s", text);
    bag_end_said_ = true;
  } else if (!throttled("no_input", 60.0)) {
    ROS_WARN("tracking: %s: is the camera driver running (rostopic hz %s)?", text, rgb_sub_.getTopic().c_str());
  }
  diagnostic_msgs::DiagnosticStatus status;
  status.name = "dqo_map: tracking";
  status.hardware_id = "dqo_map";
  status.level = diagnostic_msgs::DiagnosticStatus::WARN;
  status.message = text;
  diagnostic_msgs::KeyValue kv;
  kv.key = "seconds_without_input";
  kv.value = std::to_string(quiet);
  status.values.push_back(kv);
  diagnostic_msgs::DiagnosticArray array;
  array.header.stamp = ros::Time::now();
  array.status.push_back(status);
  diag_pub_.publish(array);
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
  // Without depth nothing can start (the map's levelling, the tracker's first frame, a keyframe
  // from tf poses); once tracking, the tracker takes the frame and says what it makes of it
  // (degraded on colour alone, or lost: a covered lens), so that the state changes at once.
  const size_t valid = count_valid_depth(depth);
  if (static_cast<double>(valid) < p_.min_valid_depth * depth.data.size() || valid == 0) {
    const bool tracking = p_.pose_source == "tracker" && R_map_body_ &&
                          session_->state() != TrackingState::kNotInitialised;
    if (!throttled("depth")) ROS_WARN("tracking: only %zu of %zu pixels have depth (0, NaN or missing): %s", valid,
                                      depth.data.size(), tracking ? "tracked without it" : "frame skipped");
    if (!tracking) return;
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
    if (!R_map_body_ && !decide_levelling(camera_frame, stamp, depth, &error)) {
      if (!throttled("level", 2.0)) ROS_INFO("tracking: map not anchored yet (%s): frame skipped", error.c_str());
      return;
    }
    // Both stamps: a camera that does not capture colour and depth together (Kinect v1 through
    // openni) is tracked on the colour's instant (PoseOptimiserParams::max_depth_gap_s).
    const tracking::RgbdInput input{stamp.toSec(), &rgb, &depth, depth_msg->header.stamp.toSec()};
    r = session_->track(undistorter_->camera(), input);
  }
  if (r.skipped == tracking::SessionResult::Skip::kOutOfOrder) {
    if (!throttled("order")) ROS_WARN("tracking: frame at %.6f is out of order (%.3f s before the last one, "
                                      "within stream/out_of_order_s): skipped", stamp.toSec(), r.time_jump);
    return;
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
    kf.pose = to_pose_msg(to_map(r.track.T_wc));
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
  // Before this frame's keyframe goes out: mapping and association see the new map first.
  if (map_identity_->update(r)) {
    std_msgs::String id;
    id.data = map_identity_->id();
    map_id_pub_.publish(id);
    ROS_WARN("tracking: a new map '%s' (%s): the old map's poses cannot be related to the new ones; mapping and "
             "association keep it apart and start empty", id.data.c_str(),
             r.reset ? "time went back" : "the camera changed");
  }
  if (r.reset) {
    ROS_WARN("tracking: time went back by %.3f s (a looping bag?): tracker and keyframe selection "
             "restarted, path cleared", r.time_jump);
    path_.poses.clear();
    last_path_stamp_ = ros::Time();
    camera_tf_->reset();
    tf_listener_->clear_if_ahead_of(stamp);
    // The state went through not_initialised, even if the new run is tracking already.
    publish_state(TrackingState::kNotInitialised);
  }
  if (r.new_camera && frames_ > 1) ROS_WARN("tracking: the camera changed: tracking restarted");
  // A new tracker run (after a reset or for a new camera) has a frame of its own: it is anchored
  // anew at its first tracked frame, with the same levelling.
  if ((r.reset || r.new_camera) && p_.pose_source == "tracker") T_map_tracker_.reset();
  if (r.track.state == TrackingState::kOk && !T_map_tracker_) {
    T_map_tracker_ = SE3::from_rotation_translation(*R_map_body_, Eigen::Vector3d::Zero()) * T_body_cam_ *
                     r.track.T_wc.inverse();
  }
  if (r.state_changed) {
    switch (r.track.state) {
      case TrackingState::kOk:
        if (r.previous_state == TrackingState::kLost) {
          ROS_INFO("tracking: relocalised at %.3f after %llu frames lost", stamp.toSec(),
                   static_cast<unsigned long long>(frames_ - lost_since_frame_));
        } else if (r.previous_state == TrackingState::kDegraded) {
          ROS_INFO("tracking: ok again at %.3f", stamp.toSec());
        } else {
          if (p_.pose_source == "tf") {
            ROS_INFO("tracking: first camera pose from tf at %.3f", stamp.toSec());
          } else {
            ROS_INFO("tracking: initialised at %.3f (%d features)", stamp.toSec(), r.track.features);
          }
        }
        break;
      case TrackingState::kDegraded:
        ROS_WARN("tracking: degraded at %.3f: %s (%d inliers)", stamp.toSec(),
                 tracking::reasons_to_string(r.track.quality.reasons).c_str(), r.track.quality.inliers);
        break;
      case TrackingState::kLost:
        lost_since_frame_ = frames_;
        ROS_WARN("tracking: lost at %.3f: %s (%d features, %d inliers)", stamp.toSec(),
                 tracking::reasons_to_string(r.track.quality.reasons).c_str(), r.track.features,
                 r.track.quality.inliers);
        break;
      case TrackingState::kNotInitialised:
        ROS_INFO("tracking: waiting for a frame with enough depth to initialise");
        break;
    }
  }
  publish_state(r.track.state);
  ++frames_per_state_[tracking::to_string(r.track.state)];
  publish_diagnostics(r, stamp);

  if (p_.pose_source == "tracker") {
    recent_ms_.push_back(r.track.milliseconds);
    if (recent_ms_.size() > 300) recent_ms_.pop_front();
    std::vector<double> sorted(recent_ms_.begin(), recent_ms_.end());
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    if (!throttled("stats", 30.0)) ROS_INFO("tracking: %llu frames, %llu keyframes, %.1f ms per frame (median of the last %zu)",
                      static_cast<unsigned long long>(frames_), static_cast<unsigned long long>(session_->keyframes()),
                      sorted[sorted.size() / 2], sorted.size());
  }
  if (!tracking::has_pose(r.track.state)) return;

  if (p_.publish_tf && p_.pose_source == "tracker") {
    std::string error;
    const auto edge = camera_tf_->edge(camera_frame, stamp, to_map(r.track.T_wc), &error);
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
  pose.pose = to_pose_msg(to_map(r.track.T_wc));
  path_.poses.push_back(pose);
  if (p_.path_max_poses > 0 && static_cast<int>(path_.poses.size()) > p_.path_max_poses) {
    path_.poses.erase(path_.poses.begin(), path_.poses.begin() + (path_.poses.size() - p_.path_max_poses));
  }
  // Latched: published whether or not anyone listens now, so that rviz started later shows it.
  if (last_path_stamp_.isZero() || (stamp - last_path_stamp_).toSec() >= p_.path_period || r.keyframe_id) {
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
    msg.poses.push_back(to_pose_msg(to_map(c.T_wc)));
  }
  poses_pub_.publish(msg);
}

void TrackingNode::publish_diagnostics(const tracking::SessionResult& r, const ros::Time& stamp) {
  // Once a second, and at once when the state or the object landmarks change.
  const ros::WallTime now = ros::WallTime::now();
  if (!r.state_changed && !objects_changed_ && !last_diag_.isZero() && (now - last_diag_).toSec() < 1.0) return;
  last_diag_ = now;
  objects_changed_ = false;
  const tracking::TrackQuality& q = r.track.quality;
  diagnostic_msgs::DiagnosticStatus status;
  status.name = "dqo_map: tracking";
  status.hardware_id = "dqo_map";
  switch (r.track.state) {
    case TrackingState::kOk:
      status.level = diagnostic_msgs::DiagnosticStatus::OK;
      break;
    case TrackingState::kDegraded:
    case TrackingState::kNotInitialised:
      status.level = diagnostic_msgs::DiagnosticStatus::WARN;
      break;
    case TrackingState::kLost:
      status.level = diagnostic_msgs::DiagnosticStatus::ERROR;
      break;
  }
  const std::string reasons = tracking::reasons_to_string(q.reasons);
  status.message = std::string(tracking::to_string(r.track.state)) + (reasons.empty() ? "" : ": " + reasons);
  auto add = [&status](const std::string& key, const std::string& value) {
    diagnostic_msgs::KeyValue kv;
    kv.key = key;
    kv.value = value;
    status.values.push_back(kv);
  };
  add("state", tracking::to_string(r.track.state));
  add("reasons", reasons);
  add("inliers", std::to_string(q.inliers));
  add("inlier_spread", std::to_string(q.spread));
  add("dense_ok", q.dense_tried ? (q.dense_ok ? "true" : "false") : "not run");
  add("dense_whitened_rms", std::to_string(q.dense_rms));
  add("dense_inlier_ratio", std::to_string(q.dense_inlier_ratio));
  add("features_dense_disagreement_m", std::to_string(q.disagreement_m));
  add("features_dense_disagreement_deg", std::to_string(q.disagreement_deg));
  add("milliseconds", std::to_string(r.track.milliseconds));
  add("map_id", map_identity_->id());
  if (objects_sub_) {
    add("object_landmarks", std::to_string(object_landmarks_));
    add("object_sightings", std::to_string(object_sightings_));
  }
  for (const auto& [state, n] : frames_per_state_) add("frames_" + state, std::to_string(n));
  diagnostic_msgs::DiagnosticArray array;
  array.header.stamp = stamp;
  array.status.push_back(status);
  diag_pub_.publish(array);
}

void TrackingNode::on_objects(const dqo_map::ObjectArrayConstPtr& msg) {
  if (!T_map_tracker_) return;  // no tracker frame in the map yet: these are not this map's objects
  if (!msg->header.frame_id.empty() && msg->header.frame_id != p_.tf.map_frame) {
    if (!throttled("objects_frame")) {
      ROS_WARN("tracking: objects in frame '%s', not the map '%s': ignored", msg->header.frame_id.c_str(),
               p_.tf.map_frame.c_str());
    }
    return;
  }
  const SE3 T_tracker_map = T_map_tracker_->inverse();
  std::vector<tracking::ObjectLandmark> landmarks;
  landmarks.reserve(msg->objects.size());
  for (const dqo_map::Object& o : msg->objects) {
    const SE3 T_map_object = from_pose_msg(o.pose);
    const Eigen::Vector3d axes(o.semi_axes.x, o.semi_axes.y, o.semi_axes.z);
    if (!(axes.minCoeff() > 0.0) || !axes.allFinite()) continue;
    tracking::ObjectLandmark l;
    l.id = o.id;
    l.quadric = DualQuadric::from_params(T_map_object.translation(), T_map_object.rotation(), axes)
                    .transformed(T_tracker_map);
    l.confirmed = true;  // the topic carries the confirmed objects only
    l.confidence = o.confidence;
    l.observations = static_cast<int>(o.observations);
    landmarks.push_back(l);
  }
  object_landmarks_ = landmarks.size();
  objects_changed_ = true;
  session_->set_object_landmarks(landmarks);
}

void TrackingNode::on_keyframe_objects(const dqo_map::KeyFrameObjectsConstPtr& msg) {
  const auto& detections = msg->detections.detections;
  std::vector<tracking::ObjectSighting> sightings;
  for (size_t i = 0; i < detections.size() && i < msg->object_ids.size(); ++i) {
    if (msg->object_ids[i] == 0) continue;
    const auto& d = detections[i];
    sightings.push_back({msg->object_ids[i], Box2d{d.x_min, d.y_min, d.x_max, d.y_max}, d.score});
  }
  object_sightings_ += sightings.size();
  objects_changed_ = true;
  session_->add_object_sightings(msg->keyframe_id, sightings);
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
