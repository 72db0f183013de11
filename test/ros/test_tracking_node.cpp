// rostest of tracking_node (test/ros/tracking.test): renders a synthetic bag with dqo_make_scene
// (tabletop, 40 frames, every 3rd: sensor noise on, 3.6 degrees between frames), plays it into the
// node frame by frame (each frame waits for the node's tf of that stamp, so nothing is dropped on a
// slow machine), and checks:
//   - the map is z up: the bag's camera looks down at the table (its body frame, camera_base, is
//     pitched about 21 degrees) and the test rolls camera_base a further 15 degrees (through the
//     static tf), yet the map's z agrees with the ground truth's up and its x with camera_base's
//     first heading, within 2 degrees (levelled by the floor: the bag has no imu);
//   - keyframes arrive, stamped with their images' stamps, with rectified pinhole images and poses
//     within 2 cm of the ground truth (after aligning the first keyframe);
//   - tf: every frame has a single parent, the node attached map to the root of the camera's tree
//     (camera_base), and map -> rgb_camera_link through tf equals the keyframe poses;
//   - the map_id (latched) is this run's; the path is latched (a late subscriber gets it);
//   - bad input leaves the node running: an unknown encoding is skipped with a log line (and no
//     tf); a depth image of NaNs, once tracking, is tracked without depth with a log line and
//     reported degraded or lost at once, not ok (tracking_faults.test: longer faults, with ground
//     truth); the bag replayed without --clock (image time goes back, ROS
//     time does not) resets it: tracking_state goes through not_initialised, keyframes keep coming
//     with IDs that are never reused, and no TF_REPEATED_DATA reaches the node's log.
// Waits (seconds, each with its own failure message), against tracking.test's time-limit of 300:
// connect 30 + bag 90 + map_id 5 + path 10 + bad input 2 x 15 + replay 40 + state 10 + probe 15
// = 230, plus rendering the bag.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <mutex>
#include <set>

#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>
#include <rosgraph_msgs/Log.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <nav_msgs/Path.h>
#include <diagnostic_msgs/DiagnosticArray.h>
#include <std_msgs/String.h>
#include <tf2/buffer_core.h>
#include <tf2_msgs/TFMessage.h>

#include <dqo_map/KeyFrame.h>
#include <dqo_map/KeyFrameObjects.h>
#include <dqo_map/ObjectArray.h>

#include "dqo_map/common/tum_trajectory.h"
#include "ros_test_poses.h"
#include "ros_test_util.h"

namespace {

namespace fs = std::filesystem;
using dqo::ros_test::Capture;
using dqo::ros_test::wait_for;

using dqo::ros_test::angle_deg;
using dqo::ros_test::to_se3;

// What the test hears from the node (callbacks run on an AsyncSpinner's thread).
struct Recorder {
  std::mutex mutex;
  std::vector<dqo_map::KeyFrame> keyframes;
  std::vector<geometry_msgs::TransformStamped> transforms;  // /tf and /tf_static, in order
  std::map<std::string, std::set<std::string>> parents;     // child -> every parent seen
  std::set<double> tf_stamps;                               // stamps of map -> * edges
  dqo::ros_test::RosoutLog log{"tracking"};
  std::vector<std::string> states;  // every tracking_state, in order
  std::vector<diagnostic_msgs::DiagnosticStatus> diagnostics;  // the tracking node's, in order
  std::string map_id;
  std::vector<nav_msgs::Path> paths;

