// The rosbag written from a synthetic scene holds what the Azure Kinect driver records: its topics,
// encodings and frame, one stamp per capture, the static camera_base -> rgb_camera_link tf, and
// detections under the image's stamp. Read back with the rosbag API.
#include <algorithm>
#include <cmath>
#include <unistd.h>
#include <cstring>
#include <filesystem>
#include <map>

#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <tf2_msgs/TFMessage.h>

#include <dqo_map/DetectionArray.h>

#include "dqo_map/common/mask_detections.h"
#include "dqo_map/ros/kinect_bag_writer.h"
#include "dqo_map/sim/renderer.h"
#include "dqo_map/sim/scene_loader.h"

namespace {

TEST(KinectBag, HoldsTheDriverLayout) {
  std::string error;
  const auto scene =
      dqo::sim::load_scene(std::string(DQO_SOURCE_DIR) + "/config/scenes/tiny.yaml", nullptr, &error);
  ASSERT_TRUE(scene) << error;
  const dqo::sim::Renderer renderer(*scene, 2);
  const auto path = std::filesystem::temp_directory_path() / "dqo_test_kinect.bag";

  constexpr int kFrames = 4;
  std::vector<dqo::Frame> frames;
  {
    dqo::ros_bridge::KinectBagOptions options;
    options.ground_truth_tf = true;
    auto writer = dqo::ros_bridge::KinectBagWriter::open(path.string(), renderer.info(), options, &error);
    ASSERT_TRUE(writer) << error;
    for (int i = 0; i < kFrames; ++i) {
      frames.push_back(renderer.render(i, false));
      ASSERT_TRUE(writer->write(frames.back(), &error)) << error;
    }
    writer->close();
  }

  rosbag::Bag bag(path.string(), rosbag::bagmode::Read);
  std::map<std::string, std::vector<ros::Time>> stamps;
  int static_tf = 0;
  for (const rosbag::MessageInstance& m : rosbag::View(bag)) {
    const std::string topic = m.getTopic();
    if (topic == "/rgb/image_raw") {
      auto img = m.instantiate<sensor_msgs::Image>();
      ASSERT_TRUE(img);
      EXPECT_EQ(img->encoding, "bgra8");
      EXPECT_EQ(img->header.frame_id, "rgb_camera_link");
      const dqo::Frame& f = frames.at(stamps[topic].size());
      ASSERT_EQ(img->width, static_cast<uint32_t>(f.rgb.width));
      // Pixel 0's channels are swapped to BGRA.
      EXPECT_EQ(img->data[0], f.rgb.data[2]);
      EXPECT_EQ(img->data[2], f.rgb.data[0]);
      EXPECT_EQ(img->data[3], 255);
      stamps[topic].push_back(img->header.stamp);
    } else if (topic == "/depth_to_rgb/image_raw") {
      auto img = m.instantiate<sensor_msgs::Image>();
      ASSERT_TRUE(img);
      EXPECT_EQ(img->encoding, "16UC1");
      EXPECT_EQ(img->header.frame_id, "rgb_camera_link");
      const dqo::Frame& f = frames.at(stamps[topic].size());
      // Millimetres, rounded; 0 where there is no return.
      for (size_t i = 0; i < f.depth.data.size(); i += 97) {
        uint16_t mm;
        std::memcpy(&mm, &img->data[2 * i], 2);
        const float z = f.depth.data[i];
        const long expected = (std::isfinite(z) && z > 0.f) ? std::lround(static_cast<double>(z) * 1000.0) : 0;
        ASSERT_EQ(mm, expected) << "pixel " << i;
      }
      stamps[topic].push_back(img->header.stamp);
    } else if (topic == "/rgb/camera_info") {
      auto info = m.instantiate<sensor_msgs::CameraInfo>();
      ASSERT_TRUE(info);
      EXPECT_DOUBLE_EQ(info->K[0], scene->camera.fx);
      EXPECT_DOUBLE_EQ(info->K[2], scene->camera.cx);
      EXPECT_EQ(info->distortion_model, "rational_polynomial");
      stamps[topic].push_back(info->header.stamp);
    } else if (topic == "/detections") {
      auto det = m.instantiate<dqo_map::DetectionArray>();
      ASSERT_TRUE(det);
      const dqo::Frame& f = frames.at(stamps[topic].size());
      ASSERT_EQ(det->detections.size(), f.detections.size());
      for (size_t k = 0; k < f.detections.size(); ++k) {
        EXPECT_FLOAT_EQ(det->detections[k].x_min, static_cast<float>(f.detections[k].box.x_min));
        EXPECT_EQ(det->detections[k].class_id, f.detections[k].class_id);
      }
      stamps[topic].push_back(det->header.stamp);
    } else if (topic == "/tf_static") {
      auto tf = m.instantiate<tf2_msgs::TFMessage>();
      ASSERT_TRUE(tf);
      ASSERT_EQ(tf->transforms.size(), 1u);
      EXPECT_EQ(tf->transforms[0].header.frame_id, "camera_base");
      EXPECT_EQ(tf->transforms[0].child_frame_id, "rgb_camera_link");
      // Latched, so that `rosbag play` latches it for late tf listeners.
      const auto header = m.getConnectionHeader();
      ASSERT_TRUE(header);
      EXPECT_EQ(header->count("latching") ? header->at("latching") : "", "1");
      EXPECT_EQ(header->at("type"), "tf2_msgs/TFMessage");
      ++static_tf;
    } else if (topic == "/tf") {
      auto tf = m.instantiate<tf2_msgs::TFMessage>();
      ASSERT_TRUE(tf);
      const auto header = m.getConnectionHeader();
      EXPECT_TRUE(!header || !header->count("latching") || header->at("latching") != "1") << "only /tf_static is latched";
      EXPECT_EQ(tf->transforms.at(0).header.frame_id, "map");
      EXPECT_EQ(tf->transforms.at(0).child_frame_id, "camera_base");
      stamps[topic].push_back(tf->transforms[0].header.stamp);
    } else {
      ADD_FAILURE() << "unexpected topic " << topic;
    }
  }
  EXPECT_EQ(static_tf, 1);
  // One stamp per capture, shared by every topic, increasing with the frames' timestamps.
  const auto& rgb = stamps["/rgb/image_raw"];
  ASSERT_EQ(rgb.size(), static_cast<size_t>(kFrames));
  for (const char* topic : {"/depth_to_rgb/image_raw", "/rgb/camera_info", "/detections", "/tf"})
    EXPECT_EQ(stamps[topic], rgb) << topic;
  for (int i = 0; i < kFrames; ++i)
    EXPECT_NEAR(rgb[i].toSec(), 1000.0 + frames[i].timestamp, 1e-6);
  for (int i = 1; i < kFrames; ++i) EXPECT_LT(rgb[i - 1], rgb[i]);
  bag.close();
  std::filesystem::remove(path);
}

TEST(KinectBag, DetectionsCarryTheInstanceMasksWhenAsked) {
  // As a segmenting detector publishes them: mono16, value k+1 = detection k, the frame's own size.
  std::string error;
  const auto scene =
      dqo::sim::load_scene(std::string(DQO_SOURCE_DIR) + "/config/scenes/tiny.yaml", nullptr, &error);
  ASSERT_TRUE(scene) << error;
  const dqo::sim::Renderer renderer(*scene, 2);
  const auto path = std::filesystem::temp_directory_path() / ("dqo_test_kinect_masks_" + std::to_string(getpid()) + ".bag");
  std::vector<dqo::Frame> frames;
  for (const bool masks : {false, true}) {
    dqo::ros_bridge::KinectBagOptions options;
    options.instance_masks = masks;
    auto writer = dqo::ros_bridge::KinectBagWriter::open(path.string(), renderer.info(), options, &error);
    ASSERT_TRUE(writer) << error;
    frames = {renderer.render(0, false), renderer.render(1, false)};
    for (const auto& f : frames) ASSERT_TRUE(writer->write(f, &error)) << error;
    writer->close();
    rosbag::Bag bag(path.string(), rosbag::bagmode::Read);
    size_t k = 0, with_detections = 0;
    for (const rosbag::MessageInstance& m : rosbag::View(bag, rosbag::TopicQuery("/detections"))) {
      auto det = m.instantiate<dqo_map::DetectionArray>();
      ASSERT_TRUE(det);
      const dqo::Frame& f = frames.at(k++);
      if (!masks) {
        EXPECT_EQ(det->instance.width, 0u) << "no masks unless asked";
        continue;
      }
      if (f.detections.empty()) continue;
      ++with_detections;
      ASSERT_EQ(det->instance.encoding, "mono16");
      ASSERT_EQ(det->instance.width, static_cast<uint32_t>(f.instance.width));
      ASSERT_EQ(det->instance.height, static_cast<uint32_t>(f.instance.height));
      const dqo::InstanceImage expected = dqo::instance_for_detections(f.instance, f.detections);
      std::vector<uint16_t> got(expected.data.size());
      ASSERT_EQ(det->instance.data.size(), 2 * got.size());
      std::memcpy(got.data(), det->instance.data.data(), det->instance.data.size());
      EXPECT_EQ(got, expected.data);
      EXPECT_GT(std::count_if(got.begin(), got.end(), [](uint16_t v) { return v != 0; }), 0);
    }
    EXPECT_EQ(k, frames.size());
    if (masks) {
      EXPECT_GT(with_detections, 0u);
    }
  }
  std::filesystem::remove(path);
}

}  // namespace
