// rostest of the whole ROS system with the mapping nodelet (test/ros/mapping.test): the test renders
// a small tabletop bag (half resolution, ground-truth tf, instance masks with the detections) and
// plays it itself, paced on the mapping nodelet's diagnostics so that nothing is dropped; then
//   - the ROS run against dqo_map_offline on the same frames: same objects, Gaussian counts within 1 %;
//   - extract_object for each ground-truth object: a mesh that scores Completion ratio < 1 cm >= 70 %;
//   - bad requests (unknown ID, paths that lead out, a truncated map): clear errors, nothing written,
//     the map unchanged; save, load, extract again: bit-identical Gaussians;
//   - a burst of keyframes beyond max_queue at a second nodelet: the oldest dropped and counted;
//   - the mapping process killed (SIGKILL) and started again: it resumes from its autosave while
//     tracking and association keep going.
// Every wait is bounded; their sum stays under the .test's time limit.

#include <gtest/gtest.h>
#include <signal.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <diagnostic_msgs/DiagnosticArray.h>
#include <dqo_map/ExtractObject.h>
#include <dqo_map/GetObject.h>
#include <dqo_map/KeyFrame.h>
#include <dqo_map/KeyFrameObjects.h>
#include <dqo_map/ListObjects.h>
#include <dqo_map/LoadMap.h>
#include <dqo_map/ObjectArray.h>
#include <dqo_map/SaveMap.h>
#include <ros/master.h>
#include <ros/network.h>
#include <xmlrpcpp/XmlRpcClient.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>

#include "dqo_map/eval/object_metrics.h"
#include "dqo_map/io/dataset_reader.h"
#include "dqo_map/io/mesh_io.h"
#include "dqo_map/mapping/map_file.h"
#include "dqo_map/mesh/object_recon.h"
#include "ros_test_util.h"

namespace {

namespace fs = std::filesystem;
using dqo::ros_test::Capture;
using dqo::ros_test::wait_for;

constexpr int kFrames = 14;  // tabletop's frames 0, 14, 28, ...: 14 keyframes over ~235 degrees
constexpr int kEvery = 14;
const char* const kMapping = "/dqo_map/mapping";
const char* const kBurst = "/dqo_map/mapping_burst";

// The mapping nodelets' diagnostics, by nodelet name.
class Diagnostics {
 public:
  void on_msg(const diagnostic_msgs::DiagnosticArray& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& s : msg.status) {
      const std::string prefix = "dqo_map: mapping ";
      if (s.name.compare(0, prefix.size(), prefix) != 0) continue;
      auto& values = latest_[s.name.substr(prefix.size())];
      values.clear();
      for (const auto& kv : s.values) values[kv.key] = kv.value;
      ++count_[s.name.substr(prefix.size())];
    }
  }
  // A value of the latest diagnostics of `node` as a number; -1 when there is none yet.
  double value(const std::string& node, const std::string& key) const {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto it = latest_.find(node);
    if (it == latest_.end()) return -1;
    const auto v = it->second.find(key);
    return v == it->second.end() ? -1 : std::atof(v->second.c_str());
  }
  int count(const std::string& node) const {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto it = count_.find(node);
    return it == count_.end() ? 0 : it->second;
  }

 private:
  mutable std::mutex mutex_;
  std::map<std::string, std::map<std::string, std::string>> latest_;
  std::map<std::string, int> count_;
};

std::string read_all(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// Every file under a folder (recursively), for "nothing was written".
std::set<std::string> files_under(const fs::path& dir) {
  std::set<std::string> out;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    out.insert(it->path().string());
  }
  return out;
}

class MappingNodeTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = dqo::ros_test::make_test_dir("dqo_mapping_node_test_");
    make_scene_rc_ = dqo::ros_test::render_tabletop_bag(dir_, kFrames, kEvery, "--gt-tf --masks --scale 0.5");
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    if (std::getenv("DQO_KEEP_TEST_DIR")) return;  // kept for a look when set
    fs::remove_all(dir_, ec);
    if (!work_dir_of_launch_.empty()) fs::remove_all(work_dir_of_launch_, ec);
  }

  void SetUp() override {
    ASSERT_EQ(make_scene_rc_, 0) << "dqo_make_scene failed; see " << (dir_ / "make_scene.log");
    captures_ = dqo::ros_test::read_captures((dir_ / "tabletop.bag").string(), &tf_static_);
    ASSERT_EQ(captures_.size(), static_cast<size_t>(kFrames));
    ros::NodeHandle nh, pnh("~");
    pnh.param<std::string>("work_dir", work_dir_, "");
    ASSERT_FALSE(work_dir_.empty());
    work_dir_of_launch_ = work_dir_;
    map_dir_ = fs::path(work_dir_) / "map";
    diag_sub_ = nh.subscribe("/diagnostics", 100, &Diagnostics::on_msg, &diag_);
    kfo_sub_ = nh.subscribe("/dqo_map/keyframe_objects", 100, &MappingNodeTest::on_kf_objects, this);
    pub_.advertise(nh, 100);
    burst_kf_pub_ = nh.advertise<dqo_map::KeyFrame>("/test/burst/keyframes", 100);
    burst_kfo_pub_ = nh.advertise<dqo_map::KeyFrameObjects>("/test/burst/keyframe_objects", 100);
    spinner_ = std::make_unique<ros::AsyncSpinner>(2);
    spinner_->start();
    ASSERT_TRUE(wait_for(
        [&] {
          // camera_info too (the tracking node and the association node, which undistorts raw
          // boxes): without it the first frame was once lost on CI, and the run then began a
          // frame later than the offline run it is compared with.
          return pub_.rgb.getNumSubscribers() > 0 && pub_.depth.getNumSubscribers() > 0 &&
                 pub_.info.getNumSubscribers() >= 2 && pub_.det.getNumSubscribers() > 0 &&
                 pub_.tf.getNumSubscribers() > 0 && kfo_sub_.getNumPublishers() > 0 &&
                 diag_.count(kMapping) > 0;
        },
        90.0))
        << "tracking, association and the mapping nodelet did not connect";
    ASSERT_TRUE(ros::service::waitForService("/dqo_map/extract_object", 30000));
  }

  void TearDown() override {
    if (spinner_) spinner_->stop();
  }

  void on_kf_objects(const dqo_map::KeyFrameObjects& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    kf_objects_stamps_.insert(msg.header.stamp);
  }
  bool has_kf_objects(const ros::Time& t) {
    std::lock_guard<std::mutex> lock(mutex_);
    return kf_objects_stamps_.count(t) > 0;
  }

  // One capture as the bag holds it; waits until the association node answered for it (the
  // tracking node's synchroniser may hold a frame until the next one comes: then up to wait_s).
  bool play(const Capture& c, bool with_static, double wait_s) {
    pub_.publish(c, with_static ? &tf_static_ : nullptr);
    return wait_for([&] { return has_kf_objects(c.stamp); }, wait_s);
  }

  size_t kf_objects_seen() {
    std::lock_guard<std::mutex> lock(mutex_);
    return kf_objects_stamps_.size();
  }

  // Until the nodelet has received at least `expected` keyframes and mapped every one it has
  // (nothing queued or waiting for its objects), bounded.
  bool wait_mapped(const std::string& node, double seconds, size_t expected = 0) {
    return wait_for(
        [&] {
          const double received = diag_.value(node, "keyframes received");
          return received >= static_cast<double>(expected) && received >= 0 &&
                 diag_.value(node, "keyframes mapped") >= received && diag_.value(node, "keyframes queued") == 0 &&
                 diag_.value(node, "keyframes waiting for objects") == 0;
        },
        seconds);
  }

  template <typename Srv>
  bool call(const std::string& name, Srv& srv) {
    return ros::service::waitForService(name, 10000) && ros::service::call(name, srv);
  }

  static fs::path dir_;
  static int make_scene_rc_;
  static std::map<uint64_t, size_t> ros_counts_;  // Gaussians per object after the paced run
  static std::string work_dir_of_launch_;         // mapping.test's folder (state, maps), removed at the end
  std::string work_dir_;
  fs::path map_dir_;
  std::vector<Capture> captures_;
  tf2_msgs::TFMessage tf_static_;
  Diagnostics diag_;
  std::mutex mutex_;
  std::set<ros::Time> kf_objects_stamps_;
  ros::Subscriber diag_sub_, kfo_sub_;
  dqo::ros_test::CapturePublishers pub_;
  ros::Publisher burst_kf_pub_, burst_kfo_pub_;
  std::unique_ptr<ros::AsyncSpinner> spinner_;
};

