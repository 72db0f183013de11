#pragma once
// What the rostests of the nodes share: a synthetic bag rendered with dqo_make_scene and read back
// as one Capture per stamp, played into the nodes by hand (with /clock) so that each test can pace
// the bag on the nodes' outputs instead of on wall time, and the /rosout lines that bad input must
// leave. Header-only: each rostest is one executable, and these are a few lines each.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <rosgraph_msgs/Clock.h>
#include <rosgraph_msgs/Log.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <tf2_msgs/TFMessage.h>

#include <dqo_map/DetectionArray.h>

namespace dqo::ros_test {

// One frame of the bag: everything dqo_make_scene writes at one stamp. tf (ground truth
// map -> camera_base) is empty unless the bag was rendered with --gt-tf.
struct Capture {
  ros::Time stamp;
  sensor_msgs::Image rgb, depth;
  sensor_msgs::CameraInfo info;
  tf2_msgs::TFMessage tf;
  dqo_map::DetectionArray detections;
};

// The bag's frames in stamp order (topics are interleaved in the bag, so they are gathered by their
// headers' stamps), and its /tf_static in *tf_static.
inline std::vector<Capture> read_captures(const std::string& bag_path, tf2_msgs::TFMessage* tf_static) {
  rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
  std::map<ros::Time, Capture> by_stamp;
  for (const rosbag::MessageInstance& m : rosbag::View(bag)) {
    if (m.getTopic() == "/tf_static") {
      *tf_static = *m.instantiate<tf2_msgs::TFMessage>();
    } else if (m.getTopic() == "/tf") {
      auto tf = m.instantiate<tf2_msgs::TFMessage>();
      by_stamp[tf->transforms.at(0).header.stamp].tf = *tf;
    } else if (m.getTopic() == "/rgb/image_raw") {
      auto img = m.instantiate<sensor_msgs::Image>();
      by_stamp[img->header.stamp].rgb = *img;
      by_stamp[img->header.stamp].stamp = img->header.stamp;
    } else if (m.getTopic() == "/depth_to_rgb/image_raw") {
      auto img = m.instantiate<sensor_msgs::Image>();
      by_stamp[img->header.stamp].depth = *img;
    } else if (m.getTopic() == "/rgb/camera_info") {
      auto info = m.instantiate<sensor_msgs::CameraInfo>();
      by_stamp[info->header.stamp].info = *info;
    } else if (m.getTopic() == "/detections") {
      auto det = m.instantiate<dqo_map::DetectionArray>();
      by_stamp[det->header.stamp].detections = *det;
    }
  }
  std::vector<Capture> captures;
  for (auto& [stamp, c] : by_stamp) captures.push_back(c);
  return captures;
}

// `c` moved to stamp t, every header with it: a frame the bag does not hold, for bad input and for
// flushing the nodes' synchronisers.
inline Capture restamped(Capture c, const ros::Time& t) {
  c.stamp = t;
  for (auto& tf : c.tf.transforms) tf.header.stamp = t;
  c.rgb.header.stamp = c.depth.header.stamp = c.info.header.stamp = c.detections.header.stamp = t;
  return c;
}

// Polls rather than waits on a condition: what the tests wait for arrives through roscpp's
// callbacks on the spinner's threads, with nothing to notify. Returns pred() at the deadline.
template <typename Pred>
bool wait_for(Pred pred, double seconds) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(seconds);
  while (ros::ok() && ros::WallTime::now() < end) {
    if (pred()) return true;
    ros::WallDuration(0.005).sleep();
  }
  return pred();
}

// A share of a rostest's time limit for a run of waits (a bag played frame by frame): each wait
// takes at most what is left, so that a slow node fails the run with its own message instead of
// the whole test overrunning its time-limit. The bounds are summed next to the .test's time-limit.
class Budget {
 public:
  explicit Budget(double seconds) : end_(ros::WallTime::now() + ros::WallDuration(seconds)), seconds_(seconds) {}
  double left() const { return std::max(0.0, (end_ - ros::WallTime::now()).toSec()); }
  bool expired() const { return left() <= 0.0; }
  double take(double wanted) const { return std::min(wanted, left()); }
  double seconds() const { return seconds_; }

