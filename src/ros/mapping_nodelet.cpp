// dqo_map/MappingNodelet: the mapping stage (GaussianMapper) behind topics and services (DESIGN.md
// "mapping nodelet"). Inputs: keyframes, keyframe_poses, keyframe_objects, objects, object_events
// (and map_id, the tracker's map identity). Outputs: map_render / map_render_ids (the map from the
// latest mapped keyframe), gaussians (PointCloud2, throttled), mapped_objects (the objects with
// their Gaussian counts, latched), /diagnostics. Services: get_object, extract_object, save_map,
// load_map. The stage runs on MappingWorker's thread: input callbacks convert and queue and never
// wait for mapping; services run on the nodelet's multi-threaded queue and wait at most for the
// mapping step in progress. Timers never wait for a step: diagnostics and progress come from the
// worker's snapshot (taken between steps) and counters; the render and the cloud skip a round when
// the mapper is busy. The gaussians cloud is latched (a restarted rviz sees the map at once).
//
// Shutdown (the destructor: the manager's SIGINT, or an unload): the step in progress is cut
// short (the trainer's stop flag) and waited for at most shutdown_timeout seconds, the queued
// keyframes are dropped, inputs and timers stop, then the map of the keyframes mapped is written
// to the autosave (config/mapping_node.yaml says how this stays under roslaunch's SIGTERM).
//
// Files: everything under output_dir; the autosave (autosave_file, every autosave_period seconds
// when something changed, and at shutdown) is what a restarted nodelet resumes from when `resume`
// is on and the autosave belongs to the same map (map_id).

#include <algorithm>
#include <chrono>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <dqo_map/ExtractObject.h>
#include <dqo_map/GetObject.h>
#include <dqo_map/KeyFrame.h>
#include <dqo_map/KeyFrameObjects.h>
#include <dqo_map/KeyFramePoses.h>
#include <dqo_map/LoadMap.h>
#include <dqo_map/ObjectArray.h>
#include <dqo_map/ObjectEvent.h>
#include <dqo_map/SaveMap.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/String.h>

#include "conversions.h"
#include "dqo_map/common/atomic_file.h"
#include "dqo_map/common/output_path.h"
#include "dqo_map/common/stopwatch.h"
#include "dqo_map/mapping/map_file.h"
#include "dqo_map/mapping/mapping_worker.h"
#include "dqo_map/mapping/params_yaml.h"
#include "dqo_map/system/object_export.h"
#include "dqo_map/system/offline_report.h"
#include "mapping_conversions.h"
#include "ros_params.h"

namespace dqo_map {

namespace fs = std::filesystem;
using dqo::mapping::GaussianMapper;
using dqo::mapping::MappingWorker;

class MappingNodelet : public nodelet::Nodelet {
 public:
  ~MappingNodelet() override;

 private:
  struct Params {
    std::string map_frame = "map";
    std::string output_dir;            // empty: $ROS_HOME/dqo_map
    std::string autosave_file = "autosave.dqomap";
    double autosave_period = 30.0;     // seconds; 0: only at shutdown; < 0: never
    bool resume = true;                // start from the autosave (same map only)
    double render_period = 2.0;        // seconds between map_render images (when subscribed)
    double gaussians_period = 5.0;     // seconds between gaussians clouds (when subscribed)
    int gaussians_max_points = 300000; // every k-th Gaussian so that the cloud stays below this
    double diagnostics_period = 1.0;
    double progress_period = 10.0;     // seconds between progress lines in the log
    int queue_size = 20;               // keyframe subscriber queue (each carries its images)
    // Seconds without a new keyframe after which keyframes still waiting for their objects are
    // mapped as background: the input stopped (a bag ended, a detector died), so keyframe time,
    // which objects_timeout counts, stands still.
    double idle_flush = 10.0;
    // Seconds the shutdown waits for the mapping step in progress (cut short at its next training
    // iteration) before it saves; see config/mapping_node.yaml.
    double shutdown_timeout = 5.0;
    // Wall seconds from the start without any keyframe before the status turns WARN (<= 0: never).
    double input_warn = 30.0;
  };

  void onInit() override;
  bool read_params(std::string* error);
  std::shared_ptr<MappingWorker> worker() const {
    std::lock_guard<std::mutex> lock(worker_mutex_);
    return worker_;
  }
  // False (nothing replaced) once shutdown began.
  bool start_worker(bool resume);

  // Inputs (single-threaded queue, in arrival order).
  void on_keyframe(const dqo_map::KeyFrame::ConstPtr& msg);
  void on_keyframe_objects(const dqo_map::KeyFrameObjects::ConstPtr& msg);
  void on_keyframe_poses(const dqo_map::KeyFramePoses::ConstPtr& msg);
  void on_objects(const dqo_map::ObjectArray::ConstPtr& msg);
  void on_event(const dqo_map::ObjectEvent::ConstPtr& msg);
  void on_map_id(const std_msgs::String::ConstPtr& msg);