fs::path MappingNodeTest::dir_;
int MappingNodeTest::make_scene_rc_ = -1;
std::map<uint64_t, size_t> MappingNodeTest::ros_counts_;
std::string MappingNodeTest::work_dir_of_launch_;

// The PID of a node of this test's master (its URI from lookupNode, then the node's getPid); 0 if
// unknown.
int pid_of(const std::string& node) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  args[1] = node;
  if (!ros::master::execute("lookupNode", args, result, payload, true)) return 0;
  std::string host;
  uint32_t port = 0;
  if (!ros::network::splitURI(static_cast<std::string>(payload), host, port)) return 0;
  XmlRpc::XmlRpcClient client(host.c_str(), static_cast<int>(port), "/");
  XmlRpc::XmlRpcValue request, response;
  request[0] = ros::this_node::getName();
  if (!client.execute("getPid", request, response) || response.getType() != XmlRpc::XmlRpcValue::TypeArray ||
      response.size() < 3 || response[2].getType() != XmlRpc::XmlRpcValue::TypeInt)
    return 0;
  return static_cast<int>(response[2]);
}

// Gaussians per object ID of a map file.
std::map<uint64_t, size_t> counts_of(const dqo::mapping::MapFileContents& map) {
  std::map<uint64_t, size_t> out;
  for (uint32_t id : map.gaussians.object_ids_per_gaussian()) ++out[id];
  return out;
}