 private:
  ros::WallTime end_;
  double seconds_;
};

// The /rosout lines of the nodes whose name contains `node`: bad input must be skipped with a log
// line, and these are the test's only view of that. on_log runs on the spinner's threads, logged()
// on the test's: hence the lock.
class RosoutLog {
 public:
  explicit RosoutLog(std::string node) : node_(std::move(node)) {}

  void on_log(const rosgraph_msgs::Log& log) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (log.name.find(node_) != std::string::npos) lines_.push_back(log.msg);
  }
  bool logged(const std::string& needle) const { return count(needle) > 0; }
  size_t count(const std::string& needle) const {
    std::lock_guard<std::mutex> lock(mutex_);
    size_t n = 0;
    for (const auto& m : lines_) n += m.find(needle) != std::string::npos;
    return n;
  }
  // Everything the node said so far, one line each (for a failure message).
  std::string dump() const {
    std::lock_guard<std::mutex> lock(mutex_);
    std::string out;
    for (const auto& m : lines_) out += "  " + node_ + ": " + m + "\n";
    return out;
  }

 private:
  const std::string node_;
  mutable std::mutex mutex_;
  std::vector<std::string> lines_;
};

// A fresh folder for one test binary's files (mkdtemp: unique, also across hosts sharing /tmp and
// reruns with a recycled PID); the caller removes it.
inline std::filesystem::path make_test_dir(const std::string& prefix) {
  std::string pattern = (std::filesystem::temp_directory_path() / (prefix + "XXXXXX")).string();
  if (!mkdtemp(pattern.data())) return {};
  return pattern;
}

// A node the test starts and stops itself (to restart it with other parameters): fork + exec of
// the binary with ROS command-line arguments (remaps, __ns, _private:=value).
class NodeProcess {
 public:
  NodeProcess() = default;
  NodeProcess(const NodeProcess&) = delete;
  NodeProcess& operator=(const NodeProcess&) = delete;
  ~NodeProcess() { stop(5.0); }

  bool start(const std::string& binary, const std::vector<std::string>& args) {
    std::vector<char*> argv;
    std::vector<std::string> all = {binary};
    all.insert(all.end(), args.begin(), args.end());
    for (auto& a : all) argv.push_back(a.data());
    argv.push_back(nullptr);
    pid_ = fork();
    if (pid_ == 0) {
      execv(binary.c_str(), argv.data());
      _exit(127);
    }
    return pid_ > 0;
  }
  // SIGINT (roscpp shuts down cleanly), SIGKILL after `seconds`. Returns whether it exited in time.
  bool stop(double seconds) {
    if (pid_ <= 0) return true;
    kill(pid_, SIGINT);
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(seconds);
    int status = 0;
    while (ros::WallTime::now() < end) {
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        return true;
      }
      ros::WallDuration(0.02).sleep();
    }
    kill(pid_, SIGKILL);
    waitpid(pid_, &status, 0);
    pid_ = -1;
    return false;
  }
  bool running() {
    if (pid_ <= 0) return false;
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) pid_ = -1;
    return pid_ > 0;
  }

 private:
  pid_t pid_ = -1;
};

#if defined(DQO_MAKE_SCENE) && defined(DQO_SOURCE_DIR)
// Renders tabletop's first `frames` frames, every `every`-th, as dir/tabletop.bag (the dataset in
// dir/data, the tool's output in dir/make_scene.log); `flags` adds dqo_make_scene options (e.g.
// "--gt-tf"). Returns std::system's status. The two paths come from the test's target
// (test/ros/CMakeLists.txt), hence the guard: tests without a bag include this header too.
inline int render_tabletop_bag(const std::filesystem::path& dir, int frames, int every, const std::string& flags) {
  const std::string cmd = std::string(DQO_MAKE_SCENE) + " " + DQO_SOURCE_DIR + "/config/scenes/tabletop.yaml " +
                          (dir / "data").string() + " --bag " + (dir / "tabletop.bag").string() + " --frames " +
                          std::to_string(frames) + " --every " + std::to_string(every) +
                          (flags.empty() ? "" : " " + flags) + " --overwrite > " + (dir / "make_scene.log").string() +
                          " 2>&1";
  return std::system(cmd.c_str());
}