  // Timers (multi-threaded queue).
  void on_reports(const ros::WallTimerEvent&);
  void on_status(const ros::WallTimerEvent&);
  void shutdown();
  void on_autosave(const ros::WallTimerEvent&);
  void publish_diagnostics();
  // False when the mapper was busy (a step in progress): nothing published, tried again later.
  bool publish_render();
  bool publish_gaussians();
  void publish_mapped_objects();

  // Services (multi-threaded queue).
  bool get_object(dqo_map::GetObject::Request& req, dqo_map::GetObject::Response& res);
  bool extract_object(dqo_map::ExtractObject::Request& req, dqo_map::ExtractObject::Response& res);
  bool save_map(dqo_map::SaveMap::Request& req, dqo_map::SaveMap::Response& res);
  bool load_map(dqo_map::LoadMap::Request& req, dqo_map::LoadMap::Response& res);

  // Saves the map to `path` (snapshot under the mapper's lock, written outside it) with the map
  // identity beside it; false and *error when it cannot be written.
  bool save_to(const std::string& path, std::string* error);
  std::string map_id_path(const std::string& map_path) const { return map_path + ".map_id"; }
  std_msgs::Header header() const;

  Params p_;
  dqo::mapping::GaussianMapperParams mapper_params_;
  std::string autosave_path_;

  mutable std::mutex worker_mutex_;
  std::shared_ptr<MappingWorker> worker_;  // replaced on a new map (map_id) or never
  bool shutting_down_ = false;             // guarded by worker_mutex_: no new worker from then on

  mutable std::mutex state_mutex_;  // guards the fields below
  std::string map_id_;              // the tracker's map identity (empty until it says)
  std::string resumed_map_id_;      // the autosave's, when the map came from it
  uint64_t next_object_id_ = 1;     // one past the largest object ID seen
  double last_stamp_ = 0.0;         // newest keyframe stamp, for time jumps
  std::vector<double> step_ms_;     // recent mapping steps
  dqo::mapping::MappingReport last_report_;
  bool have_report_ = false;

  std::atomic<uint64_t> received_{0}, refused_{0}, mapped_{0}, dropped_{0}, errors_{0};
  std::atomic<uint64_t> mapped_at_save_{0}, mapped_at_render_{0}, mapped_at_cloud_{0};
  std::atomic<bool> objects_dirty_{false};
  ros::WallTime last_progress_, last_render_, last_cloud_, last_objects_;
  std::atomic<int64_t> last_keyframe_wall_ns_{0};  // wall time of the newest keyframe
  const ros::WallTime started_ = ros::WallTime::now();
  std::atomic<bool> flushed_idle_{false};          // flushed since that keyframe
  uint64_t mapped_at_progress_ = 0;