TEST_F(MappingNodeTest, SameObjectsAndGaussiansAsTheOfflineRunAndMeshesOfTheObjects) {
  // ---- the stages on two addresses (mapping.test): the map below is made across them
  auto uri_of = [](const std::string& node) {
    XmlRpc::XmlRpcValue args, result, payload;
    args[0] = ros::this_node::getName();
    args[1] = node;
    if (!ros::master::execute("lookupNode", args, result, payload, true)) return std::string();
    return static_cast<std::string>(payload);
  };
  EXPECT_NE(uri_of("/dqo_map/tracking").find("//127.0.0.1:"), std::string::npos) << uri_of("/dqo_map/tracking");
  std::string mapping_ip;
  ros::NodeHandle("~").param<std::string>("mapping_ip", mapping_ip, "127.0.0.1");
  EXPECT_NE(uri_of("/dqo_map/manager").find("//" + mapping_ip + ":"), std::string::npos) << uri_of("/dqo_map/manager");
  if (mapping_ip == "127.0.0.1") std::printf("note: no second address (DQO_TEST_SECOND_IP): one address for all\n");

  // ---- the bag, paced: each keyframe mapped before the next frame (max_queue 0 drops nothing)
  for (size_t i = 0; i < captures_.size(); ++i) {
    play(captures_[i], i == 0, 20.0);
    ASSERT_TRUE(wait_mapped(kMapping, 60.0, kf_objects_seen()))
        << "the keyframes up to frame " << i << " not mapped within 60 s";
  }
  ASSERT_TRUE(wait_mapped(kMapping, 30.0));
  EXPECT_EQ(diag_.value(kMapping, "keyframes dropped"), 0) << "a paced bag loses nothing";
  EXPECT_EQ(diag_.value(kMapping, "messages refused"), 0);
  const int keyframes = static_cast<int>(diag_.value(kMapping, "keyframes mapped"));
  ASSERT_GE(keyframes, kFrames - 1) << "every frame is a keyframe here (mapping.test), but the last may be held";

  dqo_map::SaveMap save;
  save.request.file = "paced.dqomap";
  ASSERT_TRUE(call("/dqo_map/save_map", save));
  ASSERT_TRUE(save.response.success) << save.response.message;
  std::string error;
  const auto ros_map = dqo::mapping::load_map_file(save.response.path, &error);
  ASSERT_TRUE(ros_map) << error;
  ASSERT_EQ(static_cast<int>(ros_map->keyframes.size()), keyframes);

  // ---- dqo_map_offline on the same frames (the keyframes the ROS run got), the same parameters
  const fs::path offline = dir_ / "offline";
  const std::string cmd = std::string(DQO_MAP_OFFLINE) + " " + (dir_ / "data").string() + " --out " +
                          offline.string() + " --poses gt --labels masks --frames " + std::to_string(keyframes) +
                          " --config " + DQO_SOURCE_DIR + "/test/ros/mapping_test.yaml --tracking-config " +
                          DQO_SOURCE_DIR + "/test/ros/mapping_test_tracking.yaml --no-meshes --quiet > " +
                          (dir_ / "offline.log").string() + " 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << "dqo_map_offline failed; see " << (dir_ / "offline.log");
  const auto off_map = dqo::mapping::load_map_file((offline / "map.dqomap").string(), &error);
  ASSERT_TRUE(off_map) << error;
  ASSERT_EQ(off_map->keyframes.size(), ros_map->keyframes.size());

  std::map<uint64_t, std::string> off_classes, ros_classes;
  for (const auto& o : off_map->objects) off_classes[o.id] = o.class_name;
  for (const auto& o : ros_map->objects) ros_classes[o.id] = o.class_name;
  EXPECT_EQ(ros_classes, off_classes) << "the same objects (IDs and classes)";
  const auto off_counts = counts_of(*off_map);
  ros_counts_ = counts_of(*ros_map);
  const double off_total = static_cast<double>(off_map->gaussians.size());
  EXPECT_NEAR(static_cast<double>(ros_map->gaussians.size()), off_total, 0.01 * off_total);
  for (const auto& [id, n] : off_counts) {
    EXPECT_NEAR(static_cast<double>(ros_counts_[id]), static_cast<double>(n), std::max(1.0, 0.01 * n))
        << "Gaussians of object " << id << " (0: background)";
  }
  for (const auto& o : off_map->objects) {
    const auto* r = [&]() -> const dqo::mapping::ObjectRecord* {
      for (const auto& x : ros_map->objects) {
        if (x.id == o.id) return &x;
      }
      return nullptr;
    }();
    ASSERT_NE(r, nullptr);
    EXPECT_LT((r->quadric.centre() - o.quadric.centre()).norm(), 0.005) << "object " << o.id;
  }

  // ---- one orientation everywhere: list_objects (the association node's ellipsoids) and
  // get_object (the mapping nodelet's, rebuilt from the 4x4 dual quadric) report the same pose
  dqo_map::ListObjects list;
  ASSERT_TRUE(call("/dqo_map/list_objects", list));
  ASSERT_FALSE(list.response.objects.empty());
  int compared = 0;
  for (const dqo_map::Object& listed : list.response.objects) {
    dqo_map::GetObject get;
    get.request.id = listed.id;
    ASSERT_TRUE(call("/dqo_map/get_object", get));
    if (!get.response.found) continue;  // confirmed after the mapping nodelet's last object update
    const dqo_map::Object& got = get.response.object;
    const Eigen::Vector3d c_list(listed.pose.position.x, listed.pose.position.y, listed.pose.position.z);
    const Eigen::Vector3d c_got(got.pose.position.x, got.pose.position.y, got.pose.position.z);
    if ((c_list - c_got).norm() > 1e-6) continue;  // another version of the object (a later keyframe's)
    const Eigen::Quaterniond q_list(listed.pose.orientation.w, listed.pose.orientation.x, listed.pose.orientation.y,
                                    listed.pose.orientation.z);
    const Eigen::Quaterniond q_got(got.pose.orientation.w, got.pose.orientation.x, got.pose.orientation.y,
                                   got.pose.orientation.z);
    EXPECT_NEAR(std::abs(q_list.dot(q_got)), 1.0, 1e-6) << "object " << listed.id << ": one quaternion (up to sign)";
    EXPECT_NEAR(listed.semi_axes.x, got.semi_axes.x, 1e-6) << "object " << listed.id;
    EXPECT_NEAR(listed.semi_axes.y, got.semi_axes.y, 1e-6) << "object " << listed.id;
    EXPECT_NEAR(listed.semi_axes.z, got.semi_axes.z, 1e-6) << "object " << listed.id;
    EXPECT_GE(listed.semi_axes.x, listed.semi_axes.y) << "x the longer of the horizontal axes";
    ++compared;
  }
  EXPECT_GE(compared, 3) << "most objects are the same version in both nodes once the bag is mapped";

  // ---- extract_object for each ground-truth object; the meshes against the ground truth
  auto dataset = dqo::open_dataset((dir_ / "data").string(), &error);
  ASSERT_TRUE(dataset) << error;
  const auto& gt = dataset->info().objects;
  ASSERT_EQ(gt.size(), 4u);
  std::vector<dqo::eval::ObjectEstimate> est, truth;
  for (const auto& o : ros_map->objects) est.push_back({o.id, o.class_id, dqo::box_from_quadric(o.quadric)});
  for (const auto& g : gt) truth.push_back({g.id, g.class_id, g.box});
  const auto matched = dqo::eval::evaluate_objects(est, truth);
  ASSERT_EQ(matched.num_matched, 4) << "every ground-truth object found";
  std::map<uint64_t, std::string> mesh_paths;
  std::vector<dqo::mesh::ReconMatch> pairs;
  for (const auto& m : matched.matches) {
    dqo_map::ExtractObject ex;
    ex.request.id = m.est_id;
    ex.request.subfolder = "objects";
    ASSERT_TRUE(call("/dqo_map/extract_object", ex));
    ASSERT_TRUE(ex.response.success) << ex.response.message;
    EXPECT_TRUE(fs::exists(ex.response.gaussians_path));
    EXPECT_EQ(fs::path(ex.response.mesh_path).parent_path(), fs::canonical(map_dir_) / "objects");
    mesh_paths[m.est_id] = ex.response.mesh_path;
    pairs.push_back({m.est_id, m.gt_id});
  }
  const auto table = dqo::mesh::evaluate_object_reconstructions(
      gt, pairs, [&](uint64_t id) { return dqo::load_mesh(mesh_paths.at(id)); }, dqo::mesh::ReconParams());
  ASSERT_EQ(table.num_with_mesh, 4) << dqo::mesh::format_recon_table(table);
  for (const auto& row : table.rows) {
    EXPECT_GE(row.metrics.comp_ratio_1cm, 70.0) << "object " << row.est_id << " (" << row.class_name << ")\n"
                                                << dqo::mesh::format_recon_table(table);
  }
}

