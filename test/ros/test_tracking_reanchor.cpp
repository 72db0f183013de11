// rostest of map identity across re-anchors (test/ros/tracking_reanchor.test, issue 26):
// tracking_node and the mapping nodelet (shipped launch files) on a synthetic tabletop bag that the
// test renders and plays itself (with /clock), in this order:
//   1. frames 0-9 (0.3 s apart, 3.6 degrees of the orbit each): tracked ok, keyframes mapped into
//      map A (tracking's map_id);
//   2. a jump of at least 2 m: the frame half an orbit on (the other side of the table, nothing the
//      map holds) and the 3 after it, stamps continuing;
//   3. the bag again from its start (time goes back: a bag played again), frames 0-9.
// Checked:
//   - the jump: lost at once and on every frame after it (never degraded, never a pose: no tf),
//     no new map (map_id unchanged), no "initialised" (the tracker starts no second map);
//   - the replay: a new map_id B; the mapping nodelet follows (its diagnostics' map id), keeps map A
//     in a file of its own (map_<A>.dqomap) and starts B empty: its keyframes in the map are only
//     those of the replay, and its Gaussian count starts again (no Gaussians fused across maps).
#include <cmath>
#include <filesystem>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <std_msgs/String.h>
#include <tf2_msgs/TFMessage.h>

#include <dqo_map/KeyFrame.h>

#include "dqo_map/common/tum_trajectory.h"
#include "ros_test_util.h"

namespace {

namespace fs = std::filesystem;
using dqo::ros_test::Capture;
using dqo::ros_test::wait_for;

long key(const ros::Time& t) { return std::lround(t.toSec() * 1e6); }

struct MappingStatus {
  std::string map_id;
  long gaussians = -1, keyframes_in_map = -1;
};

struct Recorder {
  std::mutex mutex;
  std::map<long, bool> tf_at;                 // stamps (us) with a map -> camera_base tf
  std::map<long, std::string> tracking_state;  // by the diagnostics' stamp
  std::vector<std::string> map_ids;           // as published, in order
  std::vector<MappingStatus> mapping;         // the mapping nodelet's diagnostics, in order
  size_t keyframes = 0;
  dqo::ros_test::RosoutLog log{"tracking"};
  dqo::ros_test::RosoutLog mapping_log{"mapping"};

  void on_tf(const tf2_msgs::TFMessage::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex);
    for (const auto& t : msg->transforms) {
      if (t.header.frame_id == "map") tf_at[key(t.header.stamp)] = true;
    }
  }
  void on_diagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& a) {
    std::lock_guard<std::mutex> lock(mutex);
    for (const auto& s : a->status) {
      if (s.name == "dqo_map: tracking") {
        for (const auto& kv : s.values) {
          if (kv.key == "state") tracking_state[key(a->header.stamp)] = kv.value;
        }
      } else if (s.name == "dqo_map: mapping /dqo_map/mapping") {
        MappingStatus m;
        for (const auto& kv : s.values) {
          if (kv.key == "map id") m.map_id = kv.value;
          if (kv.key == "gaussians") m.gaussians = std::stol(kv.value);
          if (kv.key == "keyframes in the map") m.keyframes_in_map = std::stol(kv.value);
        }
        mapping.push_back(m);
      }
    }
  }
  void on_map_id(const std_msgs::String::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex);
    map_ids.push_back(msg->data);
  }
  void on_keyframe(const dqo_map::KeyFrame::ConstPtr&) {
    std::lock_guard<std::mutex> lock(mutex);
    ++keyframes;
  }
  void on_log(const rosgraph_msgs::Log::ConstPtr& line) {
    log.on_log(*line);
    mapping_log.on_log(*line);
  }

  bool saw_tf_at(const ros::Time& t) {
    std::lock_guard<std::mutex> lock(mutex);
    return tf_at.count(key(t)) > 0;
  }
  std::optional<std::string> state_at(const ros::Time& t) {
    std::lock_guard<std::mutex> lock(mutex);
    auto it = tracking_state.upper_bound(key(t));
    if (it == tracking_state.begin()) return std::nullopt;
    return std::prev(it)->second;
  }
  std::string last_map_id() {
    std::lock_guard<std::mutex> lock(mutex);
    return map_ids.empty() ? std::string() : map_ids.back();
  }
  std::optional<MappingStatus> last_mapping() {
    std::lock_guard<std::mutex> lock(mutex);
    if (mapping.empty()) return std::nullopt;
    return mapping.back();
  }
};

