// rostest of association_node (test/ros/association.test): renders a synthetic bag with detections
// and ground-truth tf (tabletop, by default 40 frames every 5th, the scene's sensor and detector
// noise on: misses, false positives, class confusions, box jitter), plays it into tracking_node (poses from
// tf) and association_node frame by frame (each frame waits for its keyframe_objects, so nothing is
// dropped on a slow machine; the mapper's result depends only on the keyframe sequence, so the run
// is deterministic), and checks against the scene's ground truth:
//   - the confirmed objects are as many as the scene's objects, one per ground-truth object (same
//     class, centre within half the box's largest extent);
//   - IDs are stable: an ID, once published, stays in every later ObjectArray and keeps meaning the
//     same ground-truth object; no ID is created twice or comes back after it went;
//   - object_markers hold an ellipsoid and a label per object, tf a frame object_<id> at its pose;
//     keyframe_objects' arrays are parallel, name only known objects and never one object twice;
//     list_objects (with and without a class filter) returns the published objects; the state file
//     holds them and the next ID;
//   - every confirmed object got one CONFIRMED event (after its CREATED) and a log line; list_objects
//     matches classes case-insensitively and names the map's classes for an unknown one; it and the
//     objects topic carry the Gaussian counts of the mapping nodelet's mapped_objects (published
//     here by the test); object_overlay is the keyframe's size with the detection boxes and each
//     object's conic centre (projected here independently) drawn in their colours;
//   - bad input (NaN, negative and off-image boxes, a thousand detections, detections without a
//     keyframe, a keyframe without detections, an unsupported depth encoding, time going back, a
//     detector flipping every label every keyframe and firing 50 clutter boxes, then one that sees
//     nothing) is logged and skipped, and the node still answers list_objects with the same
//     objects: none lost, none spurious.
// A second test restarts an association_node of its own (namespace /dqo_restart) against the same
// map (objects resumed), another map (not resumed; IDs not reused) and with fresh (none resumed).
// Waits (seconds, each with its own failure message), against association.test's time-limit of 600:
// connect 60 + bag 150 + processed 20 + settled 10 + Gaussian counts 10 + overlay 10 + bad input 100
// (+ the bad detector's 16 keyframes, seconds each on an idle machine)
// + restarts 4 x 20 + feeding 70 + listings 20 = 530, plus rendering the bag.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <sstream>

#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>
#include <rosgraph_msgs/Log.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <std_msgs/String.h>
#include <tf2_msgs/TFMessage.h>
#include <visualization_msgs/MarkerArray.h>

#include <dqo_map/DetectionArray.h>
#include <dqo_map/KeyFrame.h>
#include <dqo_map/KeyFrameObjects.h>
#include <dqo_map/ListObjects.h>
#include <dqo_map/ObjectArray.h>
#include <dqo_map/ObjectEvent.h>

#include "dqo_map/objects/object_mapper.h"
#include "dqo_map/objects/object_overlay.h"
#include "ros_test_util.h"

namespace {

namespace fs = std::filesystem;
using dqo::ros_test::Capture;  // its tf: the ground truth map -> camera_base (--gt-tf)
using dqo::ros_test::wait_for;

struct GtObject {
  uint64_t id = 0;
  int class_id = 0;
  Eigen::Vector3d centre;
  double max_half_extent = 0.0;
};

std::vector<GtObject> read_gt(const fs::path& path) {
  std::vector<GtObject> out;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream s(line);
    GtObject o;
    double q[4], h[3];
    s >> o.id >> o.class_id >> o.centre.x() >> o.centre.y() >> o.centre.z() >> q[0] >> q[1] >> q[2] >> q[3] >> h[0] >>
        h[1] >> h[2];
    if (!s) continue;
    o.max_half_extent = std::max({h[0], h[1], h[2]});
    out.push_back(o);
  }
  return out;
}

Eigen::Vector3d centre_of(const dqo_map::Object& o) {
  return {o.pose.position.x, o.pose.position.y, o.pose.position.z};
}

// What the test hears from the nodes (callbacks run on an AsyncSpinner's thread).
struct Recorder {
  std::mutex mutex;
  std::map<double, dqo_map::KeyFrame> keyframes;      // by stamp
  std::map<double, dqo_map::KeyFrameObjects> kf_objects;  // by stamp
  std::vector<dqo_map::ObjectArray> arrays;
  std::vector<dqo_map::ObjectEvent> events;
  std::vector<visualization_msgs::MarkerArray> markers;
  dqo::ros_test::RosoutLog log{"association"};
  std::map<std::string, geometry_msgs::TransformStamped> object_frames;  // map -> object_<id>, latest
  std::map<double, sensor_msgs::Image> overlays;      // by stamp, the latest few

  void on_keyframe(const dqo_map::KeyFrame::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    keyframes[m->header.stamp.toSec()] = *m;
  }
  void on_kf_objects(const dqo_map::KeyFrameObjects::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    kf_objects[m->header.stamp.toSec()] = *m;
  }
  void on_objects(const dqo_map::ObjectArray::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    arrays.push_back(*m);
  }
  void on_event(const dqo_map::ObjectEvent::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    events.push_back(*m);
  }
  void on_markers(const visualization_msgs::MarkerArray::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    markers.push_back(*m);
  }
  void on_overlay(const sensor_msgs::Image::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    overlays[m->header.stamp.toSec()] = *m;
    while (overlays.size() > 4) overlays.erase(overlays.begin());
  }
  void on_tf(const tf2_msgs::TFMessage::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    for (const auto& t : m->transforms) {
      if (t.child_frame_id.rfind("object_", 0) == 0) object_frames[t.child_frame_id] = t;
    }
  }
  void on_log(const rosgraph_msgs::Log::ConstPtr& line) {
    log.on_log(*line);
    if (line->name.find("tracking") != std::string::npos && line->level >= rosgraph_msgs::Log::WARN) {
      std::printf("[ INFO     ] tracking_node said: %s\n", line->msg.c_str());
    }
  }
  bool has_kf_objects(const ros::Time& t) {
    std::lock_guard<std::mutex> lock(mutex);
    return kf_objects.count(t.toSec()) > 0;
  }
  bool has_keyframe(const ros::Time& t) {
    std::lock_guard<std::mutex> lock(mutex);
    return keyframes.count(t.toSec()) > 0;
  }
  bool logged(const std::string& needle) const { return log.logged(needle); }
};

class AssociationNodeTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = dqo::ros_test::make_test_dir("dqo_association_test_");
    // By default (association.test) 40 frames, every 5th of the 300-frame orbit: 240 degrees around
    // the table, every object seen from many sides.
    ros::NodeHandle pnh("~");
    pnh.param("frames", frames_, 40);
    pnh.param("every", every_, 5);
    make_scene_rc_ = dir_.empty() ? -1 : dqo::ros_test::render_tabletop_bag(dir_, frames_, every_, "--gt-tf");
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
    remove_state_dir();
  }

  void SetUp() override {
    ASSERT_EQ(make_scene_rc_, 0) << "dqo_make_scene failed; see " << (dir_ / "make_scene.log");
    captures_ = dqo::ros_test::read_captures((dir_ / "tabletop.bag").string(), &tf_static_);
    ASSERT_EQ(captures_.size(), static_cast<size_t>(frames_));
    for (const auto& c : captures_) ASSERT_FALSE(c.tf.transforms.empty()) << "the bag has no ground-truth tf";
    gt_ = read_gt(dir_ / "data" / "objects_gt.txt");
    ASSERT_EQ(gt_.size(), 4u) << "tabletop has four objects";

    ros::NodeHandle nh, pnh("~");
    pnh.param<std::string>("state_dir", state_dir_, "");
    kf_sub_ = nh.subscribe("/dqo_map/keyframes", 100, &Recorder::on_keyframe, &rec_);
    kfo_sub_ = nh.subscribe("/dqo_map/keyframe_objects", 100, &Recorder::on_kf_objects, &rec_);
    objects_sub_ = nh.subscribe("/dqo_map/objects", 100, &Recorder::on_objects, &rec_);
    events_sub_ = nh.subscribe("/dqo_map/object_events", 1000, &Recorder::on_event, &rec_);
    markers_sub_ = nh.subscribe("/dqo_map/object_markers", 100, &Recorder::on_markers, &rec_);
    log_sub_ = nh.subscribe("/rosout", 1000, &Recorder::on_log, &rec_);
    tf_sub_ = nh.subscribe("/tf", 1000, &Recorder::on_tf, &rec_);
    overlay_sub_ = nh.subscribe("/dqo_map/object_overlay", 4, &Recorder::on_overlay, &rec_);
    mapped_pub_ = nh.advertise<dqo_map::ObjectArray>("/dqo_map/mapped_objects", 1, /*latch=*/true);
    pub_.advertise(nh, 1100);
    kf_pub_ = nh.advertise<dqo_map::KeyFrame>("/dqo_map/keyframes", 10);
    spinner_ = std::make_unique<ros::AsyncSpinner>(2);
    spinner_->start();
    ASSERT_TRUE(wait_for(
        [&] {
          return pub_.rgb.getNumSubscribers() > 0 && pub_.depth.getNumSubscribers() > 0 &&
                 pub_.info.getNumSubscribers() >= 2 && pub_.det.getNumSubscribers() > 0 &&
                 // 2: this test's recorder and association_node (the recorder alone, in this
                 // process, is connected at once; the node later, after the master's update)
                 kf_pub_.getNumSubscribers() >= 2 && pub_.tf.getNumSubscribers() > 0 &&
                 kfo_sub_.getNumPublishers() > 0 && objects_sub_.getNumPublishers() > 0 &&
                 log_sub_.getNumPublishers() > 0 && overlay_sub_.getNumPublishers() > 0 &&
                 ros::service::exists("/dqo_map/list_objects", false);
        },
        60.0))
        << "tracking_node and association_node did not connect";
  }

  void TearDown() override {
    if (spinner_) spinner_->stop();
  }
  static void remove_state_dir() {
    ros::NodeHandle pnh("~");
    std::string state_dir;
    pnh.param<std::string>("state_dir", state_dir, "");
    std::error_code ec;
    if (!state_dir.empty()) fs::remove_all(state_dir, ec);  // the launch file's fresh state folder
  }

  void set_clock(const ros::Time& t) { dqo::ros_test::set_clock(pub_.clock, t); }

  // One capture as the bag holds it; returns once association_node has published its
  // keyframe_objects (every frame is a keyframe in this test: see association.test), or after
  // wait_s: tracking_node's synchroniser may hold a frame back until the next one arrives.
  bool play(const Capture& c, bool with_static, double wait_s) {
    pub_.publish(c, with_static ? &tf_static_ : nullptr);
    return wait_for([&] { return rec_.has_kf_objects(c.stamp); }, wait_s);
  }

  // The last capture again, later: releases whatever the synchroniser still holds. Waits for its
  // own result too, so that no keyframe of the bag arrives after the stamps that follow it.
  void drain(double wait_s) {
    play(dqo::ros_test::restamped(captures_.back(), captures_.back().stamp + ros::Duration(0.1)), false, wait_s);
  }

  std::vector<dqo_map::Object> list(const std::string& class_name, bool* ok, std::string* message = nullptr,
                                    const std::string& service = "/dqo_map/list_objects") {
    dqo_map::ListObjects srv;
    srv.request.class_name = class_name;
    *ok = ros::service::call(service, srv);
    if (message) *message = srv.response.message;
    return srv.response.objects;
  }

  // The nearest ground-truth object to a centre.
  const GtObject& nearest_gt(const Eigen::Vector3d& c) const {
    size_t best = 0;
    for (size_t i = 1; i < gt_.size(); ++i) {
      if ((gt_[i].centre - c).norm() < (gt_[best].centre - c).norm()) best = i;
    }
    return gt_[best];
  }

  static fs::path dir_;
  static int make_scene_rc_, frames_, every_;
  std::vector<Capture> captures_;
  std::vector<GtObject> gt_;
  tf2_msgs::TFMessage tf_static_;
  std::string state_dir_;
  Recorder rec_;
  std::unique_ptr<ros::AsyncSpinner> spinner_;
  ros::Subscriber kf_sub_, kfo_sub_, objects_sub_, events_sub_, markers_sub_, log_sub_, tf_sub_, overlay_sub_;
  dqo::ros_test::CapturePublishers pub_;
  ros::Publisher kf_pub_, mapped_pub_;
  // The first test's keyframes and the bag's detections, by stamp: the restart test feeds them.
  static std::vector<std::pair<dqo_map::KeyFrame, dqo_map::DetectionArray>> recorded_;
};