TEST_F(MappingNodeTest, BadRequestsAreRefusedAndChangeNothing) {
  ASSERT_GT(ros_counts_.size(), 1u) << "needs the paced run's objects";
  ASSERT_TRUE(wait_mapped(kMapping, 30.0));
  const double gaussians = diag_.value(kMapping, "gaussians");
  ASSERT_GT(gaussians, 0);
  // A symlink inside the output folder that leads out of it.
  const fs::path outside = fs::path(work_dir_) / "outside";
  fs::create_directories(outside);
  std::error_code ec;
  fs::create_directory_symlink(outside, map_dir_ / "link_out", ec);
  ASSERT_FALSE(ec) << ec.message();
  const auto before = files_under(work_dir_);

  dqo_map::ExtractObject ex;
  ex.request.id = 987654;
  ASSERT_TRUE(call("/dqo_map/extract_object", ex));
  EXPECT_FALSE(ex.response.success);
  EXPECT_NE(ex.response.message.find("987654"), std::string::npos) << ex.response.message;
  for (const std::string sub : {"../escape", "/tmp/absolute", "link_out", "objects/../../escape"}) {
    ex.request.id = ros_counts_.rbegin()->first;  // an object that exists
    ex.request.subfolder = sub;
    ASSERT_TRUE(call("/dqo_map/extract_object", ex));
    EXPECT_FALSE(ex.response.success) << sub;
    EXPECT_TRUE(ex.response.gaussians_path.empty() && ex.response.mesh_path.empty()) << sub;
  }
  dqo_map::GetObject get;
  get.request.id = 987654;
  ASSERT_TRUE(call("/dqo_map/get_object", get));
  EXPECT_FALSE(get.response.found);
  EXPECT_FALSE(get.response.message.empty());
  for (const std::string name : {"../escape.dqomap", "/tmp/absolute.dqomap", "link_out/x.dqomap"}) {
    dqo_map::SaveMap save;
    save.request.file = name;
    ASSERT_TRUE(call("/dqo_map/save_map", save));
    EXPECT_FALSE(save.response.success) << name;
    dqo_map::LoadMap load;
    load.request.file = name;
    ASSERT_TRUE(call("/dqo_map/load_map", load));
    EXPECT_FALSE(load.response.success) << name;
  }
  EXPECT_EQ(files_under(work_dir_), before) << "nothing written anywhere";

  // A truncated map file: refused, the map unchanged.
  const std::string whole = read_all(map_dir_ / "paced.dqomap");
  ASSERT_GT(whole.size(), 1000u);
  std::ofstream(map_dir_ / "truncated.dqomap", std::ios::binary) << whole.substr(0, whole.size() / 2);
  dqo_map::LoadMap load;
  load.request.file = "truncated.dqomap";
  ASSERT_TRUE(call("/dqo_map/load_map", load));
  EXPECT_FALSE(load.response.success);
  EXPECT_NE(load.response.message.find("truncated"), std::string::npos) << load.response.message;
  dqo_map::GetObject still;
  still.request.id = ros_counts_.rbegin()->first;
  ASSERT_TRUE(call("/dqo_map/get_object", still));
  ASSERT_TRUE(still.response.found);
  EXPECT_EQ(still.response.object.num_gaussians, ros_counts_.rbegin()->second) << "the map is unchanged";
}

