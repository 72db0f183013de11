// rostest of mask_detector_node (test/ros/mask_detector.test): masks of each accepted encoding in,
// detections out. Boxes, classes (from the launch file's table, the default class for unknown
// instances) and the attached instance image are checked against what the test drew; a mask of an
// unsupported encoding is skipped and the node keeps answering.
#include <mutex>

#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>

#include <dqo_map/DetectionArray.h>

#include "ros_test_util.h"

namespace {

struct Rect {
  int x0, y0, x1, y1;  // inclusive pixel ranges
};

// A width x height mask of `bytes` per pixel with `value_bytes` written into each rectangle.
sensor_msgs::Image make_mask(const std::string& encoding, int bytes, const std::vector<Rect>& rects,
                             const std::vector<std::vector<uint8_t>>& values, uint32_t index) {
  sensor_msgs::Image m;
  m.header.stamp = ros::Time(10.0 + index);  // the test matches replies by stamp
  m.header.frame_id = "cam";
  m.width = 40, m.height = 30, m.encoding = encoding, m.is_bigendian = 0;
  m.step = m.width * bytes;
  m.data.assign(m.step * m.height, 0);
  for (size_t k = 0; k < rects.size(); ++k) {
    for (int y = rects[k].y0; y <= rects[k].y1; ++y) {
      for (int x = rects[k].x0; x <= rects[k].x1; ++x) {
        for (int b = 0; b < bytes; ++b) m.data[y * m.step + x * bytes + b] = values[k][b];
      }
    }
  }
  return m;
}

class MaskDetectorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ros::NodeHandle nh;
    sub_ = nh.subscribe("/test/detections", 10, &MaskDetectorTest::on_detections, this);
    pub_ = nh.advertise<sensor_msgs::Image>("/test/instance", 10);
    spinner_ = std::make_unique<ros::AsyncSpinner>(1);
    spinner_->start();
    dqo::ros_test::wait_for([&] { return pub_.getNumSubscribers() > 0 && sub_.getNumPublishers() > 0; }, 30.0);
    ASSERT_GT(pub_.getNumSubscribers(), 0u) << "mask_detector_node did not connect";
  }
  void TearDown() override { spinner_->stop(); }

  void on_detections(const dqo_map::DetectionArray::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex_);
    received_[m->header.stamp.toSec()] = *m;
  }
  // Publishes a mask and waits for its detections (matched by stamp).
  bool round_trip(const sensor_msgs::Image& mask, dqo_map::DetectionArray* out, double wait_s = 10.0) {
    pub_.publish(mask);
    return dqo::ros_test::wait_for(
        [&] {
          std::lock_guard<std::mutex> lock(mutex_);
          auto it = received_.find(mask.header.stamp.toSec());
          if (it == received_.end()) return false;
          *out = it->second;
          return true;
        },
        wait_s);
  }

  std::mutex mutex_;
  std::map<double, dqo_map::DetectionArray> received_;  // by stamp (roscpp rewrites seq)
  ros::Subscriber sub_;
  ros::Publisher pub_;
  std::unique_ptr<ros::AsyncSpinner> spinner_;
};

void expect_box(const dqo_map::Detection& d, const Rect& r) {
  EXPECT_FLOAT_EQ(d.x_min, std::max(0.0f, r.x0 - 0.5f));
  EXPECT_FLOAT_EQ(d.y_min, std::max(0.0f, r.y0 - 0.5f));
  EXPECT_FLOAT_EQ(d.x_max, r.x1 + 0.5f);
  EXPECT_FLOAT_EQ(d.y_max, r.y1 + 0.5f);
}

TEST_F(MaskDetectorTest, Mono16ColourAndBadEncodings) {
  // mono16: value 3 (in the table: cup), value 9 (unknown: the default class), value 5 too small.
  const std::vector<Rect> rects = {{2, 3, 10, 12}, {20, 5, 30, 20}, {35, 25, 35, 25}};
  dqo_map::DetectionArray det;
  ASSERT_TRUE(round_trip(make_mask("mono16", 2, rects, {{3, 0}, {9, 0}, {5, 0}}, 1), &det));
  ASSERT_EQ(det.detections.size(), 2u);
  EXPECT_EQ(det.header.frame_id, "cam");
  EXPECT_EQ(det.header.stamp, ros::Time(11.0));
  EXPECT_EQ(det.detections[0].class_name, "cup");
  EXPECT_EQ(det.detections[0].class_id, 7);
  EXPECT_FLOAT_EQ(det.detections[0].score, 1.0f);
  expect_box(det.detections[0], rects[0]);
  EXPECT_EQ(det.detections[1].class_name, "object");  // config/mask_detector.yaml's default
  expect_box(det.detections[1], rects[1]);
  // The instance image: value k+1 inside rectangle k, 0 elsewhere (the dropped one too).
  ASSERT_EQ(det.instance.encoding, "mono16");
  ASSERT_EQ(det.instance.width, 40u);
  auto value_at = [&](int x, int y) {
    return static_cast<int>(det.instance.data[y * det.instance.step + 2 * x] |
                            (det.instance.data[y * det.instance.step + 2 * x + 1] << 8));
  };
  EXPECT_EQ(value_at(5, 5), 1);
  EXPECT_EQ(value_at(25, 10), 2);
  EXPECT_EQ(value_at(35, 25), 0);
  EXPECT_EQ(value_at(15, 25), 0);

  // rgb8: red is a book, green unknown.
  const std::vector<Rect> crects = {{0, 0, 8, 8}, {15, 10, 25, 28}};
  ASSERT_TRUE(round_trip(make_mask("rgb8", 3, crects, {{255, 0, 0}, {0, 255, 0}}, 2), &det));
  ASSERT_EQ(det.detections.size(), 2u);
  // Labels ascend: green (0x00ff00) before red (0xff0000).
  EXPECT_EQ(det.detections[0].class_name, "object");
  expect_box(det.detections[0], crects[1]);
  EXPECT_EQ(det.detections[1].class_name, "book");
  EXPECT_EQ(det.detections[1].class_id, 8);
  expect_box(det.detections[1], crects[0]);

  // An unsupported encoding is skipped; the next good mask is still answered.
  EXPECT_FALSE(round_trip(make_mask("32FC1", 4, {}, {}, 3), &det, 1.0));
  ASSERT_TRUE(round_trip(make_mask("mono8", 1, {{1, 1, 6, 6}}, {{3}}, 4), &det));
  ASSERT_EQ(det.detections.size(), 1u);
  EXPECT_EQ(det.detections[0].class_name, "cup");
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_mask_detector_node");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