  void on_keyframe(const dqo_map::KeyFrame::ConstPtr& kf) {
    std::lock_guard<std::mutex> lock(mutex);
    keyframes.push_back(*kf);
  }
  void on_tf(const tf2_msgs::TFMessage::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex);
    for (const auto& t : msg->transforms) {
      transforms.push_back(t);
      parents[t.child_frame_id].insert(t.header.frame_id);
      if (t.header.frame_id == "map") tf_stamps.insert(t.header.stamp.toSec());
    }
  }
  void on_log(const rosgraph_msgs::Log::ConstPtr& line) { log.on_log(*line); }
  void on_state(const std_msgs::String::ConstPtr& s) {
    std::lock_guard<std::mutex> lock(mutex);
    states.push_back(s->data);
  }
  void on_diagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& a) {
    std::lock_guard<std::mutex> lock(mutex);
    for (const auto& status : a->status)
      if (status.name == "dqo_map: tracking") diagnostics.push_back(status);
  }
  void on_map_id(const std_msgs::String::ConstPtr& s) {
    std::lock_guard<std::mutex> lock(mutex);
    map_id = s->data;
  }
  void on_path(const nav_msgs::Path::ConstPtr& p) {
    std::lock_guard<std::mutex> lock(mutex);
    paths.push_back(*p);
  }
  bool saw_tf_at(const ros::Time& t) {
    std::lock_guard<std::mutex> lock(mutex);
    return tf_stamps.count(t.toSec()) > 0;
  }
  size_t num_keyframes() {
    std::lock_guard<std::mutex> lock(mutex);
    return keyframes.size();
  }
  bool logged(const std::string& needle) const { return log.logged(needle); }
};

class TrackingNodeTest : public dqo::ros_test::RenderedBagTest<TrackingNodeTest> {
 public:
  static constexpr const char* kDirPrefix = "dqo_tracking_test_";
  static constexpr int kFrames = 40;
  static constexpr int kEvery = 3;

 protected:
  void SetUp() override {
    ASSERT_NO_FATAL_FAILURE(load_bag());
    // Roll camera_base about the colour camera's optical axis (the camera's own pose, the ground
    // truth, stays): the body frame the map is anchored at is then pitched and rolled.
    for (auto& t : tf_static_.transforms) {
      if (t.child_frame_id != "rgb_camera_link") continue;
      const dqo::SE3 roll(Eigen::Quaterniond(Eigen::AngleAxisd(kRollDeg * M_PI / 180.0, Eigen::Vector3d::UnitZ())),
                          Eigen::Vector3d::Zero());
      const dqo::SE3 T_base_cam = to_se3(t.transform) * roll;
      t.transform.rotation.w = T_base_cam.quaternion().w();
      t.transform.rotation.x = T_base_cam.quaternion().x();
      t.transform.rotation.y = T_base_cam.quaternion().y();
      t.transform.rotation.z = T_base_cam.quaternion().z();
      T_base_cam_ = T_base_cam;
      rolled_ = true;
    }
    ASSERT_TRUE(rolled_) << "the bag has no static camera_base -> rgb_camera_link";
    std::string error;
    const auto gt = dqo::read_tum_trajectory((dir_ / "data" / "groundtruth.txt").string(), &error);
    ASSERT_TRUE(gt) << error;
    ASSERT_EQ(gt->size(), captures_.size());
    // The bag's stamps are the dataset's timestamps plus a start offset.
    const double offset = captures_.front().stamp.toSec() - gt->front().first;
    for (const auto& [t, T] : *gt) gt_[std::lround((t + offset) * 1e6)] = T;

    ros::NodeHandle nh;
    keyframe_sub_ = nh.subscribe("/dqo_map/keyframes", 100, &Recorder::on_keyframe, &rec_);
    tf_sub_ = nh.subscribe("/tf", 1000, &Recorder::on_tf, &rec_);
    tf_static_sub_ = nh.subscribe("/tf_static", 100, &Recorder::on_tf, &rec_);
    log_sub_ = nh.subscribe("/rosout", 1000, &Recorder::on_log, &rec_);
    state_sub_ = nh.subscribe("/dqo_map/tracking_state", 100, &Recorder::on_state, &rec_);
    diag_sub_ = nh.subscribe("/diagnostics", 100, &Recorder::on_diagnostics, &rec_);
    map_id_sub_ = nh.subscribe("/dqo_map/map_id", 10, &Recorder::on_map_id, &rec_);
    clock_pub_ = nh.advertise<rosgraph_msgs::Clock>("/clock", 10, true);
    tf_static_pub_ = nh.advertise<tf2_msgs::TFMessage>("/tf_static", 10, true);
    rgb_pub_ = nh.advertise<sensor_msgs::Image>("/rgb/image_raw", 10);
    depth_pub_ = nh.advertise<sensor_msgs::Image>("/depth_to_rgb/image_raw", 10);
    info_pub_ = nh.advertise<sensor_msgs::CameraInfo>("/rgb/camera_info", 10);
    objects_pub_ = nh.advertise<dqo_map::ObjectArray>("/dqo_map/objects", 1, true);
    kf_objects_pub_ = nh.advertise<dqo_map::KeyFrameObjects>("/dqo_map/keyframe_objects", 10);
    spinner_ = std::make_unique<ros::AsyncSpinner>(2);
    spinner_->start();
    ASSERT_TRUE(wait_for(
        [&] {
          return rgb_pub_.getNumSubscribers() > 0 && depth_pub_.getNumSubscribers() > 0 &&
                 info_pub_.getNumSubscribers() > 0 && keyframe_sub_.getNumPublishers() > 0 &&
                 tf_sub_.getNumPublishers() > 0 && log_sub_.getNumPublishers() > 0;
        },
        30.0))
        << "tracking_node did not connect";
  }