TEST_F(MappingNodeTest, SaveLoadExtractGivesBitIdenticalGaussians) {
  ASSERT_GT(ros_counts_.size(), 1u) << "needs the paced run's objects";
  const uint64_t id = ros_counts_.rbegin()->first;
  dqo_map::ExtractObject first;
  first.request.id = id;
  first.request.subfolder = "before";
  ASSERT_TRUE(call("/dqo_map/extract_object", first));
  ASSERT_TRUE(first.response.success) << first.response.message;
  dqo_map::SaveMap save;
  save.request.file = "roundtrip.dqomap";
  ASSERT_TRUE(call("/dqo_map/save_map", save));
  ASSERT_TRUE(save.response.success) << save.response.message;
  dqo_map::LoadMap load;
  load.request.file = "roundtrip.dqomap";
  ASSERT_TRUE(call("/dqo_map/load_map", load));
  ASSERT_TRUE(load.response.success) << load.response.message;
  dqo_map::ExtractObject second;
  second.request.id = id;
  second.request.subfolder = "after";
  ASSERT_TRUE(call("/dqo_map/extract_object", second));
  ASSERT_TRUE(second.response.success) << second.response.message;
  const std::string a = read_all(first.response.gaussians_path), b = read_all(second.response.gaussians_path);
  EXPECT_GT(a.size(), 100u);
  EXPECT_TRUE(a == b) << "the Gaussians after save and load differ from those before";
}

