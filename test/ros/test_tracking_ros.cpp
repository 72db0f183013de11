// tracking_node's skin without a ROS master: image messages of every accepted encoding become the
// core's images (and others are refused with a message naming them), calibrations are copied, ROS
// parameter trees go through the tracking configuration's strict loader, and tf lookups do not hang
// on a stopped clock.
#include <chrono>
#include <cmath>
#include <cstring>
#include <future>
#include <limits>
#include <memory>
#include <optional>
#include <thread>

#include <gtest/gtest.h>
#include <sensor_msgs/image_encodings.h>

#include <tf2_ros/buffer.h>

#include "camera_tf.h"
#include "conversions.h"
#include "ros_params.h"

namespace {

using namespace dqo::ros_bridge;

sensor_msgs::Image colour_msg(const std::string& encoding, int channels, int padding = 0) {
  sensor_msgs::Image m;
  m.width = 3;
  m.height = 2;
  m.encoding = encoding;
  m.step = m.width * channels + padding;
  m.data.assign(m.step * m.height, 0);
  for (uint32_t y = 0; y < m.height; ++y) {
    for (uint32_t x = 0; x < m.width; ++x) {
      for (int c = 0; c < channels; ++c) m.data[y * m.step + x * channels + c] = static_cast<uint8_t>(10 * (y * 3 + x) + c);
    }
  }
  return m;
}

TEST(TrackingRos, ColourEncodingsBecomeRgb) {
  dqo::ImageRgb8 rgb;
  std::string error;
  // Pixel (x=1, y=1) holds 40 + channel in each source.
  ASSERT_TRUE(from_colour_msg(colour_msg("bgra8", 4, 5), &rgb, &error)) << error;
  EXPECT_EQ(rgb.channels, 3);
  EXPECT_EQ(rgb.at(1, 1, 0), 42);  // R is bgra's channel 2
  EXPECT_EQ(rgb.at(1, 1, 2), 40);
  ASSERT_TRUE(from_colour_msg(colour_msg("bgr8", 3), &rgb, &error)) << error;
  EXPECT_EQ(rgb.at(1, 1, 0), 42);
  ASSERT_TRUE(from_colour_msg(colour_msg("rgb8", 3, 1), &rgb, &error)) << error;
  EXPECT_EQ(rgb.at(1, 1, 0), 40);
  EXPECT_EQ(rgb.at(2, 1, 2), 52);
  ASSERT_TRUE(from_colour_msg(colour_msg("mono8", 1), &rgb, &error)) << error;
  EXPECT_EQ(rgb.at(1, 1, 0), 40);
  EXPECT_EQ(rgb.at(1, 1, 2), 40);

  EXPECT_FALSE(from_colour_msg(colour_msg("yuv422", 2), &rgb, &error));
  EXPECT_NE(error.find("'yuv422' is not supported"), std::string::npos) << error;
  auto truncated = colour_msg("bgr8", 3);
  truncated.data.resize(truncated.data.size() - 1);
  EXPECT_FALSE(from_colour_msg(truncated, &rgb, &error));
  EXPECT_NE(error.find("malformed"), std::string::npos) << error;
}

TEST(TrackingRos, DepthInMetresWithInvalidAsZero) {
  sensor_msgs::Image mm;
  mm.width = 2;
  mm.height = 1;
  mm.encoding = "16UC1";
  mm.step = 4;
  mm.data = {0xE8, 0x03, 0x00, 0x00};  // 1000 mm, 0
  dqo::DepthImage depth;
  std::string error;
  ASSERT_TRUE(from_depth_msg(mm, &depth, &error)) << error;
  EXPECT_FLOAT_EQ(depth.at(0, 0), 1.0f);
  EXPECT_EQ(depth.at(1, 0), 0.0f);
  mm.is_bigendian = 1;
  mm.data = {0x03, 0xE8, 0x00, 0x00};
  ASSERT_TRUE(from_depth_msg(mm, &depth, &error)) << error;
  EXPECT_FLOAT_EQ(depth.at(0, 0), 1.0f);

  sensor_msgs::Image m;
  m.width = 4;
  m.height = 1;
  m.encoding = "32FC1";
  m.step = 16;
  const float values[4] = {2.5f, std::numeric_limits<float>::quiet_NaN(), -1.0f,
                           std::numeric_limits<float>::infinity()};
  m.data.resize(16);
  std::memcpy(m.data.data(), values, 16);
  ASSERT_TRUE(from_depth_msg(m, &depth, &error)) << error;
  EXPECT_EQ(depth.at(0, 0), 2.5f);
  EXPECT_EQ(depth.at(1, 0), 0.0f);
  EXPECT_EQ(depth.at(2, 0), 0.0f);
  EXPECT_EQ(depth.at(3, 0), 0.0f);
  EXPECT_EQ(count_valid_depth(depth), 1u);

  m.encoding = "8UC1";
  EXPECT_FALSE(from_depth_msg(m, &depth, &error));
  EXPECT_NE(error.find("'8UC1'"), std::string::npos) << error;

  // Round trip through the KeyFrame encodings.
  const auto back = to_depth_m_msg(depth, std_msgs::Header());
  EXPECT_EQ(back.encoding, "32FC1");
  dqo::DepthImage again;
  ASSERT_TRUE(from_depth_msg(back, &again, &error));
  EXPECT_EQ(again.data, depth.data);
}

TEST(TrackingRos, CalibrationFromCameraInfo) {
  sensor_msgs::CameraInfo info;
  info.width = 1280;
  info.height = 720;
  info.distortion_model = "rational_polynomial";
  info.D = {0.1, -0.2, 0.001, 0.002, 0.05, 0.3, -0.1, 0.02};
  info.K = {600, 0, 640, 0, 601, 360, 0, 0, 1};
  info.P = {600, 0, 640, 0, 0, 601, 360, 0, 0, 0, 1, 0};
  const auto c = to_calibration(info);
  EXPECT_EQ(c.width, 1280);
  EXPECT_EQ(c.D, info.D);
  EXPECT_EQ(c.K[4], 601.0);
  EXPECT_EQ(c.P[6], 360.0);
  std::string error;
  const auto u = dqo::tracking::Undistorter::create(c, &error);
  ASSERT_TRUE(u) << error;
  // The KeyFrame's camera_info is pinhole with D = 0.
  const auto rect = to_camera_info_msg(u->camera(), std_msgs::Header(), "plumb_bob");
  for (double d : rect.D) EXPECT_EQ(d, 0.0);
  EXPECT_EQ(rect.K[0], 600.0);
}

TEST(TrackingRos, ParameterTreesGoThroughTheStrictLoader) {
  XmlRpc::XmlRpcValue tree;
  tree["orb"]["num_features"] = 1500;
  tree["orb"]["scale_factor"] = 1.25;
  tree["dense"]["iterations"].setSize(4);
  for (int i = 0; i < 4; ++i) tree["dense"]["iterations"][i] = i + 2;
  tree["use_dense"] = false;
  const std::string text = "{\"tracker\": " + to_yaml(tree) + "}";
  std::string error;
  const auto config = dqo::tracking::parse_tracking_config(text, "ROS", &error, {}, false);
  ASSERT_TRUE(config) << error << "\n" << text;
  EXPECT_EQ(config->tracker.orb.num_features, 1500);
  EXPECT_FLOAT_EQ(config->tracker.orb.scale_factor, 1.25f);
  EXPECT_EQ(config->tracker.dense.iterations[3], 5);
  EXPECT_FALSE(config->tracker.use_dense);

  tree["orb"]["num_featurs"] = 3;
  EXPECT_FALSE(dqo::tracking::parse_tracking_config("{\"tracker\": " + to_yaml(tree) + "}", "ROS parameters of /dqo_map/tracking",
                                                    &error, {}, false));
  EXPECT_EQ(error, "ROS parameters of /dqo_map/tracking: unknown key 'tracker.orb.num_featurs' (known in tracker.orb: "
                   "num_features, scale_factor, num_levels, fast_threshold, min_fast_threshold, grid_cell_px, "
                   "min_depth, max_depth)");

  XmlRpc::XmlRpcValue s("a \"quoted\"\nline");
  EXPECT_EQ(to_yaml(s), "\"a \\\"quoted\\\"\\u000aline\"");
}

}  // namespace

