// yolo_detector nodelet (dqo_map/YoloDetectorNodelet): colour images in, dqo_map/DetectionArray out,
// stamped and framed like the image it came from, through a YOLO model (ONNX) on OpenCV's DNN module
// (detector/yolo_detector.h holds everything but the ROS skin). -seg models add the instance image
// (mono16, value k + 1 = detection k). Rate: every `every_n`-th image, or with `keyframes_only` the
// images whose stamps the tracker's keyframes carry (the detector then runs where mapping needs it;
// images wait in a short buffer for their keyframe). Parameters: config/yolo_detector.yaml.
// A model that cannot be used stops the nodelet at start with the reason; a bad image is skipped
// with a throttled error; the node never dies on one message.
#include <memory>
#include <set>
#include <string>

#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <ros/package.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>

#include <dqo_map/DetectionArray.h>
#include <dqo_map/KeyFrame.h>

#include "conversions.h"
#include "dqo_map/detector/keyframe_images.h"
#include "dqo_map/detector/yolo_detector.h"
#include "ros_params.h"

namespace dqo_map {

class YoloDetectorNodelet : public nodelet::Nodelet {
 private:
  void onInit() override;
  bool read_params(dqo::detector::YoloParams* p, std::string* error);
  void on_image(const sensor_msgs::ImageConstPtr& msg);
  void on_keyframe(const dqo_map::KeyFrame::ConstPtr& msg);
  void detect_and_publish(const sensor_msgs::Image& msg);
  void on_report(const ros::WallTimerEvent&);