TEST_F(MappingNodeTest, ABurstBeyondMaxQueueDropsTheOldestAndTheNodeletLives) {
  // mapping_burst (mapping.test: max_queue 2) gets keyframes and their (empty) objects back to back.
  ASSERT_TRUE(wait_for([&] { return burst_kf_pub_.getNumSubscribers() > 0 && burst_kfo_pub_.getNumSubscribers() > 0; },
                       30.0));
  std::string error;
  const int n = 12;
  for (int i = 0; i < n; ++i) {
    dqo_map::KeyFrame kf;
    const Capture& c = captures_[i % captures_.size()];
    kf.header.stamp = ros::Time(2000.0 + i);
    kf.header.frame_id = "map";
    kf.id = 100 + i;
    kf.pose.orientation.w = 1.0;
    kf.camera_info = c.info;
    kf.rgb = c.rgb;
    kf.depth = c.depth;
    burst_kf_pub_.publish(kf);
    dqo_map::KeyFrameObjects objects;
    objects.header = kf.header;
    objects.keyframe_id = kf.id;
    burst_kfo_pub_.publish(objects);
  }
  ASSERT_TRUE(wait_for([&] { return diag_.value(kBurst, "keyframes received") == n; }, 30.0));
  ASSERT_TRUE(wait_for(
      [&] { return diag_.value(kBurst, "keyframes mapped") + diag_.value(kBurst, "keyframes dropped") == n; }, 120.0))
      << "mapped " << diag_.value(kBurst, "keyframes mapped") << ", dropped " << diag_.value(kBurst, "keyframes dropped");
  EXPECT_GE(diag_.value(kBurst, "keyframes dropped"), 1) << "a burst beyond max_queue drops the oldest";
  EXPECT_GE(diag_.value(kBurst, "keyframes mapped"), 2);
  dqo_map::GetObject get;
  get.request.id = 1;
  EXPECT_TRUE(call("/dqo_map/mapping_burst/get_object", get)) << "the nodelet still answers";
}

// Stamps after the bag's, one second apart, for the frames the tests below make up.
ros::Time later_stamp(const std::vector<Capture>& captures) {
  static int n = 0;
  return captures.back().stamp + ros::Duration(10.0 + n++);
}

TEST_F(MappingNodeTest, WithoutCameraInfoNothingIsMappedAndTheNodesLive) {
  ASSERT_TRUE(wait_mapped(kMapping, 30.0));
  const double received = diag_.value(kMapping, "keyframes received");
  for (int k = 0; k < 3; ++k) {
    const Capture c = dqo::ros_test::restamped(captures_[k], later_stamp(captures_));
    dqo::ros_test::set_clock(pub_.clock, c.stamp);
    pub_.tf.publish(c.tf);
    pub_.det.publish(c.detections);
    pub_.depth.publish(c.depth);  // colour and depth, no camera_info
    pub_.rgb.publish(c.rgb);
    ros::WallDuration(0.3).sleep();
  }
  ros::WallDuration(2.0).sleep();
  EXPECT_EQ(diag_.value(kMapping, "keyframes received"), received) << "no camera_info, no keyframe";
  dqo_map::GetObject get;
  get.request.id = 1;
  EXPECT_TRUE(call("/dqo_map/get_object", get)) << "the mapping nodelet answers";
  dqo_map::ListObjects list;
  EXPECT_TRUE(call("/dqo_map/list_objects", list)) << "the association node answers";
}

TEST_F(MappingNodeTest, KeyframesWhoseDetectionsNeverComeAreMappedAsBackground) {
  ASSERT_TRUE(wait_mapped(kMapping, 30.0));
  const double received = diag_.value(kMapping, "keyframes received");
  const double gaussians = diag_.value(kMapping, "gaussians");
  for (int k = 0; k < 3; ++k) {
    Capture c = dqo::ros_test::restamped(captures_[k + 4], later_stamp(captures_));
    dqo::ros_test::set_clock(pub_.clock, c.stamp);
    pub_.tf.publish(c.tf);  // no detections
    dqo::ros_test::publish_camera(c, pub_.info, pub_.depth, pub_.rgb);
    ros::WallDuration(0.3).sleep();
  }
  // The last frame is held by the tracker's synchroniser; the two before it become keyframes whose
  // objects never come: mapped once the input stops (idle_flush) or newer keyframes pass them.
  ASSERT_TRUE(wait_for([&] { return diag_.value(kMapping, "keyframes received") >= received + 2; }, 20.0));
  EXPECT_TRUE(wait_mapped(kMapping, 60.0, static_cast<size_t>(received + 2)))
      << "keyframes without objects wait for ever: " << diag_.value(kMapping, "keyframes waiting for objects");
  EXPECT_GE(diag_.value(kMapping, "gaussians"), gaussians);
}