class TrackingReanchorTest : public dqo::ros_test::RenderedBagTest<TrackingReanchorTest> {
 public:
  static constexpr const char* kDirPrefix = "dqo_tracking_reanchor_";
  static constexpr int kFrames = 63;
  static constexpr int kEvery = 3;

 protected:
  void SetUp() override {
    ASSERT_NO_FATAL_FAILURE(load_bag());
    std::string error;
    const auto gt = dqo::read_tum_trajectory((dir_ / "data" / "groundtruth.txt").string(), &error);
    ASSERT_TRUE(gt) << error;
    for (const auto& [t, T] : *gt) gt_.push_back(T);
    ASSERT_EQ(gt_.size(), captures_.size());

    ros::NodeHandle nh;
    subs_.push_back(nh.subscribe("/tf", 1000, &Recorder::on_tf, &rec_));
    subs_.push_back(nh.subscribe("/rosout", 1000, &Recorder::on_log, &rec_));
    subs_.push_back(nh.subscribe("/diagnostics", 1000, &Recorder::on_diagnostics, &rec_));
    subs_.push_back(nh.subscribe("/dqo_map/map_id", 10, &Recorder::on_map_id, &rec_));
    subs_.push_back(nh.subscribe("/dqo_map/keyframes", 100, &Recorder::on_keyframe, &rec_));
    pub_.advertise(nh);
    spinner_ = std::make_unique<ros::AsyncSpinner>(2);
    spinner_->start();
    ASSERT_TRUE(wait_for(
        [&] {
          return pub_.rgb.getNumSubscribers() > 0 && pub_.depth.getNumSubscribers() > 0 &&
                 pub_.info.getNumSubscribers() > 0 && !rec_.last_map_id().empty() && rec_.last_mapping() &&
                 subs_[2].getNumPublishers() >= 2;
        },
        30.0))
        << "tracking_node or the mapping nodelet did not connect";
  }

  void TearDown() override {
    if (spinner_) spinner_->stop();
  }

  // Plays one capture restamped at t; waits for its tf (a frame that should have none: `wait`).
  void play(size_t i, const ros::Time& t, bool first, double wait) {
    const Capture c = dqo::ros_test::restamped(captures_[i], t);
    pub_.publish(c, first ? &tf_static_ : nullptr);
    wait_for([&] { return rec_.saw_tf_at(t); }, wait);
  }

  std::vector<dqo::SE3> gt_;
  Recorder rec_;
  std::unique_ptr<ros::AsyncSpinner> spinner_;
  std::vector<ros::Subscriber> subs_;
  dqo::ros_test::CapturePublishers pub_;
};