  void TearDown() override {
    if (spinner_) spinner_->stop();
  }

  void set_clock(const ros::Time& t) { dqo::ros_test::set_clock(clock_pub_, t); }

  // Publishes one capture as the bag holds it (the static tf first, as `rosbag play` does at the
  // bag's start) and waits for the node's map edge of that stamp.
  bool play(const Capture& c, bool with_static, double wait_s = 5.0) {
    set_clock(c.stamp);
    if (with_static) dqo::ros_test::publish_tf_static(tf_static_pub_, tf_static_, c.stamp);
    dqo::ros_test::publish_camera(c, info_pub_, depth_pub_, rgb_pub_);
    return wait_for([&] { return rec_.saw_tf_at(c.stamp); }, wait_s);
  }

  // Publishes a capture without /clock (as `rosbag play` without --clock: ROS time goes on while
  // image time jumps back) and waits for the node's map edge of that stamp.
  bool play_at(const Capture& c, const ros::Time& clock, double wait_s) {
    set_clock(clock);
    dqo::ros_test::publish_camera(c, info_pub_, depth_pub_, rgb_pub_);
    return wait_for([&] { return rec_.saw_tf_at(c.stamp); }, wait_s);
  }

  const dqo::SE3* gt_at(const ros::Time& t) const {
    auto it = gt_.find(std::lround(t.toSec() * 1e6));
    return it == gt_.end() ? nullptr : &it->second;
  }

  static constexpr double kRollDeg = 15.0;
  bool rolled_ = false;
  dqo::SE3 T_base_cam_;  // the (rolled) static camera_base -> rgb_camera_link
  std::map<long, dqo::SE3> gt_;  // ground truth by bag stamp in microseconds
  Recorder rec_;
  std::unique_ptr<ros::AsyncSpinner> spinner_;
  ros::Subscriber keyframe_sub_, tf_sub_, tf_static_sub_, log_sub_, state_sub_, map_id_sub_, diag_sub_;
  ros::Publisher clock_pub_, tf_static_pub_, rgb_pub_, depth_pub_, info_pub_;
  ros::Publisher objects_pub_, kf_objects_pub_;  // as association_node publishes them
};


