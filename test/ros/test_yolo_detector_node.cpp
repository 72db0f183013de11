// rostest of the YOLO detector nodelet (test/ros/yolo_detector.test) as users start it: roslaunch
// dqo_map yolo_detector.launch model:=... on a -seg model whose outputs the test chose
// (test/detector/yolo_fixture.h). Colour images in, DetectionArray out: stamp and frame of the image,
// the boxes, classes, scores and instance image worked out by hand; an image of a wrong encoding is
// skipped and the node keeps answering; with keyframes_only only the images the keyframes name are
// detected (the keyframe before or after its image); a missing model leaves the node inert.
#include <mutex>

#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>

#include <dqo_map/DetectionArray.h>
#include <dqo_map/KeyFrame.h>

#include "../detector/yolo_fixture.h"
#include "ros_test_util.h"

namespace {

using dqo::detector::test::RawCandidate;
using dqo::ros_test::wait_for;

sensor_msgs::Image colour_image(const std::string& encoding, double stamp) {
  sensor_msgs::Image m;
  m.header.stamp = ros::Time(stamp);
  m.header.frame_id = "rgb_camera_link";
  m.width = 320, m.height = 240, m.encoding = encoding, m.is_bigendian = 0;
  const int bytes = encoding == "bgra8" ? 4 : encoding == "32FC1" ? 4 : 3;
  m.step = m.width * bytes;
  m.data.resize(static_cast<size_t>(m.step) * m.height);
  for (size_t i = 0; i < m.data.size(); ++i) m.data[i] = static_cast<uint8_t>(i * 31);
  return m;
}

class YoloDetectorNodeTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new dqo::detector::test::TempDir();
    dqo::detector::test::write_text(dir_->file("names.txt"), "person\ncup\nbook\n");
    // The test's model takes 64x64 (the shipped config says 640x640); the rest keeps its defaults.
    dqo::detector::test::write_text(dir_->file("config.yaml"), "input_size: [64, 64]\n");
    const std::vector<RawCandidate> scene = {{32, 30, 20, 8, 1, 0.9f, 1.f, {10.f, 0.f}},
                                             {33, 30, 20, 8, 1, 0.8f, 1.f, {0.f, 0.f}},
                                             {32, 30, 20, 8, 2, 0.7f, 1.f, {0.f, 10.f}},
                                             {50, 40, 12, 12, 0, 0.6f, 1.f, {-10.f, 0.f}}};
    std::vector<float> protos(2 * 16 * 16);
    for (int v = 0; v < 16; ++v)
      for (int u = 0; u < 16; ++u) protos[v * 16 + u] = u < 8 ? 1.f : -1.f, protos[256 + v * 16 + u] = 1.f;
    model_ok_ = dqo::detector::test::make_model(
        *dir_, "seg.onnx", 64, 64,
        {{{1, 9, 10}, dqo::detector::test::make_output(scene, 10, 3, 2, false)}, {{1, 2, 16, 16}, protos}});
  }
  static void TearDownTestSuite() { delete dir_; }

  void SetUp() override {
    ASSERT_TRUE(model_ok_);
    ros::NodeHandle nh;
    sub_ = nh.subscribe("/test/detections", 10, &YoloDetectorNodeTest::on_detections, this);
    image_pub_ = nh.advertise<sensor_msgs::Image>("/test/rgb", 10);
    keyframe_pub_ = nh.advertise<dqo_map::KeyFrame>("/test/keyframes", 10);
    spinner_ = std::make_unique<ros::AsyncSpinner>(1);
    spinner_->start();
  }
  void TearDown() override {
    node_.stop(10.0);
    spinner_->stop();
  }
  // roslaunch dqo_map yolo_detector.launch with the test's model and topics.
  bool launch(const std::string& model, bool keyframes_only) {
    return node_.start("/usr/bin/roslaunch",
                       {"dqo_map", "yolo_detector.launch", "model:=" + model, "classes:=" + dir_->file("names.txt"),
                        "rgb_topic:=/test/rgb", "detections_topic:=/test/detections",
                        "keyframes_topic:=/test/keyframes", "config:=" + dir_->file("config.yaml"), std::string("keyframes_only:=") + (keyframes_only ? "true" : "false"),
                        "output:=log"});
  }
  void on_detections(const dqo_map::DetectionArray::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex_);
    received_[m->header.stamp.toSec()] = *m;
  }
  bool has(double stamp) {
    std::lock_guard<std::mutex> lock(mutex_);
    return received_.count(stamp) > 0;
  }
  dqo_map::DetectionArray get(double stamp) {
    std::lock_guard<std::mutex> lock(mutex_);
    return received_.at(stamp);
  }

  static dqo::detector::test::TempDir* dir_;
  static bool model_ok_;
  ros::Subscriber sub_;
  ros::Publisher image_pub_, keyframe_pub_;
  std::unique_ptr<ros::AsyncSpinner> spinner_;
  dqo::ros_test::NodeProcess node_;
  std::mutex mutex_;
  std::map<double, dqo_map::DetectionArray> received_;
};
dqo::detector::test::TempDir* YoloDetectorNodeTest::dir_ = nullptr;
bool YoloDetectorNodeTest::model_ok_ = false;