TEST_F(TrackingReanchorTest, AJumpIsLostAndAReplayStartsANewMap) {
  const std::string map_a = rec_.last_map_id();
  ASSERT_FALSE(map_a.empty());
  const ros::Duration dt = captures_[1].stamp - captures_[0].stamp;

  // ---- 1. frames 0-9: ok, keyframes mapped into A.
  for (size_t i = 0; i <= 9; ++i) play(i, captures_[i].stamp, i == 0, 5.0);
  for (size_t i = 0; i <= 9; ++i) {
    EXPECT_TRUE(rec_.saw_tf_at(captures_[i].stamp)) << "no pose for frame " << i << "\n" << rec_.log.dump();
  }
  ASSERT_TRUE(wait_for(
      [&] {
        const auto m = rec_.last_mapping();
        return m && m->map_id == map_a && m->keyframes_in_map >= 1 && m->gaussians > 0;
      },
      40.0))
      << "the mapping nodelet mapped no keyframe into map " << map_a;

  // ---- 2. a jump of >= 2 m to the far side of the table: lost at once, and stays lost.
  size_t j = 10;
  while (j < captures_.size() && (gt_[j].translation() - gt_[9].translation()).norm() < 2.0) ++j;
  ASSERT_LT(j + 3, captures_.size()) << "no frame 2 m from frame 9 in the bag";
  std::printf("[ INFO     ] the jump: frame 9 -> frame %zu, %.2f m\n", j, (gt_[j].translation() - gt_[9].translation()).norm());
  std::vector<ros::Time> jumped;
  for (size_t k = 0; k < 4; ++k) {
    jumped.push_back(captures_[9].stamp + dt * static_cast<int>(k + 1));
    play(j + k, jumped.back(), false, 1.0);
  }
  ros::WallDuration(1.0).sleep();  // the last frame's diagnostics
  for (size_t k = 0; k < jumped.size(); ++k) {
    const auto st = rec_.state_at(jumped[k]);
    EXPECT_TRUE(st && *st == "lost") << "frame " << j + k << " after the jump: " << (st ? *st : "no state")
                                     << " (a jump it cannot explain is lost, never degraded)\n" << rec_.log.dump();
    EXPECT_FALSE(rec_.saw_tf_at(jumped[k])) << "a pose for frame " << j + k << " after the jump";
  }
  EXPECT_EQ(rec_.last_map_id(), map_a) << "a loss is no new map";
  EXPECT_EQ(rec_.log.count("initialised at"), 1u) << "the tracker re-initialised after the jump\n" << rec_.log.dump();

  // ---- 3. the bag again from its start: time goes back, a new map.
  long gaussians_a = 0, keyframes_a = 0;
  {
    const auto m = rec_.last_mapping();
    gaussians_a = m->gaussians;
    keyframes_a = m->keyframes_in_map;
  }
  size_t keyframes_before;
  {
    std::lock_guard<std::mutex> lock(rec_.mutex);
    keyframes_before = rec_.keyframes;
  }
  for (size_t i = 0; i <= 9; ++i) play(i, captures_[i].stamp, i == 0, 5.0);
  ASSERT_TRUE(wait_for([&] { return rec_.last_map_id() != map_a; }, 5.0))
      << "replaying the bag from its start kept map " << map_a << "\n" << rec_.log.dump();
  const std::string map_b = rec_.last_map_id();
  std::printf("[ INFO     ] map %s, then %s\n", map_a.c_str(), map_b.c_str());
  EXPECT_TRUE(rec_.saw_tf_at(captures_[9].stamp)) << "the replay was not tracked\n" << rec_.log.dump();
  ASSERT_TRUE(wait_for(
      [&] {
        const auto m = rec_.last_mapping();
        return m && m->map_id == map_b && m->keyframes_in_map >= 1;
      },
      60.0))
      << "the mapping nodelet did not map the replay into map " << map_b << "\n" << rec_.mapping_log.dump();
  size_t keyframes_replay;
  {
    std::lock_guard<std::mutex> lock(rec_.mutex);
    keyframes_replay = rec_.keyframes - keyframes_before;
  }
  {
    // Every status of map B: its keyframes only the replay's, its Gaussians counted from zero.
    std::lock_guard<std::mutex> lock(rec_.mutex);
    bool first = true;
    for (const MappingStatus& m : rec_.mapping) {
      if (m.map_id != map_b) continue;
      EXPECT_LE(m.keyframes_in_map, static_cast<long>(keyframes_replay)) << "keyframes of map A in map B";
      if (first) {
        EXPECT_LT(m.gaussians, gaussians_a) << "map B's first status holds map A's Gaussians\n" << rec_.mapping_log.dump();
        first = false;
      }
    }
  }
  std::printf("[ INFO     ] map A: %ld keyframes, %ld Gaussians; map B from %zu keyframes of the replay\n", keyframes_a,
              gaussians_a, keyframes_replay);
  const std::string work_dir = ros::param::param<std::string>("~work_dir", "");
  ASSERT_FALSE(work_dir.empty());
  EXPECT_TRUE(wait_for([&] { return fs::exists(fs::path(work_dir) / ("map_" + map_a + ".dqomap")); }, 10.0))
      << "map A not kept in a file of its own\n" << rec_.mapping_log.dump();
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_tracking_reanchor");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