fs::path AssociationNodeTest::dir_;
int AssociationNodeTest::make_scene_rc_ = -1;
int AssociationNodeTest::frames_ = 0;
int AssociationNodeTest::every_ = 0;
std::vector<std::pair<dqo_map::KeyFrame, dqo_map::DetectionArray>> AssociationNodeTest::recorded_;

// The conic centre of an object in a keyframe, projected here with Eigen alone (C* = P Q* Pᵀ; the
// centre of a dual conic is C*₀:₂,₂ / C*₂₂), or nothing when the object is not in front.
std::optional<Eigen::Vector2d> conic_centre(const dqo_map::Object& o, const dqo_map::KeyFrame& kf) {
  Eigen::Matrix4d Q;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) Q(r, c) = o.dual_quadric[4 * r + c];
  }
  const auto& p = kf.pose;
  const Eigen::Quaterniond q(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z);
  const Eigen::Matrix3d R_cw = q.toRotationMatrix().transpose();
  const Eigen::Vector3d t_cw = -R_cw * Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
  if ((R_cw * centre_of(o) + t_cw).z() < 0.3) return std::nullopt;
  Eigen::Matrix3d K;
  K << kf.camera_info.K[0], 0, kf.camera_info.K[2], 0, kf.camera_info.K[4], kf.camera_info.K[5], 0, 0, 1;
  Eigen::Matrix<double, 3, 4> P;
  P << R_cw, t_cw;
  P = K * P;
  const Eigen::Matrix3d C = P * Q * P.transpose();
  return Eigen::Vector2d(C(0, 2) / C(2, 2), C(1, 2) / C(2, 2));
}

dqo::objects::Rgb pixel(const sensor_msgs::Image& img, int x, int y) {
  const size_t i = static_cast<size_t>(y) * img.step + static_cast<size_t>(x) * 3;
  return {img.data[i], img.data[i + 1], img.data[i + 2]};
}

// Whether `colour` is drawn within `r` pixels of (x, y).
bool drawn_near(const sensor_msgs::Image& img, double x, double y, int r, const dqo::objects::Rgb& colour) {
  const int cx = static_cast<int>(std::lround(x)), cy = static_cast<int>(std::lround(y));
  for (int v = cy - r; v <= cy + r; ++v) {
    for (int u = cx - r; u <= cx + r; ++u) {
      if (u >= 0 && v >= 0 && u < static_cast<int>(img.width) && v < static_cast<int>(img.height) &&
          pixel(img, u, v) == colour) {
        return true;
      }
    }
  }
  return false;
}