  ros::Subscriber keyframe_sub_, kf_objects_sub_, poses_sub_, objects_sub_, events_sub_, map_id_sub_;
  ros::Publisher render_pub_, render_ids_pub_, cloud_pub_, diag_pub_, objects_pub_;
  ros::ServiceServer get_srv_, extract_srv_, save_srv_, load_srv_;
  ros::WallTimer report_timer_, status_timer_, autosave_timer_;
  std::atomic<bool> cloud_stale_{true};  // the latched cloud is not of the current map
};

MappingNodelet::~MappingNodelet() { shutdown(); }

// Shutdown's lines go to stderr, which roslaunch shows (output=screen) or keeps in the node's log:
// during a manager's shutdown rosconsole's output was seen to get lost (the lines of an unload
// run while ros::shutdown is under way), and /rosout is gone by then anyway.
#define DQO_SHUTDOWN_LOG(level, ...)                                                  \
  do {                                                                                \
    std::fprintf(stderr, "[" #level "] [%.3f] ", ros::WallTime::now().toSec());       \
    std::fprintf(stderr, __VA_ARGS__);                                                \
    std::fprintf(stderr, "\n");                                                       \
  } while (false)

void MappingNodelet::shutdown() {
  // Inputs, timers and services may be waiting for the step in progress (a new map's save, a
  // query), and stopping a subscriber, timer or service waits for its callback in progress: so the
  // step is cut short first, then they are stopped. No new map is started from here on.
  std::shared_ptr<MappingWorker> w;
  {
    std::lock_guard<std::mutex> lock(worker_mutex_);
    shutting_down_ = true;
    w = worker_;
  }
  const auto t0 = std::chrono::steady_clock::now();
  const double step = w ? w->step_seconds() : 0.0;
  // Keyframes that are mapped are saved; those still queued are dropped (the tracker's next run
  // gives new ones) and the step in progress is cut short: shutdown must end before roslaunch
  // escalates to SIGTERM.
  const bool stopped = !w || w->stop(p_.shutdown_timeout);
  if (stopped) {
    for (ros::Subscriber* s : {&keyframe_sub_, &kf_objects_sub_, &poses_sub_, &objects_sub_, &events_sub_,
                               &map_id_sub_}) {
      s->shutdown();
    }
    report_timer_.stop();
    status_timer_.stop();
    autosave_timer_.stop();
  }
  if (!w) return;
  if (!stopped) {
    DQO_SHUTDOWN_LOG(ERROR, "mapping: the mapping step in progress did not end within shutdown_timeout (%.1f s): "
                     "exiting without saving (the last autosave, %s, stays)", p_.shutdown_timeout,
                     autosave_path_.c_str());
    // Its thread still uses the worker, and callbacks may wait for it: both must outlive this
    // nodelet (the process is ending).
    new std::shared_ptr<MappingWorker>(w);  // NOLINT: deliberately never freed
    return;
  }
  mapped_ += w->take_reports().size();
  if (p_.autosave_period < 0.0) return;
  if (mapped_.load() == mapped_at_save_.load()) {
    DQO_SHUTDOWN_LOG(INFO, "mapping: shutdown: nothing mapped since the last autosave (%s)", autosave_path_.c_str());
    return;
  }
  std::string error;
  const dqo::mapping::MappingStatus status = w->status();
  if (save_to(autosave_path_, &error)) {
    DQO_SHUTDOWN_LOG(INFO, "mapping: saved the map (%zu keyframes, %zu Gaussians) to %s at shutdown, %.1f s after it "
                     "began%s", status.keyframes_in_map, status.gaussians, autosave_path_.c_str(),
                     dqo::ms_since(t0) / 1000.0, step > 0.0 ? " (the mapping step in progress was cut short)" : "");
  } else {
    DQO_SHUTDOWN_LOG(ERROR, "mapping: shutdown autosave failed: %s", error.c_str());
  }
}

bool MappingNodelet::read_params(std::string* error) {
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  pnh.param("map_frame", p_.map_frame, p_.map_frame);
  pnh.param("output_dir", p_.output_dir, p_.output_dir);
  pnh.param("autosave_file", p_.autosave_file, p_.autosave_file);
  pnh.param("autosave_period", p_.autosave_period, p_.autosave_period);
  pnh.param("resume", p_.resume, p_.resume);
  pnh.param("render_period", p_.render_period, p_.render_period);
  pnh.param("gaussians_period", p_.gaussians_period, p_.gaussians_period);
  pnh.param("gaussians_max_points", p_.gaussians_max_points, p_.gaussians_max_points);
  pnh.param("diagnostics_period", p_.diagnostics_period, p_.diagnostics_period);
  pnh.param("progress_period", p_.progress_period, p_.progress_period);
  pnh.param("queue_size", p_.queue_size, p_.queue_size);
  pnh.param("idle_flush", p_.idle_flush, p_.idle_flush);
  pnh.param("shutdown_timeout", p_.shutdown_timeout, p_.shutdown_timeout);
  pnh.param("input_warn", p_.input_warn, p_.input_warn);
  const std::set<std::string> known = {"map_frame",          "output_dir",       "autosave_file",
                                       "autosave_period",    "resume",           "render_period",
                                       "gaussians_period",   "gaussians_max_points", "diagnostics_period",
                                       "progress_period",    "queue_size",       "idle_flush", "shutdown_timeout",
                                       "input_warn",         "mapping"};
  for (const std::string& name : dqo::ros_bridge::unknown_private_params(pnh, known)) {
    NODELET_WARN("mapping: ignoring unknown parameter %s/%s", pnh.getNamespace().c_str(), name.c_str());
  }
  if (p_.autosave_file.empty() || fs::path(p_.autosave_file).has_parent_path() || p_.render_period <= 0.0 ||
      p_.gaussians_period <= 0.0 || p_.gaussians_max_points < 1 || p_.diagnostics_period <= 0.0 ||
      p_.progress_period <= 0.0 || p_.queue_size < 1 || p_.idle_flush <= 0.0 || !(p_.shutdown_timeout >= 0.0)) {
    *error = "autosave_file must be a plain file name, the periods and idle_flush > 0, shutdown_timeout >= 0, "
             "gaussians_max_points and queue_size >= 1";
    return false;
  }
  // ~mapping through the same strict loader as dqo_map_offline --config.
  XmlRpc::XmlRpcValue value;
  std::string text = "{}";
  if (pnh.getParam("mapping", value)) text = "{\"mapping\": " + dqo::ros_bridge::to_yaml(value) + "}";
  auto params = dqo::mapping::parse_mapping_params(text, "ROS parameters of " + pnh.getNamespace(), error, {},
                                                   /*positions=*/false);
  if (!params) return false;
  mapper_params_ = *params;
  if (p_.output_dir.empty()) p_.output_dir = dqo::ros_bridge::default_output_dir();
  std::error_code ec;
  fs::create_directories(p_.output_dir, ec);
  if (ec || !fs::is_directory(p_.output_dir)) {
    *error = "cannot create the output folder " + p_.output_dir + (ec ? ": " + ec.message() : "");
    return false;
  }
  p_.output_dir = fs::canonical(p_.output_dir).string();
  autosave_path_ = (fs::path(p_.output_dir) / p_.autosave_file).string();
  return true;
}

bool MappingNodelet::start_worker(bool resume) {
  auto w = std::make_shared<MappingWorker>(mapper_params_);
  if (resume && fs::exists(autosave_path_)) {
    std::string error, warning;
    auto contents = dqo::mapping::load_map_file(autosave_path_, &error);
    if (!contents) {
      // A damaged autosave must not stop mapping; it stays for a human to look at.
      NODELET_ERROR("mapping: cannot resume: %s; starting an empty map", error.c_str());
    } else {
      std::string map_id;
      std::ifstream(map_id_path(autosave_path_)) >> map_id;
      const size_t gaussians = contents->gaussians.size(), keyframes = contents->keyframes.size();
      const uint64_t next = contents->next_object_id;
      w->with_mapper([&](GaussianMapper& m) { m.restore(std::move(*contents), &warning); });
      if (!warning.empty()) NODELET_WARN("mapping: %s", warning.c_str());
      std::lock_guard<std::mutex> lock(state_mutex_);
      resumed_map_id_ = map_id;
      next_object_id_ = std::max(next_object_id_, next);
      NODELET_INFO("mapping: resumed %zu Gaussians and %zu keyframes from %s (map '%s')", gaussians, keyframes,
                   autosave_path_.c_str(), map_id.c_str());
    }
  }
  std::lock_guard<std::mutex> lock(worker_mutex_);
  if (shutting_down_) return false;  // a new map announced during shutdown: the old one is saved
  worker_ = std::move(w);
  return true;
}

void MappingNodelet::onInit() {
  std::string error;
  if (!read_params(&error)) {
    NODELET_FATAL("mapping: %s", error.c_str());
    return;
  }
  try {
    start_worker(p_.resume);
  } catch (const std::exception& e) {
    NODELET_FATAL("mapping: %s", e.what());
    return;
  }
  ros::NodeHandle& nh = getNodeHandle();      // inputs: one thread, arrival order
  ros::NodeHandle& mt = getMTNodeHandle();    // services and timers: beside the inputs
  keyframe_sub_ = nh.subscribe("keyframes", p_.queue_size, &MappingNodelet::on_keyframe, this);
  kf_objects_sub_ = nh.subscribe("keyframe_objects", 100, &MappingNodelet::on_keyframe_objects, this);
  poses_sub_ = nh.subscribe("keyframe_poses", 10, &MappingNodelet::on_keyframe_poses, this);
  objects_sub_ = nh.subscribe("objects", 10, &MappingNodelet::on_objects, this);
  events_sub_ = nh.subscribe("object_events", 1000, &MappingNodelet::on_event, this);
  map_id_sub_ = nh.subscribe("map_id", 1, &MappingNodelet::on_map_id, this);
  // Latched like the cloud: a restarted rviz shows the last render at once, not "No Image".
  render_pub_ = mt.advertise<sensor_msgs::Image>("map_render", 1, /*latch=*/true);
  render_ids_pub_ = mt.advertise<sensor_msgs::Image>("map_render_ids", 1, /*latch=*/true);
  // Latched: a restarted rviz (or any late subscriber) gets the latest map at once.
  cloud_pub_ = mt.advertise<sensor_msgs::PointCloud2>("gaussians", 1, /*latch=*/true);
  objects_pub_ = mt.advertise<dqo_map::ObjectArray>("mapped_objects", 1, /*latch=*/true);
  diag_pub_ = mt.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10);
  get_srv_ = mt.advertiseService("get_object", &MappingNodelet::get_object, this);
  extract_srv_ = mt.advertiseService("extract_object", &MappingNodelet::extract_object, this);
  save_srv_ = mt.advertiseService("save_map", &MappingNodelet::save_map, this);
  load_srv_ = mt.advertiseService("load_map", &MappingNodelet::load_map, this);
  report_timer_ = mt.createWallTimer(ros::WallDuration(0.1), &MappingNodelet::on_reports, this);
  status_timer_ = mt.createWallTimer(ros::WallDuration(p_.diagnostics_period), &MappingNodelet::on_status, this);
  if (p_.autosave_period > 0.0) {
    autosave_timer_ = mt.createWallTimer(ros::WallDuration(p_.autosave_period), &MappingNodelet::on_autosave, this);
  }
  last_progress_ = last_render_ = last_cloud_ = last_objects_ = ros::WallTime::now();
  NODELET_INFO("mapping: backend %s, output folder %s, autosave %s every %.0f s, max_queue %d, max_gaussians %d",
               dqo::mapping::to_string(mapper_params_.backend), p_.output_dir.c_str(), autosave_path_.c_str(),
               p_.autosave_period, mapper_params_.max_queue, mapper_params_.max_gaussians);
}

std_msgs::Header MappingNodelet::header() const {
  std_msgs::Header h;
  h.stamp = ros::Time::now();
  h.frame_id = p_.map_frame;
  return h;
}

// ---------------------------------------------------------------- inputs

void MappingNodelet::on_keyframe(const dqo_map::KeyFrame::ConstPtr& msg) {
  dqo::mapping::MappingKeyframe kf;
  std::string error;
  if (!dqo::ros_bridge::from_keyframe_msg(*msg, &kf, &error)) {
    ++refused_;
    NODELET_WARN_THROTTLE(5.0, "mapping: skipping %s", error.c_str());
    return;
  }
  const auto w = worker();
  if (!w) return;
  double jump = 0.0;
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    if (last_stamp_ > 0.0 && kf.stamp < last_stamp_ - 1.0) jump = last_stamp_ - kf.stamp;
    last_stamp_ = kf.stamp;
  }
  if (jump > 0.0) {
    // A bag that loops (or a restarted recording): keyframe time goes back. The keyframes waiting
    // for their objects are keyed to the old time line, so they are mapped now rather than left
    // waiting for a timeout that the new time line would take long to reach.
    NODELET_WARN("mapping: keyframe time jumped back %.1f s (a looping bag?): mapping the waiting keyframes now",
                 jump);
    w->flush();  // in the worker's inbox before this keyframe: acts on the old time line only
  }
  ++received_;
  last_keyframe_wall_ns_ = static_cast<int64_t>(ros::WallTime::now().toNSec());
  flushed_idle_ = false;
  w->add_keyframe(std::move(kf));
}