  std::unique_ptr<dqo::detector::YoloDetector> detector_;
  ros::Subscriber image_sub_, keyframe_sub_;
  ros::Publisher pub_;
  ros::WallTimer report_timer_;
  int every_n_ = 1;
  bool keyframes_only_ = false;
  int buffer_size_ = 30;
  uint64_t images_ = 0;
  // keyframes_only: recent images and keyframe stamps, each waiting for the other.
  std::unique_ptr<dqo::detector::KeyframeImages<sensor_msgs::ImageConstPtr>> keyframe_images_;
  // For the periodic report (all callbacks on the nodelet's one input thread: no lock needed).
  uint64_t detected_frames_ = 0, detections_ = 0, skipped_ = 0;
  double inference_ms_ = 0.0, total_ms_ = 0.0;
};

bool YoloDetectorNodelet::read_params(dqo::detector::YoloParams* p, std::string* error) {
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  pnh.param("model", p->model, p->model);
  pnh.param("classes", p->classes, std::string());
  if (p->classes.empty()) p->classes = ros::package::getPath("dqo_map") + "/config/coco.names";
  std::vector<int> input_size{p->input_width, p->input_height};
  pnh.param("input_size", input_size, input_size);
  std::string layout = "auto", channel_order = "auto", input_scale = "auto", letterbox = "auto";
  pnh.param("layout", layout, layout);
  pnh.param("channel_order", channel_order, channel_order);
  double scale_number = 0.0;  // input_scale: a number (1, 0.00392) or text ("1/255", "auto")
  if (pnh.getParam("input_scale", scale_number)) input_scale = std::to_string(scale_number);
  else pnh.param("input_scale", input_scale, input_scale);
  pnh.param("letterbox", letterbox, letterbox);
  double confidence = p->confidence, nms = p->nms_iou, mask = p->mask_threshold;
  pnh.param("confidence", confidence, confidence);
  pnh.param("nms_iou", nms, nms);
  pnh.param("mask_threshold", mask, mask);
  pnh.param("max_detections", p->max_detections, p->max_detections);
  pnh.param("keep_classes", p->keep_classes, p->keep_classes);
  pnh.param("ignore_classes", p->ignore_classes, p->ignore_classes);
  pnh.param("cuda", p->cuda, p->cuda);
  pnh.param("every_n", every_n_, every_n_);
  pnh.param("keyframes_only", keyframes_only_, keyframes_only_);
  pnh.param("buffer_size", buffer_size_, buffer_size_);
  const std::set<std::string> known = {"model", "classes", "input_size", "layout", "channel_order", "input_scale",
                                       "letterbox", "confidence", "nms_iou",
                                       "mask_threshold", "max_detections", "keep_classes", "ignore_classes",
                                       "cuda", "every_n", "keyframes_only", "buffer_size", "queue_size"};
  for (const std::string& name : dqo::ros_bridge::unknown_private_params(pnh, known)) {
    NODELET_WARN("yolo_detector: ignoring unknown parameter %s/%s", pnh.getNamespace().c_str(), name.c_str());
  }
  if (input_size.size() != 2) {
    *error = "input_size is [width, height], e.g. [640, 640]";
    return false;
  }
  p->input_width = input_size[0];
  p->input_height = input_size[1];
  if (!dqo::detector::parse_yolo_layout(layout, &p->layout)) {
    *error = "layout is auto, v5, v8, v11, v10 or yolox, not " + layout;
    return false;
  }
  if (!dqo::detector::parse_channel_order(channel_order, &p->input.channels) ||
      !dqo::detector::parse_input_scale(input_scale, &p->input.scale) ||
      !dqo::detector::parse_pad_placement(letterbox, &p->input.pad)) {
    *error = "channel_order is auto, rgb or bgr; input_scale auto, 1, 1/255 or a number; letterbox auto, centre or "
             "top_left (not " + channel_order + ", " + input_scale + ", " + letterbox + ")";
    return false;
  }
  p->confidence = static_cast<float>(confidence);
  p->nms_iou = static_cast<float>(nms);
  p->mask_threshold = static_cast<float>(mask);
  if (every_n_ < 1 || buffer_size_ < 1) {
    *error = "every_n and buffer_size must be >= 1";
    return false;
  }
  if (p->model.empty()) {
    *error = "no ~model given: the path of a YOLO model exported to ONNX (README: the detector)";
    return false;
  }
  return true;
}

void YoloDetectorNodelet::onInit() {
  dqo::detector::YoloParams params;
  std::string error;
  if (!read_params(&params, &error) || !(detector_ = dqo::detector::YoloDetector::create(params, &error))) {
    NODELET_FATAL("yolo_detector: %s", error.c_str());
    return;  // inert: nothing subscribed, nothing published
  }
  // Before any subscription: callbacks may start at once.
  if (keyframes_only_) {
    keyframe_images_ =
        std::make_unique<dqo::detector::KeyframeImages<sensor_msgs::ImageConstPtr>>(static_cast<size_t>(buffer_size_));
  }
  ros::NodeHandle& nh = getNodeHandle();
  int queue_size = 1;  // the newest image: a slow model drops frames rather than lag
  getPrivateNodeHandle().param("queue_size", queue_size, queue_size);
  pub_ = nh.advertise<dqo_map::DetectionArray>("detections", 10);
  // Keyframes wait for their images: keep several images in the subscriber's queue meanwhile.
  image_sub_ = nh.subscribe("rgb/image_raw", keyframes_only_ ? std::max(queue_size, 10) : std::max(queue_size, 1),
                            &YoloDetectorNodelet::on_image, this);
  if (keyframes_only_) keyframe_sub_ = nh.subscribe("keyframes", 10, &YoloDetectorNodelet::on_keyframe, this);
  report_timer_ = nh.createWallTimer(ros::WallDuration(10.0), &YoloDetectorNodelet::on_report, this);
  NODELET_INFO("yolo_detector: %s (%s; input %s), input %dx%d, %zu classes, confidence %.2f; %s -> %s, %s",
               params.model.c_str(), detector_->layout().describe().c_str(),
               detector_->input_convention().describe().c_str(), params.input_width, params.input_height,
               detector_->class_names().size(), params.confidence, image_sub_.getTopic().c_str(),
               pub_.getTopic().c_str(),
               keyframes_only_ ? ("the images of " + keyframe_sub_.getTopic()).c_str()
                               : every_n_ == 1 ? "every image" : ("every " + std::to_string(every_n_) + "th image").c_str());
}

void YoloDetectorNodelet::on_image(const sensor_msgs::ImageConstPtr& msg) {
  ++images_;
  if (!keyframes_only_) {
    if ((images_ - 1) % static_cast<uint64_t>(every_n_) == 0) detect_and_publish(*msg);
    return;
  }
  if (const auto image = keyframe_images_->add_image(msg->header.stamp.toNSec(), msg)) detect_and_publish(**image);
}

void YoloDetectorNodelet::on_keyframe(const dqo_map::KeyFrame::ConstPtr& msg) {
  const uint64_t unmatched = keyframe_images_->unmatched_keyframes();
  if (const auto image = keyframe_images_->add_keyframe(msg->header.stamp.toNSec())) detect_and_publish(**image);
  if (keyframe_images_->unmatched_keyframes() > unmatched) {
    NODELET_WARN_THROTTLE(5.0, "yolo_detector: a keyframe's image never came (%llu so far): it gets no detections",
                          static_cast<unsigned long long>(keyframe_images_->unmatched_keyframes()));
  }
}

void YoloDetectorNodelet::detect_and_publish(const sensor_msgs::Image& msg) {
  dqo::ImageRgb8 rgb;
  std::string error;
  if (!dqo::ros_bridge::from_colour_msg(msg, &rgb, &error)) {
    ++skipped_;
    NODELET_ERROR_THROTTLE(5.0, "yolo_detector: %s: image skipped", error.c_str());
    return;
  }
  dqo::detector::YoloDetections r;
  try {
    r = detector_->detect(rgb);
  } catch (const std::exception& e) {  // OpenCV's errors (out of memory, a backend failure)
    ++skipped_;
    NODELET_ERROR_THROTTLE(5.0, "yolo_detector: %s: image skipped", e.what());
    return;
  }
  dqo_map::DetectionArray out = dqo::ros_bridge::to_detection_array_msg(r.detections, msg.header);
  if (!r.instance.empty()) out.instance = dqo::ros_bridge::to_mono16_msg(r.instance, msg.header);
  pub_.publish(out);
  ++detected_frames_;
  detections_ += r.detections.size();
  inference_ms_ += r.inference_ms;
  total_ms_ += r.preprocess_ms + r.inference_ms + r.decode_ms;
}

void YoloDetectorNodelet::on_report(const ros::WallTimerEvent&) {
  // On the inputs' callback thread (getNodeHandle()): the counters need no lock.
  const uint64_t frames = detected_frames_;
  if (frames == 0 && skipped_ == 0) return;
  NODELET_INFO("yolo_detector: %llu images detected (%.1f detections each, %.1f ms inference, %.1f ms in all), %llu "
               "skipped",
               static_cast<unsigned long long>(frames), frames ? double(detections_) / frames : 0.0,
               frames ? inference_ms_ / frames : 0.0, frames ? total_ms_ / frames : 0.0,
               static_cast<unsigned long long>(skipped_));
}

}  // namespace dqo_map

PLUGINLIB_EXPORT_CLASS(dqo_map::YoloDetectorNodelet, nodelet::Nodelet)