TEST_F(AssociationNodeTest, ObjectsIdsOutputsAndBadInput) {
  // ---- the bag, in order (each frame waits for its keyframe_objects; 150 s for the whole bag)
  dqo::ros_test::Budget bag(150.0);
  for (size_t i = 0; i < captures_.size(); ++i) {
    if (bag.expired()) {
      ADD_FAILURE() << "the bag's " << bag.seconds() << " s ran out at frame " << i << " of " << captures_.size();
      break;
    }
    play(captures_[i], i == 0, bag.take(10.0));
  }
  drain(bag.take(10.0));
  auto all_processed = [&] {
    for (const auto& c : captures_) {
      if (!rec_.has_kf_objects(c.stamp)) return false;
    }
    return true;
  };
  if (!wait_for(all_processed, 20.0)) {
    for (size_t i = 0; i < captures_.size(); ++i) {
      if (rec_.has_kf_objects(captures_[i].stamp)) continue;
      ADD_FAILURE() << "frame " << i << " at " << captures_[i].stamp << ": no keyframe_objects; "
                    << (rec_.has_keyframe(captures_[i].stamp) ? "tracking_node published its keyframe"
                                                              : "tracking_node published no keyframe");
    }
  }

  // Topics are not ordered among each other: let the objects, markers and tf of the last keyframe
  // arrive before reading them.
  auto settled = [&] {
    std::lock_guard<std::mutex> lock(rec_.mutex);
    if (rec_.kf_objects.empty() || rec_.arrays.empty() || rec_.markers.empty()) return false;
    const ros::Time last = rec_.kf_objects.rbegin()->second.header.stamp;
    if (rec_.arrays.back().header.stamp != last) return false;
    if (rec_.markers.back().markers.empty() || rec_.markers.back().markers.front().header.stamp != last) return false;
    // The keyframes themselves come on another topic: they may arrive after their results.
    for (const auto& [stamp, m] : rec_.kf_objects) {
      if (!rec_.keyframes.count(stamp)) return false;
    }
    for (const auto& o : rec_.arrays.back().objects) {
      const auto f = rec_.object_frames.find("object_" + std::to_string(o.id));
      if (f == rec_.object_frames.end() || f->second.header.stamp != last) return false;
    }
    return true;
  };
  EXPECT_TRUE(wait_for(settled, 10.0)) << "objects, markers, keyframes or tf of the last keyframe missing";

  dqo_map::ObjectArray final_array;
  std::set<uint64_t> created, gone;
  size_t arrays_before_bad = 0;
  {
    std::lock_guard<std::mutex> lock(rec_.mutex);
    ASSERT_FALSE(rec_.arrays.empty());
    final_array = rec_.arrays.back();
    // ---- one confirmed object per ground-truth object
    EXPECT_EQ(final_array.objects.size(), gt_.size());
    std::set<uint64_t> matched_gt;
    for (const auto& o : final_array.objects) {
      const GtObject& g = nearest_gt(centre_of(o));
      const double d = (g.centre - centre_of(o)).norm();
      EXPECT_EQ(o.class_id, g.class_id) << "object " << o.id << " nearest to ground truth " << g.id;
      EXPECT_LT(d, g.max_half_extent) << "object " << o.id << " is " << d << " m from ground truth " << g.id;
      EXPECT_TRUE(matched_gt.insert(g.id).second) << "two objects for ground truth " << g.id;
      std::printf("[ INFO     ] object %llu (%s): ground truth %llu at %.3f m, %u observations, semi-axes %.3f %.3f "
                  "%.3f\n", static_cast<unsigned long long>(o.id), o.class_name.c_str(),
                  static_cast<unsigned long long>(g.id), d, o.observations, o.semi_axes.x, o.semi_axes.y,
                  o.semi_axes.z);
    }
    // Where each final object was first published (for diagnosing splits and bad initialisations).
    for (const auto& o : final_array.objects) {
      for (size_t k = 0; k < rec_.arrays.size(); ++k) {
        const auto it = std::find_if(rec_.arrays[k].objects.begin(), rec_.arrays[k].objects.end(),
                                     [&](const dqo_map::Object& p) { return p.id == o.id; });
        if (it == rec_.arrays[k].objects.end()) continue;
        const Eigen::Vector3d c = centre_of(*it);
        std::printf("[ INFO     ] object %llu first published at %.3f: centre %.3f %.3f %.3f, semi-axes %.3f %.3f %.3f\n",
                    static_cast<unsigned long long>(o.id), rec_.arrays[k].header.stamp.toSec(), c.x(), c.y(), c.z(),
                    it->semi_axes.x, it->semi_axes.y, it->semi_axes.z);
        break;
      }
    }

    // ---- stable IDs: present from the first array that holds them to the end, always meaning the
    // same ground-truth object; never created twice.
    std::map<uint64_t, size_t> first_seen;
    std::map<uint64_t, uint64_t> gt_at_first;
    for (size_t k = 0; k < rec_.arrays.size(); ++k) {
      for (const auto& o : rec_.arrays[k].objects) {
        if (!first_seen.count(o.id)) {
          first_seen[o.id] = k;
          gt_at_first[o.id] = nearest_gt(centre_of(o)).id;
        }
      }
    }
    for (const auto& o : final_array.objects) {
      ASSERT_TRUE(first_seen.count(o.id));
      for (size_t k = first_seen[o.id]; k < rec_.arrays.size(); ++k) {
        bool present = false;
        for (const auto& p : rec_.arrays[k].objects) present = present || p.id == o.id;
        EXPECT_TRUE(present) << "object " << o.id << " missing from array " << k << " after appearing in " << first_seen[o.id];
      }
      EXPECT_EQ(gt_at_first[o.id], nearest_gt(centre_of(o)).id) << "object " << o.id << " changed meaning";
    }
    for (const auto& e : rec_.events) {
      if (e.type == dqo_map::ObjectEvent::CREATED) {
        EXPECT_TRUE(created.insert(e.id).second) << "ID " << e.id << " created twice";
      }
      if (e.type == dqo_map::ObjectEvent::MERGED || e.type == dqo_map::ObjectEvent::REMOVED) gone.insert(e.id);
      if (e.type == dqo_map::ObjectEvent::MERGED) {
        EXPECT_NE(e.into_id, 0u);
      }
    }
    for (const auto& o : final_array.objects) {
      EXPECT_TRUE(created.count(o.id)) << "object " << o.id << " without a CREATED event";
      EXPECT_FALSE(gone.count(o.id)) << "object " << o.id << " was merged or removed but is still published";
    }
    // Every ID, final or not, is published in one unbroken run of arrays: once gone, never back.
    std::map<uint64_t, std::pair<size_t, size_t>> runs;  // id -> (last array, arrays holding it)
    for (size_t k = 0; k < rec_.arrays.size(); ++k) {
      for (const auto& p : rec_.arrays[k].objects) {
        auto& r = runs[p.id];
        r.first = k;
        ++r.second;
      }
    }
    for (const auto& [id, r] : runs) {
      EXPECT_EQ(r.second, r.first - first_seen[id] + 1) << "object " << id << " disappeared and came back";
    }
    const uint64_t max_id = first_seen.empty() ? 0 : first_seen.rbegin()->first;

    // ---- markers: an ellipsoid (2x semi-axes) and a label per object; DELETE for objects that went
    ASSERT_FALSE(rec_.markers.empty());
    std::map<std::pair<std::string, int>, visualization_msgs::Marker> last_marker;
    for (const auto& arr : rec_.markers) {
      for (const auto& m : arr.markers) last_marker[{m.ns, m.id}] = m;
    }
    for (const auto& o : final_array.objects) {
      const auto s = last_marker.find({"ellipsoids", static_cast<int>(o.id)});
      ASSERT_NE(s, last_marker.end()) << "no ellipsoid marker for object " << o.id;
      EXPECT_EQ(s->second.type, visualization_msgs::Marker::SPHERE);
      EXPECT_NEAR(s->second.scale.x, 2.0 * o.semi_axes.x, 1e-9);
      EXPECT_NEAR(s->second.scale.z, 2.0 * o.semi_axes.z, 1e-9);
      const auto t = last_marker.find({"labels", static_cast<int>(o.id)});
      ASSERT_NE(t, last_marker.end());
      EXPECT_EQ(t->second.text, std::to_string(o.id) + " " + o.class_name);
    }
    for (const uint64_t id : gone) {
      const auto s = last_marker.find({"ellipsoids", static_cast<int>(id)});
      if (s != last_marker.end()) {
        EXPECT_EQ(s->second.action, visualization_msgs::Marker::DELETE) << "object " << id;
      }
    }

    // ---- tf (publish_tf on in association.test): map -> object_<id> at each object's pose
    for (const auto& o : final_array.objects) {
      const auto f = rec_.object_frames.find("object_" + std::to_string(o.id));
      ASSERT_NE(f, rec_.object_frames.end()) << "no tf frame for object " << o.id;
      EXPECT_EQ(f->second.header.frame_id, "map");
      EXPECT_NEAR(f->second.transform.translation.x, o.pose.position.x, 1e-9);
      EXPECT_NEAR(f->second.transform.translation.z, o.pose.position.z, 1e-9);
      EXPECT_NEAR(std::abs(f->second.transform.rotation.w * o.pose.orientation.w +
                           f->second.transform.rotation.x * o.pose.orientation.x +
                           f->second.transform.rotation.y * o.pose.orientation.y +
                           f->second.transform.rotation.z * o.pose.orientation.z), 1.0, 1e-9);
    }

    // ---- keyframe_objects: parallel arrays, known objects, one detection per object
      for (const auto& [stamp, m] : rec_.kf_objects) {
      ASSERT_EQ(m.object_ids.size(), m.detections.detections.size()) << "keyframe " << m.keyframe_id;
      if (!rec_.keyframes.count(stamp)) {
        ADD_FAILURE() << "keyframe_objects at " << stamp << " (keyframe " << m.keyframe_id << ") but no such keyframe";
        continue;
      }
      EXPECT_EQ(rec_.keyframes[stamp].id, m.keyframe_id);
      std::set<uint64_t> ids;
      for (const uint64_t id : m.object_ids) {
        if (id == 0) continue;
        EXPECT_TRUE(created.count(id)) << "keyframe " << m.keyframe_id << " names unknown object " << id;
        EXPECT_TRUE(ids.insert(id).second) << "object " << id << " took two detections of keyframe " << m.keyframe_id;
      }
      for (const auto& d : m.detections.detections) {
        EXPECT_TRUE(std::isfinite(d.x_min) && d.x_max > d.x_min && d.y_max > d.y_min);
      }
      EXPECT_EQ(m.detections.instance.width, 0u) << "the bag's detections carry no instance image";
    }

    // ---- list_objects: the published objects, and a class filter
    bool ok = false;
    const auto listed = list("", &ok);
    ASSERT_TRUE(ok);
    ASSERT_EQ(listed.size(), final_array.objects.size());
    for (size_t i = 0; i < listed.size(); ++i) {
      EXPECT_EQ(listed[i].id, final_array.objects[i].id);
      EXPECT_EQ(listed[i].class_name, final_array.objects[i].class_name);
      for (int k = 0; k < 16; ++k) EXPECT_DOUBLE_EQ(listed[i].dual_quadric[k], final_array.objects[i].dual_quadric[k]);
    }
    if (!listed.empty()) {
      const std::string cls = listed.front().class_name;
      size_t expected = 0;
      for (const auto& o : listed) expected += o.class_name == cls;
      const auto filtered = list(cls, &ok);
      ASSERT_TRUE(ok);
      EXPECT_EQ(filtered.size(), expected);
      for (const auto& o : filtered) EXPECT_EQ(o.class_name, cls);
      std::string upper = cls, message;
      std::transform(upper.begin(), upper.end(), upper.begin(), [](unsigned char c) { return std::toupper(c); });
      EXPECT_EQ(list(upper, &ok).size(), expected) << "class names match case-insensitively";
      EXPECT_TRUE(list("no_such_class", &ok, &message).empty());
      EXPECT_NE(message.find("no_such_class"), std::string::npos) << message;
      for (const auto& o : listed) EXPECT_NE(message.find(o.class_name), std::string::npos) << "'" << message << "' names no " << o.class_name;
    }

    // ---- CONFIRMED: once per object that ever was in `objects`, after its CREATED, with a log line
    std::map<uint64_t, int> confirmed_count;
    std::set<uint64_t> created_so_far;
    for (const auto& e : rec_.events) {
      if (e.type == dqo_map::ObjectEvent::CREATED) created_so_far.insert(e.id);
      if (e.type != dqo_map::ObjectEvent::CONFIRMED) continue;
      ++confirmed_count[e.id];
      EXPECT_TRUE(created_so_far.count(e.id)) << "object " << e.id << " confirmed before it was created";
    }
    for (const auto& [id, r] : runs) EXPECT_EQ(confirmed_count[id], 1) << "CONFIRMED events of object " << id;
    for (const auto& [id, n] : confirmed_count) EXPECT_TRUE(runs.count(id)) << "object " << id << " confirmed but never published";
    for (const auto& o : final_array.objects) {
      EXPECT_TRUE(rec_.logged("object " + std::to_string(o.id) + " confirmed: " + o.class_name))
          << "no log line for the confirmation of object " << o.id;
    }
    std::printf("[ INFO     ] %zu CREATED, %zu CONFIRMED events for %zu objects\n", created.size(), confirmed_count.size(),
                final_array.objects.size());

    // ---- the state file: the same objects, and a next ID above every ID given
    if (!state_dir_.empty()) {
      dqo::objects::ObjectMapper restored;
      std::string error;
      ASSERT_TRUE(restored.load_state(state_dir_ + "/objects_state.yaml", &error)) << error;
      EXPECT_GT(restored.next_id(), max_id);
      for (const uint64_t id : created) EXPECT_GT(restored.next_id(), id);
      const auto objs = restored.objects();
      ASSERT_EQ(objs.size(), final_array.objects.size());
      for (size_t i = 0; i < objs.size(); ++i) EXPECT_EQ(objs[i].id, final_array.objects[i].id);
    }
    arrays_before_bad = rec_.arrays.size();
    recorded_.clear();
    for (const auto& c : captures_) {
      const auto kf = rec_.keyframes.find(c.stamp.toSec());
      if (kf != rec_.keyframes.end()) recorded_.emplace_back(kf->second, c.detections);
    }
  }

  // ---- object_overlay of the last keyframe: its size, and the conic centres and boxes drawn
  {
    ros::Time last;
    {
      std::lock_guard<std::mutex> lock(rec_.mutex);
      last = rec_.kf_objects.rbegin()->second.header.stamp;
    }
    EXPECT_TRUE(wait_for([&] { std::lock_guard<std::mutex> l(rec_.mutex); return rec_.overlays.count(last.toSec()) > 0; }, 10.0))
        << "no object_overlay for the last keyframe";
    std::lock_guard<std::mutex> lock(rec_.mutex);
    const auto ov = rec_.overlays.find(last.toSec());
    if (ov != rec_.overlays.end()) {
      const sensor_msgs::Image& img = ov->second;
      const dqo_map::KeyFrame& kf = rec_.keyframes.at(last.toSec());
      EXPECT_EQ(img.encoding, "rgb8");
      EXPECT_EQ(img.width, kf.rgb.width);
      EXPECT_EQ(img.height, kf.rgb.height);
      ASSERT_EQ(img.data.size(), static_cast<size_t>(img.step) * img.height);
      int centres = 0;
      // The overlay's palette: the confirmed objects' IDs (those of the final array).
      std::vector<dqo::objects::ObjectId> ids;
      for (const auto& o : final_array.objects) ids.push_back(o.id);
      const dqo::objects::ObjectPalette palette(ids);
      for (const auto& o : final_array.objects) {
        const auto c = conic_centre(o, kf);
        if (!c || c->x() < 0 || c->y() < 0 || c->x() >= img.width || c->y() >= img.height) continue;
        ++centres;
        EXPECT_TRUE(drawn_near(img, c->x(), c->y(), 2, palette.colour(o.id)))
            << "object " << o.id << ": no dot at its conic centre " << c->transpose();
      }
      EXPECT_GT(centres, 0) << "no object in view of the last keyframe";
      const auto& m = rec_.kf_objects.rbegin()->second;
      ASSERT_FALSE(m.detections.detections.empty());
      for (size_t k = 0; k < m.detections.detections.size(); ++k) {
        const auto& d = m.detections.detections[k];
        const auto colour = m.object_ids[k] ? palette.colour(m.object_ids[k]) : dqo::objects::kUnmatchedColour;
        const double xm = 0.5 * (d.x_min + d.x_max), ym = 0.5 * (d.y_min + d.y_max);
        // Another box or a label may cover one edge: one of the four is enough.
        EXPECT_TRUE(drawn_near(img, d.x_min, ym, 1, colour) || drawn_near(img, d.x_max, ym, 1, colour) ||
                    drawn_near(img, xm, d.y_min, 1, colour) || drawn_near(img, xm, d.y_max, 1, colour))
            << "detection " << k << " (" << d.class_name << "): its box is not drawn";
      }
    }
  }

  // ---- Gaussian counts: the mapping nodelet's mapped_objects (published here) fill num_gaussians
  {
    dqo_map::ObjectArray mapped;
    mapped.header = final_array.header;
    for (const auto& o : final_array.objects) {
      dqo_map::Object m;
      m.id = o.id;
      m.num_gaussians = static_cast<uint32_t>(1000 + o.id);
      mapped.objects.push_back(m);
    }
    mapped_pub_.publish(mapped);
    auto counted = [&] {
      bool ok = false;
      const auto objs = list("", &ok);
      if (!ok || objs.empty()) return false;
      for (const auto& o : objs) {
        if (o.num_gaussians != 1000 + o.id) return false;
      }
      return true;
    };
    EXPECT_TRUE(wait_for(counted, 10.0)) << "list_objects does not carry mapped_objects' Gaussian counts";
  }

  // ---- bad input. Keyframes built from the last one, with new IDs and later stamps.
  dqo_map::KeyFrame kf_template;
  {
    std::lock_guard<std::mutex> l(rec_.mutex);
    kf_template = rec_.keyframes.rbegin()->second;
  }
  const ros::Time t0 = captures_.back().stamp + ros::Duration(1.0);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  auto keyframe_at = [&](uint64_t id, const ros::Time& t) {
    dqo_map::KeyFrame kf = kf_template;
    kf.id = id;
    kf.header.stamp = kf.rgb.header.stamp = kf.depth.header.stamp = kf.camera_info.header.stamp = t;
    return kf;
  };
  auto detections_at = [&](const ros::Time& t) {
    dqo_map::DetectionArray d = captures_.back().detections;
    d.header.stamp = t;
    return d;
  };
  // (a) NaN, negative-size and off-image boxes next to the real ones
  dqo_map::DetectionArray bad = detections_at(t0);
  dqo_map::Detection d;
  d.class_id = 1, d.class_name = "book", d.score = 0.9f;
  d.x_min = nan, d.y_min = 10, d.x_max = 50, d.y_max = 60;
  bad.detections.push_back(d);
  d.x_min = 100, d.y_min = 100, d.x_max = 40, d.y_max = 30;
  bad.detections.push_back(d);
  d.x_min = 5000, d.y_min = 5000, d.x_max = 5100, d.y_max = 5100;
  bad.detections.push_back(d);
  pub_.det.publish(bad);
  kf_pub_.publish(keyframe_at(1000001, t0));
  EXPECT_TRUE(wait_for([&] { return rec_.has_kf_objects(t0); }, 20.0)) << "keyframe with bad boxes not processed; "
                                                                         << "association_node said:\n" << rec_.log.dump();
  EXPECT_TRUE(wait_for([&] { return rec_.logged("rejected as unusable"); }, 5.0)) << "no log line about the bad boxes";
  {
    std::lock_guard<std::mutex> l(rec_.mutex);
    const auto& m = rec_.kf_objects[t0.toSec()];
    for (const auto& det : m.detections.detections) {
      EXPECT_TRUE(std::isfinite(det.x_min) && det.x_max > det.x_min && det.x_max <= 640.f) << "a bad box passed";
    }
  }
  // (b) a thousand detections
  const ros::Time t1 = t0 + ros::Duration(0.1);
  dqo_map::DetectionArray many;
  many.header = bad.header;
  many.header.stamp = t1;
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> x(0.f, 600.f), y(0.f, 440.f), s(5.f, 40.f);
  for (int i = 0; i < 1000; ++i) {
    d.x_min = x(rng), d.y_min = y(rng), d.x_max = d.x_min + s(rng), d.y_max = d.y_min + s(rng);
    d.score = 0.5f;
    many.detections.push_back(d);
  }
  pub_.det.publish(many);
  kf_pub_.publish(keyframe_at(1000002, t1));
  EXPECT_TRUE(wait_for([&] { return rec_.has_kf_objects(t1); }, 30.0)) << "keyframe with 1000 detections not processed";
  {
    std::lock_guard<std::mutex> l(rec_.mutex);
    const auto& m = rec_.kf_objects[t1.toSec()];
    EXPECT_LT(m.detections.detections.size(), 1000u) << "the filter's cap on detections per keyframe";
    EXPECT_EQ(m.object_ids.size(), m.detections.detections.size());
  }
  EXPECT_TRUE(wait_for([&] { return rec_.logged("beyond the per-keyframe limit"); }, 5.0))
      << "no log line about the detections over the limit";
  // (c) an unsupported depth encoding: used without depth
  const ros::Time t2 = t1 + ros::Duration(0.1);
  dqo_map::KeyFrame odd = keyframe_at(1000003, t2);
  odd.depth.encoding = "yuv422";
  pub_.det.publish(detections_at(t2));
  kf_pub_.publish(odd);
  EXPECT_TRUE(wait_for([&] { return rec_.has_kf_objects(t2); }, 20.0)) << "keyframe with an unsupported depth not processed";
  EXPECT_TRUE(wait_for([&] { return rec_.logged("yuv422"); }, 5.0)) << "no log line naming the depth encoding";
  // (d) a keyframe whose detections never come, then detections of no keyframe far later: the
  // keyframe expires with a log line, the detections are dropped. In either order of arrival: a
  // keyframe expires once a stamp buffer_seconds newer is seen on either stream (stamp_matcher.h).
  const ros::Time t3 = t2 + ros::Duration(0.1);
  kf_pub_.publish(keyframe_at(1000004, t3));
  pub_.det.publish(detections_at(t3 + ros::Duration(20.0)));
  pub_.det.publish(detections_at(t3 + ros::Duration(20.5)));
  EXPECT_TRUE(wait_for([&] { return rec_.logged("got no detections"); }, 10.0)) << "no log line about the lonely keyframe";
  EXPECT_FALSE(rec_.has_kf_objects(t3));
  // (e) time goes back (a looping bag): buffers cleared, logged
  pub_.det.publish(detections_at(captures_.front().stamp));
  EXPECT_TRUE(wait_for([&] { return rec_.logged("time went back"); }, 10.0)) << "no log line about the time jump";

  // (f) a detector gone wrong for 8 keyframes: every label flipped every keyframe and 50 clutter
  // boxes beside the real ones; then (g) one that sees nothing for 8 keyframes (objects it had
  // confirmed stay: the depth still shows them).
  std::vector<std::pair<int, std::string>> classes;
  for (const auto& det : captures_.back().detections.detections) classes.emplace_back(det.class_id, det.class_name);
  ros::Time tf = t3 + ros::Duration(30.0);
  for (int k = 0; k < 16; ++k, tf += ros::Duration(0.1)) {
    dqo_map::DetectionArray wrong = detections_at(tf);
    if (k < 8) {
      for (size_t i = 0; i < wrong.detections.size(); ++i) {
        const auto& c = classes[(i + 1 + static_cast<size_t>(k)) % classes.size()];
        wrong.detections[i].class_id = c.first;
        wrong.detections[i].class_name = c.second;
      }
      for (int i = 0; i < 50; ++i) {
        d.x_min = x(rng), d.y_min = y(rng), d.x_max = d.x_min + 20.f + s(rng), d.y_max = d.y_min + 20.f + s(rng);
        d.class_id = 76, d.class_name = "scissors", d.score = 0.4f;
        wrong.detections.push_back(d);
      }
    } else {
      wrong.detections.clear();
    }
    pub_.det.publish(wrong);
    kf_pub_.publish(keyframe_at(1000010 + static_cast<uint64_t>(k), tf));
    EXPECT_TRUE(wait_for([&] { return rec_.has_kf_objects(tf); }, 20.0)) << "keyframe " << k << " of the bad detector not processed";
  }
  EXPECT_TRUE(wait_for([&] { return rec_.logged("started candidates"); }, 5.0)) << "no log line counting the clutter";

  // ---- still alive, and bad input made no confirmed object
  bool ok = false;
  const auto after = list("", &ok);
  ASSERT_TRUE(ok) << "association_node no longer answers list_objects";
  std::set<uint64_t> before_ids, after_ids;
  for (const auto& o : final_array.objects) before_ids.insert(o.id);
  for (const auto& o : after) after_ids.insert(o.id);
  EXPECT_EQ(after_ids, before_ids);
  {
    std::lock_guard<std::mutex> l(rec_.mutex);
    EXPECT_GT(rec_.arrays.size(), arrays_before_bad) << "objects are still published after bad input";
    for (const auto& o : rec_.arrays.back().objects) {
      if (before_ids.count(o.id)) {
        EXPECT_EQ(o.num_gaussians, 1000 + o.id) << "objects topic: Gaussian count of " << o.id;
      }
    }
  }
}