void MappingNodelet::on_keyframe_objects(const dqo_map::KeyFrameObjects::ConstPtr& msg) {
  dqo::mapping::KeyframeObjects objects;
  std::string error;
  if (!dqo::ros_bridge::from_keyframe_objects_msg(*msg, &objects, &error)) {
    ++refused_;
    NODELET_WARN_THROTTLE(5.0, "mapping: skipping %s", error.c_str());
    return;
  }
  if (const auto w = worker()) w->add_keyframe_objects(std::move(objects));
}

void MappingNodelet::on_keyframe_poses(const dqo_map::KeyFramePoses::ConstPtr& msg) {
  std::string error;
  auto poses = dqo::ros_bridge::from_keyframe_poses_msg(*msg, &error);
  if (!poses) {
    ++refused_;
    NODELET_WARN_THROTTLE(5.0, "mapping: skipping %s", error.c_str());
    return;
  }
  if (const auto w = worker()) w->set_keyframe_poses(std::move(*poses));
}

void MappingNodelet::on_objects(const dqo_map::ObjectArray::ConstPtr& msg) {
  std::vector<dqo::mapping::ObjectRecord> records;
  uint64_t max_id = 0;
  for (const dqo_map::Object& o : msg->objects) {
    if (auto r = dqo::ros_bridge::from_object_msg(o)) {
      records.push_back(std::move(*r));
      max_id = std::max<uint64_t>(max_id, o.id);
    } else {
      NODELET_WARN_THROTTLE(5.0, "mapping: object %llu has no proper ellipsoid: left out",
                            static_cast<unsigned long long>(o.id));
    }
  }
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    next_object_id_ = std::max(next_object_id_, max_id + 1);
  }
  if (const auto w = worker()) w->set_objects(std::move(records));
  objects_dirty_ = true;
}