TEST_F(YoloDetectorNodeTest, DetectsEveryImageWithBoxesClassesAndMasks) {
  ASSERT_TRUE(launch(dir_->file("seg.onnx"), false));
  ASSERT_TRUE(wait_for([&] { return image_pub_.getNumSubscribers() > 0 && sub_.getNumPublishers() > 0; }, 60.0))
      << "yolo_detector did not connect";
  // A wrong encoding first: skipped, and the node goes on.
  image_pub_.publish(colour_image("32FC1", 1.0));
  for (const auto& [enc, stamp] : {std::pair{"bgra8", 2.0}, std::pair{"rgb8", 3.0}, std::pair{"bgr8", 4.0}}) {
    image_pub_.publish(colour_image(enc, stamp));
    ASSERT_TRUE(wait_for([&] { return has(stamp); }, 20.0)) << enc;
    const dqo_map::DetectionArray d = get(stamp);
    EXPECT_EQ(d.header.frame_id, "rgb_camera_link");
    ASSERT_EQ(d.detections.size(), 3u) << enc;
    EXPECT_EQ(d.detections[0].class_name, "cup");
    EXPECT_EQ(d.detections[0].class_id, 1);
    EXPECT_NEAR(d.detections[0].score, 0.9, 1e-6);
    // Input box (22, 26)-(42, 34) back through the letterbox: (x - 0) / 0.2, (y - 8) / 0.2.
    EXPECT_NEAR(d.detections[0].x_min, 110, 1e-3);
    EXPECT_NEAR(d.detections[0].y_min, 90, 1e-3);
    EXPECT_NEAR(d.detections[0].x_max, 210, 1e-3);
    EXPECT_NEAR(d.detections[0].y_max, 130, 1e-3);
    EXPECT_EQ(d.detections[1].class_name, "book");
    EXPECT_EQ(d.detections[2].class_name, "person");
    EXPECT_NEAR(d.detections[2].x_min, 220, 1e-3);
    ASSERT_EQ(d.instance.encoding, "mono16");
    ASSERT_EQ(d.instance.width, 320u);
    auto at = [&](int x, int y) {
      const uint8_t* p = &d.instance.data[y * d.instance.step + 2 * x];
      return static_cast<int>(p[0] | (p[1] << 8));
    };
    EXPECT_EQ(at(120, 100), 1) << "the cup has the left of its box";
    EXPECT_EQ(at(200, 100), 2) << "the book the right of the same box";
    EXPECT_EQ(at(250, 160), 3);
    EXPECT_EQ(at(10, 10), 0);
  }
  EXPECT_FALSE(has(1.0)) << "the 32FC1 image was skipped";
}

TEST_F(YoloDetectorNodeTest, KeyframesOnlyDetectsTheImagesOfKeyframes) {
  ASSERT_TRUE(launch(dir_->file("seg.onnx"), true));
  ASSERT_TRUE(wait_for([&] { return image_pub_.getNumSubscribers() > 0 && keyframe_pub_.getNumSubscribers() > 0 &&
                                    sub_.getNumPublishers() > 0; }, 60.0));
  for (double t : {10.0, 11.0, 12.0}) image_pub_.publish(colour_image("bgra8", t));
  ros::WallDuration(0.5).sleep();
  dqo_map::KeyFrame kf;
  kf.header.stamp = ros::Time(11.0);  // the keyframe after its image
  keyframe_pub_.publish(kf);
  EXPECT_TRUE(wait_for([&] { return has(11.0); }, 20.0));
  kf.header.stamp = ros::Time(13.0);  // the keyframe before its image
  keyframe_pub_.publish(kf);
  ros::WallDuration(0.5).sleep();
  image_pub_.publish(colour_image("bgra8", 13.0));
  EXPECT_TRUE(wait_for([&] { return has(13.0); }, 20.0));
  ros::WallDuration(1.0).sleep();
  EXPECT_FALSE(has(10.0) || has(12.0)) << "images without a keyframe are not detected";
}

TEST_F(YoloDetectorNodeTest, AMissingModelLeavesTheNodeInert) {
  ASSERT_TRUE(launch(dir_->file("no_such_model.onnx"), false));
  ros::WallDuration(8.0).sleep();
  EXPECT_EQ(image_pub_.getNumSubscribers(), 0u) << "a node without a usable model subscribes nothing";
  EXPECT_EQ(sub_.getNumPublishers(), 0u);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "yolo_detector_test");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
