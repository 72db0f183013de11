// association_node: the ROS skin of the object stage (dqo::objects::ObjectMapper). Pairs keyframes
// with the detections of their images by stamp (dqo::objects::StampMatcher), maps raw detection
// boxes through the camera's undistortion, feeds the mapper, and publishes objects, rviz markers,
// object events (CONFIRMED with a log line per object), which detection became which object and an
// object_overlay image; serves list_objects (with the mapping nodelet's Gaussian counts from
// mapped_objects); keeps the object state file (IDs are never reused, also across restarts; objects
// are resumed only into the map they belong to: tracking_node's map_id). No object maths lives here.
// Parameters: config/association.yaml (this node) and config/objects.yaml (~objects, the core's),
// loaded by launch/association.launch.
//
// Bad input never stops the node: unusable boxes (NaN, negative size, outside the image, too many)
// are rejected by the core and counted in a throttled log line; keyframes whose detections never
// come, detections that match no keyframe, unsupported depth, a missing camera_info are logged and
// skipped; time going backwards (a looping bag) clears the buffers.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <std_msgs/String.h>
#include <tf2_ros/transform_broadcaster.h>
#include <visualization_msgs/MarkerArray.h>

#include <dqo_map/DetectionArray.h>
#include <dqo_map/KeyFrame.h>
#include <dqo_map/KeyFrameObjects.h>
#include <dqo_map/KeyFramePoses.h>
#include <dqo_map/ListObjects.h>
#include <dqo_map/ObjectArray.h>
#include <dqo_map/ObjectEvent.h>

#include "conversions.h"
#include "dqo_map/objects/object_mapper.h"
#include "dqo_map/objects/object_overlay.h"
#include "dqo_map/objects/object_query.h"
#include "dqo_map/objects/stamp_matcher.h"
#include "object_conversions.h"
#include "object_ros_params.h"
#include "ros_params.h"
#include "sim_clock_watch.h"

namespace dqo::ros_bridge {
namespace {

namespace fs = std::filesystem;
using objects::DetectionVerdict;

struct NodeParams {
  std::string map_frame = "map";
  double stamp_tolerance = 0.002;  // seconds between a keyframe's and its detections' stamps
  double buffer_seconds = 5.0;     // how long either side waits for the other (detector latency)
  double max_reorder_seconds = 1.0;  // detection arrays this far out of order are not a looping bag
  bool detections_rectified = false;  // true: boxes already refer to the rectified image
  bool publish_tf = false;         // map -> object_<id> per confirmed object
  std::string output_dir;          // empty: $ROS_HOME/dqo_map, else ~/.ros/dqo_map
  std::string state_file = "objects_state.yaml";
  bool fresh = false;              // true: resume no objects from the state file (its ID counter still)
  int queue_size = 10;
  double diagnostics_period = 1.0;  // wall seconds between /diagnostics statuses
  double input_warn = 10.0;         // wall seconds without keyframes, or with keyframes but no detections, before a WARN
};

class AssociationNode {
 public:
  AssociationNode(ros::NodeHandle nh, ros::NodeHandle pnh);
  bool ok() const { return mapper_ != nullptr; }

 private:
  void on_keyframe(const dqo_map::KeyFrameConstPtr& kf);
  void on_detections(const dqo_map::DetectionArrayConstPtr& det);
  void on_camera_info(const sensor_msgs::CameraInfoConstPtr& info);
  void on_poses(const dqo_map::KeyFramePosesConstPtr& poses);
  void on_map_id(const std_msgs::StringConstPtr& msg);
  void on_mapped_objects(const dqo_map::ObjectArrayConstPtr& msg);
  bool on_list(dqo_map::ListObjects::Request& req, dqo_map::ListObjects::Response& res);
  void log_reset(const std::optional<objects::StampReset>& reset, const char* stream);
  void match();
  void process(const dqo_map::KeyFrame& kf, const dqo_map::DetectionArray& det, const std::optional<SE3>& early_pose);
  void publish(const std_msgs::Header& header, const objects::KeyFrameAssociation& result);
  void publish_events(const std_msgs::Header& header, const std::vector<objects::ObjectEvent>& events);
  void publish_overlay(const dqo_map::KeyFrame& kf, const dqo_map::DetectionArray& det,
                       const objects::ObjectKeyFrame& okf, const objects::KeyFrameAssociation& result, const std_msgs::Header& image_header);
  dqo_map::Object object_msg(const objects::MapObject& o) const;
  void save_state();
  bool throttled(const std::string& kind, double period = 5.0);
  void publish_diagnostics(const ros::WallTimerEvent&);