void MappingNodelet::on_event(const dqo_map::ObjectEvent::ConstPtr& msg) {
  auto event = dqo::ros_bridge::from_event_msg(*msg);
  if (!event) return;  // CONFIRMED and later kinds: nothing for the Gaussians to do
  if (const auto w = worker()) w->apply_event(*event);
  objects_dirty_ = true;
}

void MappingNodelet::on_map_id(const std_msgs::String::ConstPtr& msg) {
  std::string previous, resumed;
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    previous = map_id_;
    resumed = resumed_map_id_;
  }
  if (msg->data == previous) return;
  const bool from_other_map = previous.empty() ? (!resumed.empty() && resumed != msg->data) : true;
  if (!from_other_map) {
    std::lock_guard<std::mutex> lock(state_mutex_);
    map_id_ = msg->data;
    resumed_map_id_.clear();
    NODELET_INFO("mapping: map '%s'%s", msg->data.c_str(), resumed.empty() ? "" : " (resumed)");
    return;
  }
  // The tracker started a new map: the Gaussians of the old one are in another frame. Keep them in
  // a file of their own (saved under the old identity: map_id_ changes only once the new map is
  // in place, so that neither the file nor the diagnostics mix the two) and start empty.
  const std::string old_id = previous.empty() ? resumed : previous;
  const std::string kept = (fs::path(p_.output_dir) / ("map_" + old_id + ".dqomap")).string();
  std::string error;
  const auto w = worker();
  const size_t had = w ? w->status().gaussians : 0;
  if (had > 0 && dqo::resolve_output_path(p_.output_dir, "map_" + old_id + ".dqomap", &error) &&
      save_to(kept, &error)) {
    NODELET_WARN("mapping: new map '%s' (was '%s'): the old map's %zu Gaussians are kept in %s; starting empty",
                 msg->data.c_str(), old_id.c_str(), had, kept.c_str());
  } else if (had > 0) {
    NODELET_WARN("mapping: new map '%s' (was '%s'): the old map is dropped (%s); starting empty", msg->data.c_str(),
                 old_id.c_str(), error.c_str());
  } else {
    NODELET_INFO("mapping: new map '%s' (was '%s', empty)", msg->data.c_str(), old_id.c_str());
  }
  if (!start_worker(/*resume=*/false)) return;
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    map_id_ = msg->data;
    resumed_map_id_.clear();
  }
  mapped_at_save_ = mapped_.load();
  cloud_stale_ = true;  // the latched cloud shows the old map
}