TEST_F(MappingNodeTest, ALoopingBagIsMappedOn) {
  // The bag's first frames again with their own stamps: time jumps back.
  ASSERT_TRUE(wait_mapped(kMapping, 60.0));
  const double received = diag_.value(kMapping, "keyframes received");
  for (int k = 0; k < 4; ++k) play(captures_[k], k == 0, 5.0);
  ASSERT_TRUE(wait_for([&] { return diag_.value(kMapping, "keyframes received") >= received + 3; }, 30.0))
      << "keyframes after the jump back reach the mapping nodelet";
  EXPECT_TRUE(wait_mapped(kMapping, 60.0, static_cast<size_t>(received + 3)));
  EXPECT_EQ(diag_.value(kMapping, "keyframes dropped"), 0);
}

TEST_F(MappingNodeTest, KilledMappingProcessResumesFromItsAutosave) {
  ASSERT_TRUE(wait_mapped(kMapping, 30.0));
  const double gaussians = diag_.value(kMapping, "gaussians");
  // The autosave (mapping.test: every second) holds the mapped map.
  ASSERT_TRUE(wait_for(
      [&] {
        std::string e;
        const auto m = dqo::mapping::load_map_file((map_dir_ / "autosave.dqomap").string(), &e);
        return m && static_cast<double>(m->gaussians.size()) == gaussians;
      },
      20.0))
      << "the autosave does not hold the current map";
  // SIGKILL: no shutdown, no last save. The manager holds both nodelets. Its PID from this test's
  // own master (a pattern for pkill would also hit other ROS systems running on the machine).
  const int manager_pid = pid_of("/dqo_map/manager");
  ASSERT_GT(manager_pid, 0) << "the manager's PID";
  ASSERT_EQ(kill(manager_pid, SIGKILL), 0);
  const int before = diag_.count(kMapping);
  ros::WallDuration(1.0).sleep();
  // The same nodelet again, as its own process, with the parameters already on the server.
  const std::string start = std::string("ROS_NAMESPACE=/dqo_map ") + DQO_MAPPING_NODE +
                            " __name:=mapping > " + (fs::path(work_dir_) / "restarted.log").string() + " 2>&1 & echo $! > " +
                            (fs::path(work_dir_) / "restarted.pid").string();
  ASSERT_EQ(std::system(start.c_str()), 0);
  ASSERT_TRUE(wait_for([&] { return diag_.count(kMapping) > before + 1; }, 60.0)) << "the restarted nodelet reports";
  EXPECT_EQ(diag_.value(kMapping, "gaussians"), gaussians) << "resumed from the autosave";
  // Tracking and association kept going: two more frames (later stamps) reach the map.
  ros::WallDuration(1.0).sleep();
  // Three frames: the tracking node's synchroniser holds each until the next one comes.
  std::vector<ros::Time> stamps;
  for (int k = 0; k < 3; ++k) {
    const Capture c = dqo::ros_test::restamped(captures_[k], later_stamp(captures_));
    stamps.push_back(c.stamp);
    play(c, false, 5.0);
  }
  for (int k = 0; k < 2; ++k) {
    EXPECT_TRUE(wait_for([&] { return has_kf_objects(stamps[k]); }, 20.0))
        << "the association node answers after the restart (frame " << k << ")";
  }
  EXPECT_TRUE(wait_for([&] { return diag_.value(kMapping, "keyframes mapped") >= 1; }, 60.0))
      << "the restarted nodelet maps new keyframes";
  EXPECT_TRUE(wait_for([&] { return diag_.value(kMapping, "gaussians") > gaussians; }, 30.0));
  int restarted_pid = 0;
  std::ifstream(fs::path(work_dir_) / "restarted.pid") >> restarted_pid;
  if (restarted_pid > 0) kill(restarted_pid, SIGINT);
}

}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_mapping_node");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