// association_node restarted (its own instance in /dqo_restart, fed the first test's keyframes):
// against the same map it resumes its objects; against another map (a new tracker run) it resumes
// none, and the IDs it gives next are new; with fresh it resumes none either; IDs are never reused.
TEST_F(AssociationNodeTest, RestartResumesOnlyObjectsOfItsMap) {
  ASSERT_GE(recorded_.size(), 15u) << "needs the keyframes of ObjectsIdsOutputsAndBadInput";
  const fs::path state_dir = dqo::ros_test::make_test_dir("dqo_association_restart_");
  ASSERT_FALSE(state_dir.empty());
  const std::string ns = "/dqo_restart";
  ros::NodeHandle nh;
  // The launch file's parameters of /dqo_map/association, for the node of this test.
  XmlRpc::XmlRpcValue params;
  ASSERT_TRUE(nh.getParam("/dqo_map/association", params));
  nh.setParam(ns + "/association", params);
  ros::Publisher map_id_pub = nh.advertise<std_msgs::String>(ns + "/map_id", 1, /*latch=*/true);
  ros::Publisher kf_pub = nh.advertise<dqo_map::KeyFrame>(ns + "/keyframes", 20);
  ros::Publisher det_pub = nh.advertise<dqo_map::DetectionArray>(ns + "/detections", 20);
  ros::Publisher info_pub = nh.advertise<sensor_msgs::CameraInfo>(ns + "/rgb/camera_info", 1, /*latch=*/true);
  std::mutex mutex;
  std::set<double> processed;
  std::vector<dqo_map::ObjectEvent> events;
  ros::Subscriber kfo_sub = nh.subscribe<dqo_map::KeyFrameObjects>(ns + "/keyframe_objects", 50,
      [&](const dqo_map::KeyFrameObjects::ConstPtr& m) { std::lock_guard<std::mutex> l(mutex); processed.insert(m->header.stamp.toSec()); });
  ros::Subscriber events_sub = nh.subscribe<dqo_map::ObjectEvent>(ns + "/object_events", 1000,
      [&](const dqo_map::ObjectEvent::ConstPtr& m) { std::lock_guard<std::mutex> l(mutex); events.push_back(*m); });
  info_pub.publish(captures_.front().info);
  auto set_map = [&](const std::string& id) {
    std_msgs::String m;
    m.data = id;
    map_id_pub.publish(m);
  };
  const std::string service = ns + "/list_objects";
  dqo::ros_test::NodeProcess node;
  // Starts the node and waits (20 s) until it listens and answers.
  auto start = [&](bool fresh) {
    const bool started = node.start(DQO_ASSOCIATION_NODE, {"__ns:=" + ns, "__name:=association", "_output_dir:=" + state_dir.string(),
                                                           "_publish_tf:=false", std::string("_fresh:=") + (fresh ? "true" : "false")});
    return started && wait_for([&] {
      return kf_pub.getNumSubscribers() > 0 && det_pub.getNumSubscribers() > 0 && map_id_pub.getNumSubscribers() > 0 &&
             info_pub.getNumSubscribers() > 0 && kfo_sub.getNumPublishers() > 0 && ros::service::exists(service, false);
    }, 20.0);
  };
  // Feeds recorded keyframes [from, to) with their detections, each waiting for its result.
  auto feed = [&](size_t from, size_t to, double seconds) {
    dqo::ros_test::Budget budget(seconds);
    size_t done = 0;
    for (size_t k = from; k < to && k < recorded_.size() && !budget.expired(); ++k) {
      det_pub.publish(recorded_[k].second);
      kf_pub.publish(recorded_[k].first);
      const double t = recorded_[k].first.header.stamp.toSec();
      done += wait_for([&] { std::lock_guard<std::mutex> l(mutex); return processed.count(t) > 0; }, budget.take(5.0));
    }
    return done;
  };
  auto ids_of = [&](bool* ok) {
    std::set<uint64_t> ids;
    for (const auto& o : list("", ok, nullptr, service)) ids.insert(o.id);
    return ids;
  };
  bool ok = false;

  // 1. Map A: objects made.
  set_map("tracker:map:A");
  ASSERT_TRUE(start(false)) << "association_node (map A) did not come up";
  EXPECT_EQ(feed(0, 15, 40.0), 15u) << "keyframes processed of 15";
  std::set<uint64_t> ids_a = ids_of(&ok);
  ASSERT_TRUE(ok);
  ASSERT_FALSE(ids_a.empty()) << "no object confirmed from 15 keyframes";
  uint64_t max_id = 0;
  {
    std::lock_guard<std::mutex> l(mutex);
    for (const auto& e : events) max_id = std::max(max_id, e.id);
  }
  EXPECT_TRUE(node.stop(10.0)) << "association_node did not stop on SIGINT";

  // 2. Map A again: the same objects.
  ASSERT_TRUE(start(false)) << "association_node (map A, restarted) did not come up";
  EXPECT_EQ(ids_of(&ok), ids_a) << "objects of the same map not resumed";
  EXPECT_TRUE(node.stop(10.0));

  // 3. Map B (a new tracker run): none resumed, then new objects with new IDs.
  set_map("tracker:map:B");
  ASSERT_TRUE(start(false)) << "association_node (map B) did not come up";
  EXPECT_TRUE(wait_for([&] { bool listed = false; return ids_of(&listed).empty() && listed; }, 10.0))
      << "objects of map A resumed into map B";
  {
    std::lock_guard<std::mutex> l(mutex);
    processed.clear();
    events.clear();
  }
  EXPECT_EQ(feed(15, 30, 30.0), 15u) << "keyframes processed of 15 in map B";
  const std::set<uint64_t> ids_b = ids_of(&ok);
  EXPECT_FALSE(ids_b.empty()) << "no object confirmed in map B";
  {
    std::lock_guard<std::mutex> l(mutex);
    for (const auto& e : events) {
      if (e.type == dqo_map::ObjectEvent::CREATED) {
        EXPECT_GT(e.id, max_id) << "ID " << e.id << " reused in map B";
      }
      max_id = std::max(max_id, e.id);
    }
  }
  EXPECT_TRUE(node.stop(10.0));
  {
    std::ifstream state(state_dir / "objects_state.yaml");
    std::stringstream text;
    text << state.rdbuf();
    EXPECT_NE(text.str().find("\nmap tracker:map:B\n"), std::string::npos) << "the state file names no map B";
  }

  // 4. fresh: none resumed (not even map B's own), and IDs still go on.
  ASSERT_TRUE(start(true)) << "association_node (fresh) did not come up";
  EXPECT_TRUE(ids_of(&ok).empty() && ok) << "objects resumed despite fresh";
  EXPECT_TRUE(node.stop(10.0));
  dqo::objects::ObjectMapper restored;
  std::string error;
  ASSERT_TRUE(restored.load_state((state_dir / "objects_state.yaml").string(), &error)) << error;
  EXPECT_GT(restored.next_id(), max_id) << "the ID counter went back";
  std::error_code ec;
  fs::remove_all(state_dir, ec);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_association_node");
  ros::NodeHandle nh;  // keeps the node alive for the whole run
  return RUN_ALL_TESTS();
}