// pose_source tf with the ROS clock standing still (a paused bag, a test that stops /clock): a
// transform that comes a little after its image is still found, within the timeout in wall time.
// tf2's own timeout sleeps in ROS time and would wait for ever here; the lookups run on detached
// threads so that such a hang fails the test instead of stalling it.
std::future<std::optional<dqo::SE3>> lookup_async(const CameraTf& tf, const std::string& frame, const ros::Time& stamp) {
  auto promise = std::make_shared<std::promise<std::optional<dqo::SE3>>>();
  auto future = promise->get_future();
  std::thread([&tf, frame, stamp, promise] {
    std::string error;
    promise->set_value(tf.camera_pose(frame, stamp, &error));
  }).detach();
  return future;
}

TEST(TrackingRos, TfLookupWaitsInWallTimeWhileTheClockStandsStill) {
  ros::Time::init();
  ros::Time::setNow(ros::Time(100.0));  // sim time, and it does not move
  static tf2_ros::Buffer buffer;        // static: outlives a lookup left hanging by a regression
  buffer.setUsingDedicatedThread(true);
  CameraTfOptions options;
  options.map_frame = "map";
  options.timeout = 2.0;
  static const CameraTf tf(buffer, options);
  const ros::Time stamp(100.0);
  auto found = lookup_async(tf, "cam", stamp);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));  // the transform comes after the image
  geometry_msgs::TransformStamped t;
  t.header.stamp = stamp;
  t.header.frame_id = "map";
  t.child_frame_id = "cam";
  t.transform.translation.x = 1.5;
  t.transform.rotation.w = 1.0;
  buffer.setTransform(t, "test");
  ASSERT_EQ(found.wait_for(std::chrono::seconds(5)), std::future_status::ready)
      << "the lookup waited on the stopped ROS clock";
  const auto pose = found.get();
  ASSERT_TRUE(pose);
  EXPECT_DOUBLE_EQ(pose->translation().x(), 1.5);
  // A transform that never comes: nullopt after the timeout (wall time), not a hang.
  auto missing = lookup_async(tf, "other_cam", stamp);
  ASSERT_EQ(missing.wait_for(std::chrono::seconds(5)), std::future_status::ready);
  EXPECT_FALSE(missing.get());
}
