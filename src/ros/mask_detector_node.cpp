// mask_detector: instance masks in, detections out (DESIGN.md: for datasets and simulators that
// give instance masks and no detector). Each instance of the mask (a mono8 / mono16 value, or a
// colour of an rgb8 / bgr8 mask; 0 / black = none) becomes one box with the class from the table
// ~classes and score 1; the DetectionArray carries the instance image renumbered as mono16 (value
// k+1 = detection k). The maths: objects/mask_detections.h. Parameters: config/mask_detector.yaml.
//
// Bad input (an unsupported encoding, a malformed image) is skipped with a throttled log line.
#include <map>
#include <set>
#include <string>

#include <ros/ros.h>
#include <sensor_msgs/Image.h>

#include <dqo_map/DetectionArray.h>

#include "conversions.h"
#include "object_conversions.h"
#include "object_ros_params.h"
#include "ros_params.h"

namespace dqo::ros_bridge {
namespace {

class MaskDetectorNode {
 public:
  MaskDetectorNode(ros::NodeHandle nh, ros::NodeHandle pnh);
  bool ok() const { return ok_; }

 private:
  void on_mask(const sensor_msgs::ImageConstPtr& msg);
  bool throttled(const std::string& kind, double period = 5.0);

  ros::NodeHandle nh_, pnh_;
  MaskDetectionParams params_;
  bool attach_instance_ = true;
  bool ok_ = false;
  ros::Subscriber sub_;
  ros::Publisher pub_;
  std::set<uint32_t> reported_unknown_;
  std::map<std::string, ros::WallTime> last_complaint_;
};

// In wall time: ROS time goes backwards when a bag loops.
bool MaskDetectorNode::throttled(const std::string& kind, double period) {
  const ros::WallTime now = ros::WallTime::now();
  ros::WallTime& last = last_complaint_[kind];
  if (!last.isZero() && (now - last).toSec() < period) return true;
  last = now;
  return false;
}

MaskDetectorNode::MaskDetectorNode(ros::NodeHandle nh, ros::NodeHandle pnh) : nh_(nh), pnh_(pnh) {
  pnh_.param("min_pixels", params_.min_pixels, params_.min_pixels);
  pnh_.param("skip_unknown", params_.skip_unknown, params_.skip_unknown);
  pnh_.param("default_class_id", params_.default_class.class_id, params_.default_class.class_id);
  pnh_.param("default_class_name", params_.default_class.class_name, params_.default_class.class_name);
  double score = params_.score;
  pnh_.param("score", score, score);
  params_.score = static_cast<float>(score);
  pnh_.param("attach_instance", attach_instance_, attach_instance_);
  int queue_size = 10;
  pnh_.param("queue_size", queue_size, queue_size);
  const std::set<std::string> known = {"min_pixels", "skip_unknown", "default_class_id", "default_class_name",
                                       "score",      "attach_instance", "queue_size",   "classes"};
  for (const std::string& name : unknown_private_params(pnh_, known)) {
    ROS_WARN("mask_detector: ignoring unknown parameter %s/%s", pnh_.getNamespace().c_str(), name.c_str());
  }
  if (params_.min_pixels < 1 || queue_size < 1 || !(score >= 0.0 && score <= 1.0)) {
    ROS_FATAL("mask_detector: min_pixels and queue_size must be >= 1, score in [0, 1]");
    return;
  }
  std::string error;
  if (!read_mask_classes(pnh_, &params_, &error)) {
    ROS_FATAL("mask_detector: %s", error.c_str());
    return;
  }
  pub_ = nh_.advertise<dqo_map::DetectionArray>("detections", 10);
  sub_ = nh_.subscribe("instance", queue_size, &MaskDetectorNode::on_mask, this);
  const std::string unknown = params_.skip_unknown ? "skipped" : "become class " + params_.default_class.class_name;
  ROS_INFO("mask_detector: masks %s -> %s; %zu classes in the table, unknown instances %s", sub_.getTopic().c_str(),
           pub_.getTopic().c_str(), params_.classes.size(), unknown.c_str());
  ok_ = true;
}

void MaskDetectorNode::on_mask(const sensor_msgs::ImageConstPtr& msg) {
  LabelImage labels;
  std::string error;
  if (!from_label_msg(*msg, &labels, &error)) {
    if (!throttled("encoding")) ROS_ERROR("mask_detector: %s: mask skipped", error.c_str());
    return;
  }
  const MaskDetections r = detections_from_mask(labels, params_);
  if (!params_.skip_unknown && !params_.classes.empty()) {
    for (size_t k = 0; k < r.labels.size(); ++k) {
      // Once per label: a table that misses an instance is worth one line, not one per frame.
      if (!params_.classes.count(r.labels[k]) && reported_unknown_.insert(r.labels[k]).second) {
        ROS_WARN("mask_detector: instance label %u (0x%06x as a colour) is not in ~classes: class %s", r.labels[k],
                 r.labels[k], params_.default_class.class_name.c_str());
      }
    }
  }
  if (r.dropped_too_many > 0 && !throttled("too_many")) {
    ROS_WARN("mask_detector: %d instances beyond 65535 dropped", r.dropped_too_many);
  }
  dqo_map::DetectionArray out = to_detection_array_msg(r.detections, msg->header);
  if (attach_instance_) out.instance = to_mono16_msg(r.instance, msg->header);
  pub_.publish(out);
}

}  // namespace
}  // namespace dqo::ros_bridge

int main(int argc, char** argv) {
  ros::init(argc, argv, "mask_detector");
  dqo::ros_bridge::MaskDetectorNode node(ros::NodeHandle(), ros::NodeHandle("~"));
  if (!node.ok()) return 1;
  ros::spin();
  return 0;
}