// ---------------------------------------------------------------- timers

void MappingNodelet::on_reports(const ros::WallTimerEvent&) {
  const auto w = worker();
  if (!w) return;
  for (const std::string& e : w->take_errors()) {
    ++errors_;
    NODELET_WARN("mapping: %s", e.c_str());
  }
  std::vector<dqo::mapping::MappingReport> reports = w->take_reports();
  if (!reports.empty()) {
    std::lock_guard<std::mutex> lock(state_mutex_);
    for (const auto& r : reports) {
      step_ms_.push_back(r.total_ms);
      dropped_ = r.dropped_total;
    }
    if (step_ms_.size() > 50) step_ms_.erase(step_ms_.begin(), step_ms_.end() - 50);
    last_report_ = reports.back();
    have_report_ = true;
    mapped_ += reports.size();
    objects_dirty_ = true;
  }
  const ros::WallTime now = ros::WallTime::now();
  const int64_t last_kf = last_keyframe_wall_ns_.load();
  if (last_kf > 0 && !flushed_idle_ && (static_cast<int64_t>(now.toNSec()) - last_kf) * 1e-9 >= p_.idle_flush) {
    flushed_idle_ = true;
    const size_t waiting = w->status().waiting;
    if (waiting > 0) {
      NODELET_INFO("mapping: no keyframe for %.0f s: mapping the %zu keyframes still waiting for their objects as "
                   "background", p_.idle_flush, waiting);
      w->flush();
    }
  }
  if ((now - last_objects_).toSec() >= 1.0 && objects_dirty_.exchange(false)) {
    last_objects_ = now;
    publish_mapped_objects();
  }
  // The render and the cloud need the map itself: taken when the mapper is free, else tried again
  // at the next tick (the worker then leaves a turn between two steps: try_with_mapper). Never
  // waiting for a step: a timer callback in progress holds up stopping the timer (shutdown).
  if ((now - last_render_).toSec() >= p_.render_period && mapped_.load() != mapped_at_render_.load() &&
      (render_pub_.getNumSubscribers() > 0 || render_ids_pub_.getNumSubscribers() > 0)) {
    const uint64_t mapped = mapped_.load();
    if (publish_render()) {
      last_render_ = now;
      mapped_at_render_ = mapped;
    }
  }
  // Latched, so published also without subscribers: whoever subscribes later gets the latest.
  if ((now - last_cloud_).toSec() >= p_.gaussians_period &&
      (mapped_.load() != mapped_at_cloud_.load() || cloud_stale_.load())) {
    const uint64_t mapped = mapped_.load();
    if (publish_gaussians()) {
      last_cloud_ = now;
      mapped_at_cloud_ = mapped;
      cloud_stale_ = false;
    }
  }
}

// Never takes the mapper's lock: counters, the worker's snapshot and the reports taken so far.
void MappingNodelet::on_status(const ros::WallTimerEvent&) {
  const ros::WallTime now = ros::WallTime::now();
  if ((now - last_progress_).toSec() >= p_.progress_period && mapped_.load() != mapped_at_progress_) {
    const double rate = (mapped_.load() - mapped_at_progress_) / (now - last_progress_).toSec();
    mapped_at_progress_ = mapped_.load();
    last_progress_ = now;
    std::ostringstream objects;
    std::lock_guard<std::mutex> lock(state_mutex_);
    for (const auto& [id, n] : last_report_.gaussians_per_object) {
      if (id != 0) objects << ' ' << id << ':' << n;
    }
    NODELET_INFO("mapping: %llu keyframes mapped (%.2f/s), %zu Gaussians (%zu background), %zu waiting, %llu "
                 "dropped; Gaussians per object:%s",
                 static_cast<unsigned long long>(mapped_.load()), rate, last_report_.num_gaussians,
                 last_report_.gaussians_per_object.count(0) ? last_report_.gaussians_per_object.at(0) : size_t{0},
                 last_report_.queued, static_cast<unsigned long long>(dropped_.load()),
                 objects.str().empty() ? " none yet" : objects.str().c_str());
  }
  publish_diagnostics();
}