// A test suite over one tabletop bag, rendered once for all its tests (render_tabletop_bag) and
// read back in each test's SetUp (load_bag: ASSERT_NO_FATAL_FAILURE(load_bag())). CRTP: the suite
// gives kDirPrefix, kFrames and kEvery (every kEvery-th of the scene's frames); each suite then has
// its own folder and bag.
template <typename Suite>
class RenderedBagTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = make_test_dir(Suite::kDirPrefix);
    make_scene_rc_ = dir_.empty() ? -1 : render_tabletop_bag(dir_, Suite::kFrames, Suite::kEvery, "");
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  void load_bag() {
    ASSERT_EQ(make_scene_rc_, 0) << "dqo_make_scene failed; see " << (dir_ / "make_scene.log");
    captures_ = read_captures((dir_ / "tabletop.bag").string(), &tf_static_);
    ASSERT_EQ(captures_.size(), static_cast<size_t>(Suite::kFrames));
    ASSERT_FALSE(tf_static_.transforms.empty());
  }

  static inline std::filesystem::path dir_;
  static inline int make_scene_rc_ = -1;
  std::vector<Capture> captures_;
  tf2_msgs::TFMessage tf_static_;
};
#endif

// /clock, for nodes running on sim time (use_sim_time in the .test files).
inline void set_clock(const ros::Publisher& clock_pub, const ros::Time& t) {
  rosgraph_msgs::Clock c;
  c.clock = t;
  clock_pub.publish(c);
}

// The bag's static tf at stamp t, as `rosbag play` sends it at the bag's start. Latched, and the
// nodes do not depend on its arriving before the images (tracking_node waits root_wait for a tree).
inline void publish_tf_static(const ros::Publisher& tf_static_pub, tf2_msgs::TFMessage tf_static, const ros::Time& t) {
  for (auto& tf : tf_static.transforms) tf.header.stamp = t;
  tf_static_pub.publish(tf_static);
}

// A capture's camera topics (CameraInfo, depth, colour): one place, so that every test plays them
// in the same order.
inline void publish_camera(const Capture& c, const ros::Publisher& info_pub, const ros::Publisher& depth_pub,
                           const ros::Publisher& rgb_pub) {
  info_pub.publish(c.info);
  depth_pub.publish(c.depth);
  rgb_pub.publish(c.rgb);
}


// The publishers of what `rosbag play` of a dqo_make_scene bag sends, and one capture sent as the
// bag sends it (clock, the static tf with the first, tf, detections, camera): one place, so that
// every test plays captures alike.
struct CapturePublishers {
  ros::Publisher clock, tf_static, tf, rgb, depth, info, det;

  void advertise(ros::NodeHandle& nh, uint32_t detections_queue = 100) {
    clock = nh.advertise<rosgraph_msgs::Clock>("/clock", 10, true);
    tf_static = nh.advertise<tf2_msgs::TFMessage>("/tf_static", 10, true);
    tf = nh.advertise<tf2_msgs::TFMessage>("/tf", 100);
    rgb = nh.advertise<sensor_msgs::Image>("/rgb/image_raw", 10);
    depth = nh.advertise<sensor_msgs::Image>("/depth_to_rgb/image_raw", 10);
    info = nh.advertise<sensor_msgs::CameraInfo>("/rgb/camera_info", 10);
    det = nh.advertise<dqo_map::DetectionArray>("/detections", detections_queue);
  }
  // `tf_static`: the bag's static tf, sent first (the first capture); nullptr: not sent.
  void publish(const Capture& c, const tf2_msgs::TFMessage* static_tf) const {
    set_clock(clock, c.stamp);
    if (static_tf) publish_tf_static(tf_static, *static_tf, c.stamp);
    tf.publish(c.tf);
    det.publish(c.detections);
    publish_camera(c, info, depth, rgb);
  }
};

}  // namespace dqo::ros_test