  ros::NodeHandle nh_, pnh_;
  NodeParams p_;
  std::unique_ptr<objects::ObjectMapper> mapper_;
  std::string state_path_;
  ros::Subscriber kf_sub_, det_sub_, info_sub_, poses_sub_, map_id_sub_, mapped_sub_;
  ros::Publisher objects_pub_, markers_pub_, events_pub_, kf_objects_pub_, overlay_pub_;
  ros::ServiceServer list_srv_;
  tf2_ros::TransformBroadcaster tf_broadcaster_;

  std::optional<tracking::CameraCalibration> calibration_;
  std::optional<tracking::Undistorter> undistorter_;
  using Matcher = objects::StampMatcher<dqo_map::KeyFrameConstPtr, dqo_map::DetectionArrayConstPtr>;
  std::optional<Matcher> matcher_;  // pairs keyframes with their detections by stamp
  std::map<std::string, ros::WallTime> last_complaint_;
  std::map<objects::ObjectId, uint32_t> num_gaussians_;  // from the mapping nodelet's mapped_objects

  // What /diagnostics reports (all on the node's one callback thread).
  ros::Publisher diag_pub_;
  ros::WallTimer diag_timer_;
  ros::WallTime started_ = ros::WallTime::now(), last_keyframe_, last_detections_;
  SimClockWatch clock_;  // a bag's stopped /clock, seen from the diagnostics timer
  uint64_t keyframes_processed_ = 0, keyframes_without_detections_ = 0, detection_arrays_ = 0;
};

// ROS_*_THROTTLE counts in ROS time, which a looping bag sends backwards: throttle in wall time.
bool AssociationNode::throttled(const std::string& kind, double period) {
  const ros::WallTime now = ros::WallTime::now();
  ros::WallTime& last = last_complaint_[kind];
  if (!last.isZero() && (now - last).toSec() < period) return true;
  last = now;
  return false;
}

AssociationNode::AssociationNode(ros::NodeHandle nh, ros::NodeHandle pnh) : nh_(nh), pnh_(pnh) {
  pnh_.param("map_frame", p_.map_frame, p_.map_frame);
  pnh_.param("stamp_tolerance", p_.stamp_tolerance, p_.stamp_tolerance);
  pnh_.param("buffer_seconds", p_.buffer_seconds, p_.buffer_seconds);
  pnh_.param("max_reorder_seconds", p_.max_reorder_seconds, p_.max_reorder_seconds);
  pnh_.param("detections_rectified", p_.detections_rectified, p_.detections_rectified);
  pnh_.param("publish_tf", p_.publish_tf, p_.publish_tf);
  pnh_.param("output_dir", p_.output_dir, p_.output_dir);
  pnh_.param("state_file", p_.state_file, p_.state_file);
  pnh_.param("queue_size", p_.queue_size, p_.queue_size);
  pnh_.param("fresh", p_.fresh, p_.fresh);
  pnh_.param("diagnostics_period", p_.diagnostics_period, p_.diagnostics_period);
  pnh_.param("input_warn", p_.input_warn, p_.input_warn);
  const std::set<std::string> known = {"map_frame",  "stamp_tolerance", "buffer_seconds", "max_reorder_seconds", "detections_rectified",
                                       "publish_tf", "output_dir",      "state_file",     "queue_size", "fresh", "objects",
                                       "diagnostics_period", "input_warn"};
  for (const std::string& name : unknown_private_params(pnh_, known)) {
    ROS_WARN("association: ignoring unknown parameter %s/%s", pnh_.getNamespace().c_str(), name.c_str());
  }
  if (p_.stamp_tolerance < 0.0 || p_.buffer_seconds <= 0.0 || p_.max_reorder_seconds < 0.0 || p_.queue_size < 1 || p_.state_file.empty() ||
      !(p_.diagnostics_period > 0.0) ||
      fs::path(p_.state_file).has_parent_path()) {
    ROS_FATAL("association: stamp_tolerance must be >= 0, buffer_seconds > 0, max_reorder_seconds >= 0, queue_size >= 1, "
              "diagnostics_period > 0, state_file a plain file name");
    return;
  }
  std::string error;
  const auto params = read_object_params(pnh_, &error);
  if (!params) {
    ROS_FATAL("association: %s", error.c_str());
    return;
  }
  if (p_.output_dir.empty()) p_.output_dir = default_output_dir();
  std::error_code ec;
  fs::create_directories(p_.output_dir, ec);
  state_path_ = (fs::path(p_.output_dir) / p_.state_file).string();
  auto mapper = std::make_unique<objects::ObjectMapper>(*params);
  if (fs::exists(state_path_)) {
    // A state we cannot read would let IDs be given twice: refuse to start rather than guess.
    if (!mapper->load_state(state_path_, &error)) {
      ROS_FATAL("association: cannot load the object state %s: %s (move it away to start a new map)",
                state_path_.c_str(), error.c_str());
      return;
    }
    if (p_.fresh) {
      const size_t dropped = mapper->drop_objects().size();
      ROS_INFO("association: fresh start: %zu objects of %s not resumed; IDs continue from %llu", dropped,
               state_path_.c_str(), static_cast<unsigned long long>(mapper->next_id()));
    } else {
      // Provisionally: the tracker's map_id decides (on_map_id) whether they belong to this map.
      ROS_INFO("association: resumed %zu objects of map '%s' from %s; next object ID %llu", mapper->objects().size(),
               mapper->map_id().c_str(), state_path_.c_str(), static_cast<unsigned long long>(mapper->next_id()));
    }
  }
  mapper_ = std::move(mapper);
  matcher_.emplace(objects::StampMatcherParams{p_.stamp_tolerance, p_.buffer_seconds, p_.max_reorder_seconds});

  objects_pub_ = nh_.advertise<dqo_map::ObjectArray>("objects", 10, /*latch=*/true);
  markers_pub_ = nh_.advertise<visualization_msgs::MarkerArray>("object_markers", 10, /*latch=*/true);
  events_pub_ = nh_.advertise<dqo_map::ObjectEvent>("object_events", 100);
  kf_objects_pub_ = nh_.advertise<dqo_map::KeyFrameObjects>("keyframe_objects", 10);
  // Latched: rviz started (or restarted) after the last keyframe still shows its overlay.
  overlay_pub_ = nh_.advertise<sensor_msgs::Image>("object_overlay", 2, /*latch=*/true);
  list_srv_ = nh_.advertiseService("list_objects", &AssociationNode::on_list, this);
  diag_pub_ = nh_.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10);
  diag_timer_ = nh_.createWallTimer(ros::WallDuration(p_.diagnostics_period), &AssociationNode::publish_diagnostics, this);
  kf_sub_ = nh_.subscribe("keyframes", p_.queue_size, &AssociationNode::on_keyframe, this);
  det_sub_ = nh_.subscribe("detections", 100, &AssociationNode::on_detections, this);
  poses_sub_ = nh_.subscribe("keyframe_poses", 10, &AssociationNode::on_poses, this);
  map_id_sub_ = nh_.subscribe("map_id", 1, &AssociationNode::on_map_id, this);
  mapped_sub_ = nh_.subscribe("mapped_objects", 1, &AssociationNode::on_mapped_objects, this);
  if (!p_.detections_rectified) info_sub_ = nh_.subscribe("rgb/camera_info", 1, &AssociationNode::on_camera_info, this);
  std_msgs::Header header;
  header.frame_id = p_.map_frame;
  header.stamp = ros::Time::now();
  publish(header, objects::KeyFrameAssociation());  // the resumed map, for late subscribers (latched)
  const std::string boxes = p_.detections_rectified ? "rectified" : "raw, undistorted with " + info_sub_.getTopic();
  ROS_INFO("association: keyframes %s, detections %s (%s); state %s", kf_sub_.getTopic().c_str(),
           det_sub_.getTopic().c_str(), boxes.c_str(), state_path_.c_str());
}

void AssociationNode::log_reset(const std::optional<objects::StampReset>& reset, const char* stream) {
  if (!reset) return;
  ROS_WARN("association: %s time went back by %.3f s (a looping bag?): %zu keyframes and %zu detection arrays "
           "dropped from the buffers", stream, reset->back_by, reset->dropped_keyframes, reset->dropped_detections);
}

void AssociationNode::on_keyframe(const dqo_map::KeyFrameConstPtr& kf) {
  last_keyframe_ = ros::WallTime::now();
  log_reset(matcher_->add_keyframe(kf->header.stamp.toSec(), kf->id, kf), "keyframe");
  match();
}

void AssociationNode::on_detections(const dqo_map::DetectionArrayConstPtr& det) {
  last_detections_ = ros::WallTime::now();
  ++detection_arrays_;
  log_reset(matcher_->add_detections(det->header.stamp.toSec(), det), "detection");
  match();
}

// The node's state where a robot's monitor looks. WARN when its inputs stop: keyframes that come
// without detections (no detector running, another topic: no object will ever appear) or no
// keyframes at all (tracking not running or not initialised; also the end of a bag).
void AssociationNode::publish_diagnostics(const ros::WallTimerEvent&) {
  const ros::WallTime now = ros::WallTime::now();
  auto since = [&](const ros::WallTime& t) { return (now - (t.isZero() ? started_ : t)).toSec(); };
  const double no_keyframes = since(last_keyframe_);
  const double no_detections = since(last_detections_);
  const bool clock_stopped = clock_.stopped();
  diagnostic_msgs::DiagnosticStatus status;
  status.name = "dqo_map: association";
  status.hardware_id = "dqo_map";
  const size_t confirmed = mapper_->objects().size();
  const size_t all = mapper_->objects(true).size();
  char text[512];
  if (p_.input_warn > 0.0 && no_keyframes < p_.input_warn && no_detections >= p_.input_warn) {
    status.level = diagnostic_msgs::DiagnosticStatus::WARN;
    std::snprintf(text, sizeof(text), "keyframes arrive but no detections on %s for %.0f s: is a detector running? "
                  "(no object appears without one)", det_sub_.getTopic().c_str(), no_detections);
  } else if (p_.input_warn > 0.0 && no_keyframes >= p_.input_warn) {
    status.level = diagnostic_msgs::DiagnosticStatus::WARN;
    std::snprintf(text, sizeof(text), "no keyframes on %s for %.0f s%s", kf_sub_.getTopic().c_str(), no_keyframes,
                  last_keyframe_.isZero() ? " (none yet: is tracking running and initialised?)"
                  : clock_stopped         ? " (the clock stopped too: a bag that ended or is paused)"
                                          : "");
  } else {
    status.level = diagnostic_msgs::DiagnosticStatus::OK;
    std::snprintf(text, sizeof(text), "%zu objects", confirmed);
  }
  status.message = text;
  auto add = [&status](const std::string& key, const std::string& value) {
    diagnostic_msgs::KeyValue kv;
    kv.key = key;
    kv.value = value;
    status.values.push_back(kv);
  };
  add("objects", std::to_string(confirmed));
  add("candidates", std::to_string(all - confirmed));
  add("keyframes processed", std::to_string(keyframes_processed_));
  add("keyframes without detections", std::to_string(keyframes_without_detections_));
  add("detection arrays received", std::to_string(detection_arrays_));
  add("seconds since a keyframe", last_keyframe_.isZero() ? "never" : std::to_string(no_keyframes));
  add("seconds since detections", last_detections_.isZero() ? "never" : std::to_string(no_detections));
  diagnostic_msgs::DiagnosticArray array;
  array.header.stamp = ros::Time::now();
  array.status.push_back(status);
  diag_pub_.publish(array);
}

void AssociationNode::on_camera_info(const sensor_msgs::CameraInfoConstPtr& info) {
  const tracking::CameraCalibration c = to_calibration(*info);
  if (calibration_ && *calibration_ == c) return;
  calibration_ = c;
  std::string error;
  undistorter_ = tracking::Undistorter::create(c, &error);
  if (!undistorter_) ROS_ERROR("association: cannot use camera_info (%s): %s", info_sub_.getTopic().c_str(), error.c_str());
  match();  // keyframes may have waited for it
}

// The tracker's map identity (latched, new per tracker run). Objects belong to the map they were
// made in: for another map (a restarted tracker, whose map frame has another origin) they are
// dropped with REMOVED events, while the ID counter goes on, so that no ID is given twice.
void AssociationNode::on_map_id(const std_msgs::StringConstPtr& msg) {
  if (msg->data == mapper_->map_id()) {
    if (!mapper_->objects(true).empty()) {
      ROS_INFO("association: map '%s' is the state's own: %zu objects resumed", msg->data.c_str(),
               mapper_->objects().size());
    }
    return;
  }
  const std::string old = mapper_->map_id();
  const std::vector<objects::ObjectEvent> dropped = mapper_->drop_objects();
  mapper_->set_map_id(msg->data);
  // Keyframes still buffered in the matcher are the new map's (they come from the new tracker run).
  if (!dropped.empty()) {
    ROS_WARN("association: the map is now '%s', not '%s': %zu objects of the old map not resumed; IDs continue "
             "from %llu", msg->data.c_str(), old.c_str(), dropped.size(),
             static_cast<unsigned long long>(mapper_->next_id()));
  } else {
    ROS_INFO("association: map '%s'", msg->data.c_str());
  }
  std_msgs::Header header;
  header.frame_id = p_.map_frame;
  header.stamp = ros::Time::now();
  objects::KeyFrameAssociation removal;
  removal.events = dropped;
  publish(header, removal);
  save_state();
}

void AssociationNode::on_mapped_objects(const dqo_map::ObjectArrayConstPtr& msg) {
  num_gaussians_.clear();
  for (const auto& o : msg->objects) num_gaussians_[o.id] = o.num_gaussians;
}

dqo_map::Object AssociationNode::object_msg(const objects::MapObject& o) const {
  dqo_map::Object msg = to_object_msg(o, mapper_->class_names(), mapper_->params().labels.top_classes);
  const auto it = num_gaussians_.find(o.id);
  if (it != num_gaussians_.end()) msg.num_gaussians = it->second;
  return msg;
}

void AssociationNode::save_state() {
  std::string error;
  if (!mapper_->save_state(state_path_, &error) && !throttled("save")) {
    ROS_ERROR("association: cannot write the object state %s: %s", state_path_.c_str(), error.c_str());
  }
}

void AssociationNode::on_poses(const dqo_map::KeyFramePosesConstPtr& poses) {
  if (poses->ids.size() != poses->poses.size()) {
    if (!throttled("poses")) ROS_ERROR("association: keyframe_poses with %zu ids but %zu poses: skipped", poses->ids.size(), poses->poses.size());
    return;
  }
  std::map<objects::KeyFrameId, SE3> by_id;
  for (size_t i = 0; i < poses->ids.size(); ++i) by_id[poses->ids[i]] = from_pose_msg(poses->poses[i]);
  mapper_->update_keyframe_poses(by_id);
  matcher_->correct_poses(by_id);  // keyframes still waiting get theirs when processed
}

// The matcher decides (in stamp order, see stamp_matcher.h); this logs and processes what it hands out.
void AssociationNode::match() {
  using Kind = Matcher::Step::Kind;
  const bool no_camera = !p_.detections_rectified && !undistorter_;
  const Matcher::MatchResult result = matcher_->match(!no_camera);
  for (const Matcher::Step& step : result.steps) {
    if (step.kind == Kind::kMatched) {
      // Whatever a keyframe holds, the node keeps running: anything thrown skips this keyframe.
      try {
        ++keyframes_processed_;
        process(*step.keyframe, *step.detections, step.early_pose);
      } catch (const std::exception& e) {
        if (!throttled("exception")) ROS_ERROR("association: keyframe %llu failed: %s: skipped",
                                               static_cast<unsigned long long>(step.id), e.what());
      }
      continue;
    }
    const bool found = step.kind == Kind::kHeld || step.had_detections;
    if (found && !throttled("camera_info")) {
      ROS_WARN("association: no usable camera_info on %s yet: keyframes wait (raw boxes must be undistorted; set "
               "detections_rectified if they are not raw)", info_sub_.getTopic().c_str());
    }
    if (step.kind == Kind::kExpired && !found) keyframes_without_detections_ = step.expired_total;
    if (step.kind != Kind::kExpired || throttled("unmatched_keyframe")) continue;
    const std::string why = found ? "had detections but no usable camera_info arrived on " + info_sub_.getTopic()
                                  : "got no detections on " + det_sub_.getTopic() + " within " +
                                        std::to_string(p_.stamp_tolerance) + " s of its stamp";
    ROS_WARN("association: keyframe %llu at %.6f %s within %.1f s: skipped (%llu so far)",
             static_cast<unsigned long long>(step.id), step.stamp, why.c_str(), p_.buffer_seconds,
             static_cast<unsigned long long>(step.expired_total));
  }
  if (result.dropped_detections_total > 0 && !throttled("unmatched_detections", 30.0)) {
    ROS_INFO("association: %llu detection arrays matched no keyframe so far (expected for frames that are not "
             "keyframes)", static_cast<unsigned long long>(result.dropped_detections_total));
  }
}

void AssociationNode::process(const dqo_map::KeyFrame& kf, const dqo_map::DetectionArray& det,
                              const std::optional<SE3>& early_pose) {
  objects::ObjectKeyFrame okf;
  DepthImage depth;
  InstanceImage instance;
  std::vector<std::string> warnings;
  std::string error;
  const tracking::Undistorter* undistorter = p_.detections_rectified ? nullptr : &*undistorter_;
  if (!to_object_keyframe(kf, det, undistorter, &okf, &depth, &instance, &warnings, &error)) {
    if (!throttled("camera")) ROS_ERROR("association: %s: skipped", error.c_str());
    return;
  }
  for (const std::string& w : warnings) {
    if (!throttled(w.substr(0, 20))) ROS_WARN("association: keyframe %llu: %s", static_cast<unsigned long long>(kf.id), w.c_str());
  }
  if (early_pose) okf.T_wc = *early_pose;  // corrected by bundle adjustment while it waited
  error.clear();
  const objects::KeyFrameAssociation result = mapper_->process_keyframe(okf, &error);
  if (!error.empty()) {
    if (!throttled("process")) ROS_ERROR("association: keyframe %llu: %s: skipped", static_cast<unsigned long long>(kf.id), error.c_str());
    return;
  }
  // One line per kind of unusable input (throttled apart, so one kind does not hide the other).
  int invalid = 0, over_limit = 0;
  for (const DetectionVerdict v : result.verdicts) {
    invalid += v == DetectionVerdict::kInvalid;
    over_limit += v == DetectionVerdict::kOverLimit;
  }
  const auto kf_id = static_cast<unsigned long long>(kf.id);
  if (invalid > 0 && !throttled("invalid_boxes")) {
    ROS_WARN("association: keyframe %llu: %d of %zu detections rejected as unusable (NaN, empty or negative "
             "size, or outside the %dx%d image)", kf_id, invalid, result.verdicts.size(), okf.camera.width,
             okf.camera.height);
  }
  int started = 0;
  for (const auto v : result.verdicts) started += v == objects::DetectionVerdict::kNewObject;
  if (started >= 10 && !throttled("clutter")) {
    ROS_WARN("association: keyframe %llu: %d of %zu detections started candidates (clutter?); a candidate is "
             "confirmed only by repeated detections where its depth agrees (objects/lifecycle/existence)",
             kf_id, started, result.verdicts.size());
  }
  if (over_limit > 0 && !throttled("over_limit")) {
    ROS_WARN("association: keyframe %llu: %zu detections, %d beyond the per-keyframe limit "
             "(objects/filter/max_detections) dropped", kf_id, result.verdicts.size(), over_limit);
  }
  std_msgs::Header header;
  header.stamp = kf.header.stamp;
  header.frame_id = p_.map_frame;
  publish(header, result);
  InstanceImage renumbered;
  if (!instance.empty()) renumbered = objects::renumber_instance(instance, result.filtered_source);
  std_msgs::Header image_header = header;
  image_header.frame_id = kf.camera_info.header.frame_id;
  kf_objects_pub_.publish(to_keyframe_objects_msg(result, image_header, renumbered));
  if (overlay_pub_.getNumSubscribers() > 0) publish_overlay(kf, det, okf, result, image_header);

  bool changed = !result.events.empty();
  for (const auto id : result.object_ids) changed = changed || id != 0;
  if (changed) save_state();
  ROS_DEBUG("association: keyframe %llu: %zu detections, %zu kept, %zu events, %.1f + %.1f ms",
            static_cast<unsigned long long>(kf.id), result.verdicts.size(), result.filtered.size(),
            result.events.size(), result.association_ms, result.refinement_ms);
}

void AssociationNode::publish(const std_msgs::Header& header, const objects::KeyFrameAssociation& result) {
  std::vector<objects::ObjectId> deleted;
  for (const objects::ObjectEvent& e : result.events) {
    events_pub_.publish(to_event_msg(e, header));
    if (e.type == objects::ObjectEvent::Type::kMerged || e.type == objects::ObjectEvent::Type::kRemoved) {
      deleted.push_back(e.id);
    }
    if (e.type == objects::ObjectEvent::Type::kRenamed) {
      ROS_INFO("association: object %llu renamed %s (its detections' class vote changed)",
               static_cast<unsigned long long>(e.id), e.class_name.c_str());
    }
  }
  // CONFIRMED after the keyframe's other events: the object is in the array published next.
  for (const objects::ObjectId id : result.confirmed) {
    const objects::MapObject* o = mapper_->find(id);
    if (!o) continue;
    dqo_map::ObjectEvent e;
    e.header = header;
    e.type = dqo_map::ObjectEvent::CONFIRMED;
    e.id = id;
    events_pub_.publish(e);
    const dqo_map::Object m = to_object_msg(*o);
    ROS_INFO("association: object %llu confirmed: %s, centre %.3f %.3f %.3f, semi-axes %.3f %.3f %.3f m",
             static_cast<unsigned long long>(id), o->class_name.c_str(), m.pose.position.x, m.pose.position.y,
             m.pose.position.z, m.semi_axes.x, m.semi_axes.y, m.semi_axes.z);
  }
  const std::vector<objects::MapObject> confirmed = mapper_->objects();
  dqo_map::ObjectArray array;
  array.header = header;
  for (const auto& o : confirmed) array.objects.push_back(object_msg(o));
  objects_pub_.publish(array);
  markers_pub_.publish(to_marker_array(confirmed, deleted, header));
  if (!p_.publish_tf) return;
  for (const auto& o : array.objects) {
    geometry_msgs::TransformStamped t;
    t.header = header;
    t.child_frame_id = "object_" + std::to_string(o.id);
    t.transform = to_transform_msg(from_pose_msg(o.pose));
    tf_broadcaster_.sendTransform(t);
  }
}

bool AssociationNode::on_list(dqo_map::ListObjects::Request& req, dqo_map::ListObjects::Response& res) {
  const objects::ClassQueryResult found = objects::objects_of_class(mapper_->objects(), req.class_name);
  for (const auto& o : found.objects) res.objects.push_back(object_msg(o));
  res.message = found.message;
  return true;
}

// The keyframe's rectified colour image with its filtered detections (each in the colour of the
// object it became) and every object's projected conic: drawn by the core (object_overlay.h).
void AssociationNode::publish_overlay(const dqo_map::KeyFrame& kf, const dqo_map::DetectionArray& det,
                                      const objects::ObjectKeyFrame& okf, const objects::KeyFrameAssociation& result,
                                      const std_msgs::Header& image_header) {
  ImageRgb8 rgb;
  std::string error;
  if (!from_colour_msg(kf.rgb, &rgb, &error)) {
    if (!throttled("overlay")) ROS_WARN("association: no object_overlay for keyframe %llu: %s",
                                        static_cast<unsigned long long>(kf.id), error.c_str());
    return;
  }
  std::vector<objects::OverlayDetection> dets;
  for (size_t k = 0; k < result.filtered.size(); ++k) {
    objects::OverlayDetection d;
    d.box = result.filtered[k].box;
    d.score = result.filtered[k].score;
    const auto source = static_cast<size_t>(result.filtered_source[k]);
    d.class_name = source < det.detections.size() ? det.detections[source].class_name : "";
    d.object_id = result.filtered_object_ids[k];
    dets.push_back(d);
  }
  // The camera and pose the keyframe was processed with (its pose corrected by BA while it waited).
  const ImageRgb8 overlay = objects::draw_object_overlay(rgb, okf.camera, okf.T_wc, dets, mapper_->objects());
  overlay_pub_.publish(to_rgb8_msg(overlay, image_header));
}

}  // namespace
}  // namespace dqo::ros_bridge

int main(int argc, char** argv) {
  ros::init(argc, argv, "association");
  dqo::ros_bridge::AssociationNode node(ros::NodeHandle(), ros::NodeHandle("~"));
  if (!node.ok()) return 1;
  ros::spin();
  return 0;
}