void MappingNodelet::publish_diagnostics() {
  const auto w = worker();
  if (!w) return;
  const dqo::mapping::MappingStatus status = w->status();
  const double step_s = w->step_seconds();
  const size_t inbox = w->inbox_size();
  double mean_ms = 0.0, max_ms = 0.0;
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    for (double ms : step_ms_) {
      mean_ms += ms;
      max_ms = std::max(max_ms, ms);
    }
    if (!step_ms_.empty()) mean_ms /= step_ms_.size();
  }
  diagnostic_msgs::DiagnosticStatus s;
  s.name = "dqo_map: mapping " + getName();  // one per nodelet: several may run
  s.hardware_id = dqo::mapping::to_string(mapper_params_.backend);
  s.level = diagnostic_msgs::DiagnosticStatus::OK;
  s.message = "mapping";
  if (dropped_.load() > 0) {
    s.level = diagnostic_msgs::DiagnosticStatus::WARN;
    s.message = "keyframes dropped: mapping is slower than the input (max_queue)";
  } else if (received_.load() == 0) {
    // No keyframe ever: tracking is not running, not initialised (no camera?) or publishes elsewhere.
    const double waited = (ros::WallTime::now() - started_).toSec();
    s.message = "waiting for keyframes";
    if (p_.input_warn > 0.0 && waited >= p_.input_warn) {
      s.level = diagnostic_msgs::DiagnosticStatus::WARN;
      std::ostringstream m;
      m << "no keyframes on " << keyframe_sub_.getTopic() << " for " << static_cast<int>(waited)
        << " s: is tracking running and initialised?";
      s.message = m.str();
    }
  } else if (status.ready + inbox == 0 && status.waiting == 0 && step_s == 0.0) {
    s.message = "idle: every keyframe received is mapped";  // caught up (the end of a bag, a still camera)
  }
  auto kv = [&](const std::string& key, const std::string& value) {
    diagnostic_msgs::KeyValue k;
    k.key = key;
    k.value = value;
    s.values.push_back(k);
  };
  auto num = [](double v) {
    std::ostringstream o;
    o << v;
    return o.str();
  };
  kv("keyframes received", std::to_string(received_.load()));
  kv("keyframes mapped", std::to_string(mapped_.load()));
  kv("keyframes in the map", std::to_string(status.keyframes_in_map));
  kv("keyframes waiting for objects", std::to_string(status.waiting));
  kv("keyframes queued", std::to_string(status.ready + inbox));
  kv("keyframes dropped", std::to_string(dropped_.load()));
  kv("messages refused", std::to_string(refused_.load() + errors_.load()));
  kv("ms per update (mean of last 50)", num(mean_ms));
  kv("ms per update (max of last 50)", num(max_ms));
  kv("mapping step in progress (s)", num(step_s));  // 0: idle
  kv("gaussians", std::to_string(status.gaussians));
  kv("objects", std::to_string(status.objects.size()));
  kv("map memory (MB)", num(status.bytes / 1e6));
  kv("peak resident memory (MB)", num(dqo::system::peak_memory_mb()));
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    kv("map id", map_id_.empty() ? resumed_map_id_ : map_id_);
  }
  diagnostic_msgs::DiagnosticArray a;
  a.header.stamp = ros::Time::now();
  a.status.push_back(s);
  diag_pub_.publish(a);
}

void MappingNodelet::publish_mapped_objects() {
  const auto w = worker();
  if (!w) return;
  dqo_map::ObjectArray a;
  a.header = header();
  for (const auto& o : w->status().objects) {
    if (o.object.id != 0) a.objects.push_back(dqo::ros_bridge::to_object_msg(o));
  }
  objects_pub_.publish(a);
}

bool MappingNodelet::publish_render() {
  const auto w = worker();
  if (!w) return false;
  dqo::gs::RenderOutput r;
  double stamp = 0.0;
  bool have = false;
  const bool ran = w->try_with_mapper([&](GaussianMapper& m) {
    if (m.keyframe_poses().empty()) return;
    const dqo::mapping::KeyframePose& k = m.keyframe_poses().back();
    stamp = k.stamp;
    m.render(k.camera, k.T_wc, &r);
    have = true;
  });
  if (!ran) return false;
  if (!have) return true;
  std_msgs::Header h = header();
  h.stamp = ros::Time(stamp);
  h.frame_id = "";  // an image of the map, seen from the keyframe's camera
  render_pub_.publish(dqo::ros_bridge::to_rgb8_msg(dqo::system::render_colour_image(r), h));
  render_ids_pub_.publish(dqo::ros_bridge::to_rgb8_msg(dqo::system::render_ids_image(r), h));
  return true;
}

bool MappingNodelet::publish_gaussians() {
  const auto w = worker();
  if (!w) return false;
  sensor_msgs::PointCloud2 cloud;
  const bool ran = w->try_with_mapper([&](GaussianMapper& m) {
    const size_t n = m.map().size();
    const size_t stride = (n + p_.gaussians_max_points - 1) / p_.gaussians_max_points;
    cloud = dqo::ros_bridge::to_gaussian_cloud(m.map(), header(), std::max<size_t>(1, stride));
  });
  if (ran) cloud_pub_.publish(cloud);
  return ran;
}

void MappingNodelet::on_autosave(const ros::WallTimerEvent&) {
  if (mapped_.load() == mapped_at_save_.load()) return;
  std::string error;
  const auto t0 = std::chrono::steady_clock::now();
  if (save_to(autosave_path_, &error)) {
    NODELET_DEBUG("mapping: autosaved to %s in %.0f ms", autosave_path_.c_str(), dqo::ms_since(t0));
  } else {
    NODELET_ERROR_THROTTLE(60.0, "mapping: autosave failed: %s", error.c_str());
  }
}