TEST_F(TrackingNodeTest, KeyframesTfAndBadInput) {
  // ---- the bag, in order (each frame waits for its tf; 90 s for the whole bag)
  int tracked = 0;
  dqo::ros_test::Budget bag(90.0);
  for (size_t i = 0; i < captures_.size(); ++i) {
    if (bag.expired()) {
      ADD_FAILURE() << "the bag's " << bag.seconds() << " s ran out at frame " << i << " of " << captures_.size();
      break;
    }
    tracked += play(captures_[i], i == 0, bag.take(5.0)) ? 1 : 0;
    // Objects as landmarks (tracking.test enables them): association_node's topics, once the
    // tracker is in the map. Three objects, one without a valid ellipsoid (dropped); then one
    // keyframe's detections, one of them rejected (object 0).
    if (i == 10) {
      dqo_map::ObjectArray objects;
      objects.header.frame_id = "map";
      objects.header.stamp = captures_[i].stamp;
      for (int k = 0; k < 3; ++k) {
        dqo_map::Object o;
        o.id = 7 + k;
        o.pose.orientation.w = 1.0;
        o.pose.position.x = 0.3 * k;
        o.pose.position.z = 0.5;
        o.semi_axes.x = o.semi_axes.y = o.semi_axes.z = k == 2 ? 0.0 : 0.1;
        o.observations = 5;
        o.confidence = 0.9f;
        objects.objects.push_back(o);
      }
      EXPECT_GT(objects_pub_.getNumSubscribers(), 0u) << "tracking_node does not take objects";
      objects_pub_.publish(objects);
    } else if (i == 12) {
      dqo_map::KeyFrameObjects kfo;
      kfo.header.stamp = captures_[i].stamp;
      {
        std::lock_guard<std::mutex> lock(rec_.mutex);
        kfo.keyframe_id = rec_.keyframes.empty() ? 1 : rec_.keyframes.front().id;
      }
      dqo_map::Detection d;
      d.x_min = 100;
      d.y_min = 100;
      d.x_max = 200;
      d.y_max = 180;
      d.score = 0.8f;
      kfo.detections.detections = {d, d};
      kfo.object_ids = {7, 0};
      kf_objects_pub_.publish(kfo);
    }
  }
  EXPECT_GE(tracked, 38) << "frames the node published tf for";
  {
    // The tracker got the two valid objects and the one associated detection (its /diagnostics).
    std::lock_guard<std::mutex> lock(rec_.mutex);
    bool landmarks = false, sightings = false;
    for (const auto& status : rec_.diagnostics) {
      for (const auto& kv : status.values) {
        landmarks = landmarks || (kv.key == "object_landmarks" && kv.value == "2");
        sightings = sightings || (kv.key == "object_sightings" && kv.value == "1");
      }
    }
    EXPECT_TRUE(landmarks) << "no tracking status reported the 2 object landmarks";
    EXPECT_TRUE(sightings) << "no tracking status reported the 1 object sighting";
  }
  // The last frame's keyframe (if it is one) may arrive after its tf: the frames' stamps say which
  // keyframes to read, so nothing below depends on that order.

  std::vector<dqo_map::KeyFrame> keyframes;
  {
    std::lock_guard<std::mutex> lock(rec_.mutex);
    keyframes = rec_.keyframes;
    ASSERT_FALSE(rec_.states.empty()) << "no tracking_state";
    EXPECT_EQ(rec_.states.back(), "ok");  // tracking::to_string(TrackingState::kOk)
    // The state and its evidence on /diagnostics: the first status is sent at once.
    ASSERT_FALSE(rec_.diagnostics.empty()) << "no tracking status on /diagnostics";
    std::map<std::string, std::string> values;
    for (const auto& kv : rec_.diagnostics.back().values) values[kv.key] = kv.value;
    EXPECT_EQ(values["state"], "ok");
    EXPECT_EQ(rec_.diagnostics.back().level, diagnostic_msgs::DiagnosticStatus::OK);
    EXPECT_GE(std::stoi(values["frames_ok"]), 1);
    EXPECT_EQ(values.count("reasons"), 1u);
    EXPECT_EQ(values.count("features_dense_disagreement_m"), 1u);
  }
  ASSERT_GE(keyframes.size(), 5u);

  // ---- the map is z up and keeps camera_base's first heading
  {
    const dqo::SE3* gt_first = gt_at(keyframes.front().header.stamp);
    ASSERT_TRUE(gt_first);
    const Eigen::Matrix3d R_world_map = gt_first->rotation() * to_se3(keyframes.front().pose).rotation().transpose();
    const Eigen::Vector3d map_z = R_world_map * Eigen::Vector3d::UnitZ();
    const double up_deg = std::acos(std::min(1.0, map_z.z())) * 180.0 / M_PI;
    EXPECT_LT(up_deg, 2.0) << "the map's z is " << up_deg << " degrees from the ground truth's up";
    const Eigen::Vector3d body_x = gt_first->rotation() * T_base_cam_.rotation().transpose() * Eigen::Vector3d::UnitX();
    const Eigen::Vector3d heading = Eigen::Vector3d(body_x.x(), body_x.y(), 0.0).normalized();
    const double heading_deg = std::acos(std::min(1.0, heading.dot(R_world_map * Eigen::Vector3d::UnitX()))) * 180.0 / M_PI;
    EXPECT_LT(heading_deg, 2.0) << "the map's x is " << heading_deg << " degrees from camera_base's first heading";
    const Eigen::Vector3d body_z = gt_first->rotation() * T_base_cam_.rotation().transpose() * Eigen::Vector3d::UnitZ();
    std::printf("[ INFO     ] camera_base tilted %.1f deg from up; map z %.2f deg from up, x %.2f deg from its heading\n",
                std::acos(body_z.z()) * 180.0 / M_PI, up_deg, heading_deg);
  }
  // ---- map_id (latched): this tracker run's own
  EXPECT_TRUE(wait_for([&] { std::lock_guard<std::mutex> l(rec_.mutex); return !rec_.map_id.empty(); }, 5.0))
      << "no map_id";
  {
    std::lock_guard<std::mutex> l(rec_.mutex);
    EXPECT_EQ(rec_.map_id.rfind("tracker:map:", 0), 0u) << rec_.map_id;
  }

  std::set<double> image_stamps;
  for (const auto& c : captures_) image_stamps.insert(c.stamp.toSec());
  const dqo::SE3* gt0 = gt_at(keyframes.front().header.stamp);
  ASSERT_TRUE(gt0);
  const dqo::SE3 T_gt_map = *gt0 * to_se3(keyframes.front().pose).inverse();
  uint64_t last_id = 0;
  double worst_m = 0.0, worst_deg = 0.0;
  for (const auto& kf : keyframes) {
    EXPECT_EQ(kf.header.frame_id, "map");
    EXPECT_TRUE(image_stamps.count(kf.header.stamp.toSec())) << "keyframe stamp " << kf.header.stamp;
    EXPECT_EQ(kf.rgb.header.stamp, kf.header.stamp);
    EXPECT_EQ(kf.depth.header.stamp, kf.header.stamp);
    EXPECT_GT(kf.id, last_id);
    last_id = kf.id;
    EXPECT_EQ(kf.rgb.encoding, "rgb8");
    EXPECT_EQ(kf.depth.encoding, "32FC1");
    EXPECT_EQ(kf.rgb.width, 640u);
    EXPECT_EQ(kf.depth.height, 480u);
    EXPECT_EQ(kf.camera_info.width, 640u);
    for (double d : kf.camera_info.D) EXPECT_EQ(d, 0.0);
    EXPECT_EQ(kf.camera_info.K[0], captures_.front().info.K[0]);
    const dqo::SE3* gt = gt_at(kf.header.stamp);
    ASSERT_TRUE(gt);
    const dqo::SE3 delta = gt->inverse() * (T_gt_map * to_se3(kf.pose));
    worst_m = std::max(worst_m, delta.translation().norm());
    worst_deg = std::max(worst_deg, angle_deg(delta));
    EXPECT_LT(delta.translation().norm(), 0.02) << "keyframe " << kf.id << " at " << kf.header.stamp;
  }
  EXPECT_LT(worst_deg, 2.0);
  std::printf("[ INFO     ] %zu keyframes; worst position error %.4f m, rotation %.3f deg\n", keyframes.size(),
              worst_m, worst_deg);

  // ---- tf: one parent per frame, map above the driver's root, and map -> camera = keyframe pose
  {
    std::lock_guard<std::mutex> lock(rec_.mutex);
    for (const auto& [child, parents] : rec_.parents) {
      EXPECT_EQ(parents.size(), 1u) << child << " has " << parents.size() << " parents";
    }
    ASSERT_TRUE(rec_.parents.count("camera_base"));
    EXPECT_EQ(*rec_.parents["camera_base"].begin(), "map");
    EXPECT_EQ(*rec_.parents["rgb_camera_link"].begin(), "camera_base");
    tf2::BufferCore buffer(ros::Duration(1000.0));
    for (const auto& t : rec_.transforms) {
      buffer.setTransform(t, "test", t.header.frame_id == "camera_base" && t.child_frame_id == "rgb_camera_link");
    }
    for (const auto& kf : keyframes) {
      const auto tf = buffer.lookupTransform("map", "rgb_camera_link", kf.header.stamp);
      const dqo::SE3 delta = to_se3(tf.transform).inverse() * to_se3(kf.pose);
      EXPECT_LT(delta.translation().norm(), 1e-6);
      EXPECT_LT(angle_deg(delta), 1e-4);
    }
  }

  // ---- the path is latched: a subscriber that comes now gets it
  {
    ros::NodeHandle nh;
    ros::Subscriber path_sub = nh.subscribe("/dqo_map/path", 10, &Recorder::on_path, &rec_);
    EXPECT_TRUE(wait_for([&] { std::lock_guard<std::mutex> l(rec_.mutex); return !rec_.paths.empty(); }, 10.0))
        << "a late subscriber got no path: not latched";
    std::lock_guard<std::mutex> l(rec_.mutex);
    if (!rec_.paths.empty()) {
      const nav_msgs::Path& path = rec_.paths.back();
      EXPECT_EQ(path.header.frame_id, "map");
      ASSERT_FALSE(path.poses.empty());
      const auto& first = path.poses.front();
      EXPECT_EQ(first.header.stamp, keyframes.front().header.stamp);
      EXPECT_LT((to_se3(first.pose).translation() - to_se3(keyframes.front().pose).translation()).norm(), 1e-9);
    }
  }

  // ---- bad input: an unknown encoding (skipped, logged, no tf: checked once the frame after it is
  // handled, the node takes frames in order), depth of NaNs (logged, tracked without depth: not ok).
  Capture bad = dqo::ros_test::restamped(captures_.back(), captures_.back().stamp + ros::Duration(0.1));
  bad.rgb.encoding = "yuv422";
  play(bad, false, 0.0);
  EXPECT_TRUE(wait_for([&] { return rec_.logged("yuv422"); }, 15.0)) << "no log line naming the encoding";

  Capture nan_depth = dqo::ros_test::restamped(captures_.back(), bad.stamp + ros::Duration(0.1));
  nan_depth.depth.encoding = "32FC1";
  nan_depth.depth.step = nan_depth.depth.width * 4;
  nan_depth.depth.data.assign(static_cast<size_t>(nan_depth.depth.step) * nan_depth.depth.height, 0);
  for (size_t i = 0; i + 4 <= nan_depth.depth.data.size(); i += 4) {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    std::memcpy(&nan_depth.depth.data[i], &nan, 4);
  }
  play(nan_depth, false, 0.0);
  EXPECT_TRUE(wait_for([&] { return rec_.logged("have depth"); }, 15.0)) << "no log line about missing depth";
  EXPECT_TRUE(wait_for([&] {
    std::lock_guard<std::mutex> lock(rec_.mutex);
    return rec_.states.back() == "degraded" || rec_.states.back() == "lost";
  }, 15.0)) << "the frame without depth was not reported degraded or lost: " << rec_.log.dump();
  ros::WallDuration(0.2).sleep();  // a tf of the frame before would have come by now
  EXPECT_FALSE(rec_.saw_tf_at(bad.stamp)) << "a tf for the frame with an unknown encoding";

  // ---- the bag replayed without --clock: image time goes back, ROS time goes on. The node
  // restarts, its state passes through not_initialised, keyframes keep coming, and its tf listener
  // hears its own edges at the replayed stamps without TF_REPEATED_DATA. 40 s for the 6 frames.
  {
    std::lock_guard<std::mutex> lock(rec_.mutex);
    rec_.tf_stamps.clear();  // the replayed stamps were seen before: wait for new edges
  }
  const ros::Time clock0 = captures_.back().stamp + ros::Duration(10.0);
  dqo::ros_test::Budget replay(40.0);
  for (size_t i = 0; i < 6 && !replay.expired(); ++i) {
    EXPECT_TRUE(play_at(captures_[i], clock0 + ros::Duration(0.1 * i), replay.take(10.0))) << "frame " << i << " of the replay";
  }
  EXPECT_FALSE(replay.expired()) << "the replay's " << replay.seconds() << " s ran out";
  EXPECT_TRUE(rec_.logged("time went back")) << "no log line about the time jump";
  auto went_through_reset = [&] {
    std::lock_guard<std::mutex> lock(rec_.mutex);
    const auto ok = std::find(rec_.states.begin(), rec_.states.end(), "ok");
    const auto reset = std::find(ok, rec_.states.end(), "not_initialised");
    return reset != rec_.states.end() && std::find(reset, rec_.states.end(), "ok") != rec_.states.end();
  };
  EXPECT_TRUE(wait_for(went_through_reset, 10.0)) << "tracking_state did not go ok -> not_initialised -> ok through the reset";
  EXPECT_TRUE(wait_for([&] {
    std::lock_guard<std::mutex> lock(rec_.mutex);
    for (const auto& kf : rec_.keyframes) {
      if (kf.header.stamp == captures_[0].stamp && kf.id > last_id) return true;
    }
    return false;
  }, 5.0)) << "the first frame after the reset did not become a keyframe with a new ID";
  {
    std::lock_guard<std::mutex> lock(rec_.mutex);
    std::set<uint64_t> ids;
    for (const auto& kf : rec_.keyframes) EXPECT_TRUE(ids.insert(kf.id).second) << "keyframe ID " << kf.id << " reused";
    for (const auto& [child, parents] : rec_.parents) EXPECT_EQ(parents.size(), 1u) << child;
  }
  // A probe: a transform sent twice with one stamp must give TF_REPEATED_DATA in the node's log (so
  // that the check below can fail), and the node handles /tf in order, so once the probe's line is
  // there, every earlier edge has been handled.
  {
    ros::NodeHandle nh;
    ros::Publisher tf_pub = nh.advertise<tf2_msgs::TFMessage>("/tf", 10);
    // This test's own /tf subscriber and the node's listener.
    ASSERT_TRUE(wait_for([&] { return tf_pub.getNumSubscribers() >= 2; }, 5.0)) << "the node does not listen to /tf";
    tf2_msgs::TFMessage probe;
    probe.transforms.resize(1);
    probe.transforms[0].header.frame_id = "dqo_probe_parent";
    probe.transforms[0].child_frame_id = "dqo_probe";
    probe.transforms[0].header.stamp = captures_[5].stamp;
    probe.transforms[0].transform.rotation.w = 1.0;
    tf_pub.publish(probe);
    tf_pub.publish(probe);
    EXPECT_TRUE(wait_for([&] { return rec_.logged("TF_REPEATED_DATA"); }, 10.0))
        << "the probe's repeated transform left no TF_REPEATED_DATA in the node's log";
  }
  EXPECT_EQ(rec_.log.count("TF_REPEATED_DATA"), rec_.log.count("dqo_probe"))
      << "TF_REPEATED_DATA for the node's own transforms after the replay";
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_tracking_node");
  ros::NodeHandle nh;  // keeps the node alive for the whole run
  return RUN_ALL_TESTS();
}