bool MappingNodelet::save_to(const std::string& path, std::string* error) {
  const auto w = worker();
  if (!w) {
    *error = "no map";
    return false;
  }
  uint64_t next_id;
  std::string map_id;
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    next_id = next_object_id_;
    map_id = map_id_.empty() ? resumed_map_id_ : map_id_;
  }
  const uint64_t mapped = mapped_.load();
  const dqo::mapping::MapFileContents contents =
      w->with_mapper([&](GaussianMapper& m) { return m.snapshot(next_id); });
  if (!dqo::mapping::save_map_file(path, contents, error)) return false;
  std::string why;
  if (!dqo::write_file_atomically(map_id_path(path), map_id + "\n", &why)) {
    NODELET_WARN("mapping: %s", why.c_str());
  }
  if (path == autosave_path_) mapped_at_save_ = mapped;
  return true;
}

// ---------------------------------------------------------------- services

bool MappingNodelet::get_object(dqo_map::GetObject::Request& req, dqo_map::GetObject::Response& res) {
  const auto w = worker();
  if (!w) return false;
  w->with_mapper([&](GaussianMapper& m) {
    for (const auto& o : m.list_objects()) {
      if (o.object.id != req.id || req.id == 0) continue;
      res.found = true;
      res.object = dqo::ros_bridge::to_object_msg(o);
      res.gaussians = dqo::ros_bridge::to_gaussian_cloud(m.object_gaussians(req.id), header());
      res.message = std::to_string(o.num_gaussians) + " Gaussians";
      return;
    }
    res.found = false;
    res.message = "no object " + std::to_string(req.id) + " in the map (" + std::to_string(m.list_objects().size()) +
                  " objects; list them with list_objects)";
  });
  return true;
}

bool MappingNodelet::extract_object(dqo_map::ExtractObject::Request& req, dqo_map::ExtractObject::Response& res) {
  const auto w = worker();
  if (!w) return false;
  const auto t0 = std::chrono::steady_clock::now();
  const dqo::system::ObjectExport e = w->with_mapper([&](GaussianMapper& m) {
    return dqo::system::export_object(m, req.id, p_.output_dir, req.subfolder);
  });
  res.success = e.success;
  res.message = e.message;
  res.gaussians_path = e.gaussians_path;
  res.mesh_path = e.mesh_path;
  if (e.success) {
    NODELET_INFO("mapping: extract_object %llu: %zu Gaussians, %s and %s (%.1f s)",
                 static_cast<unsigned long long>(req.id), e.num_gaussians, e.gaussians_path.c_str(),
                 e.mesh_path.c_str(), dqo::ms_since(t0) / 1000.0);
  } else {
    NODELET_WARN("mapping: extract_object %llu: %s", static_cast<unsigned long long>(req.id), e.message.c_str());
  }
  return true;
}

bool MappingNodelet::save_map(dqo_map::SaveMap::Request& req, dqo_map::SaveMap::Response& res) {
  std::string error;
  const std::string name = req.file.empty() ? "map.dqomap" : req.file;
  const auto path = dqo::resolve_output_path(p_.output_dir, name, &error);
  if (!path) {
    res.success = false;
    res.message = "refused: " + error;
    NODELET_WARN("mapping: save_map %s", res.message.c_str());
    return true;
  }
  std::error_code ec;
  fs::create_directories(fs::path(*path).parent_path(), ec);
  res.success = save_to(*path, &error);
  res.path = res.success ? *path : "";
  res.message = res.success ? "saved" : error;
  NODELET_INFO("mapping: save_map %s: %s", path->c_str(), res.message.c_str());
  return true;
}

bool MappingNodelet::load_map(dqo_map::LoadMap::Request& req, dqo_map::LoadMap::Response& res) {
  std::string error;
  const std::string name = req.file.empty() ? "map.dqomap" : req.file;
  const auto path = dqo::resolve_output_path(p_.output_dir, name, &error);
  res.success = false;
  if (!path) {
    res.message = "refused: " + error;
    NODELET_WARN("mapping: load_map %s", res.message.c_str());
    return true;
  }
  auto contents = dqo::mapping::load_map_file(*path, &error);
  if (!contents) {
    res.message = error + " (the map is unchanged)";
    NODELET_WARN("mapping: load_map: %s", res.message.c_str());
    return true;
  }
  const auto w = worker();
  if (!w) return false;
  const size_t n = contents->gaussians.size();
  const uint64_t next = contents->next_object_id;
  std::string warning;
  w->with_mapper([&](GaussianMapper& m) { m.restore(std::move(*contents), &warning); });
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    next_object_id_ = std::max(next_object_id_, next);
  }
  objects_dirty_ = true;
  cloud_stale_ = true;
  res.success = true;
  res.path = *path;
  res.message = "loaded " + std::to_string(n) + " Gaussians" + (warning.empty() ? "" : "; " + warning);
  NODELET_INFO("mapping: load_map %s: %s", path->c_str(), res.message.c_str());
  return true;
}

}  // namespace dqo_map

PLUGINLIB_EXPORT_CLASS(dqo_map::MappingNodelet, nodelet::Nodelet)
