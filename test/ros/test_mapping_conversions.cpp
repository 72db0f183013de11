// The mapping nodelet's message conversions (src/ros/mapping_conversions.h), without a master: the
// Gaussian cloud against the map's own attributes, objects through a message and back, keyframes
// and events refused or accepted as the nodelet needs.

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "conversions.h"
#include "mapping_conversions.h"

namespace dqo::ros_bridge {
namespace {

gs::GaussianMap three_gaussians() {
  gs::GaussianMap map;
  for (int i = 0; i < 3; ++i) {
    gs::GaussianInit g;
    g.position = Eigen::Vector3f(0.1f * i, -0.2f, 1.0f + i);
    g.log_scale = Eigen::Vector3f(std::log(0.01f), std::log(0.02f * (i + 1)), std::log(0.005f));
    g.opacity = 0.7f;
    g.colour = Eigen::Vector3f(0.25f, 0.5f, 1.0f);
    g.object_id = static_cast<uint32_t>(i == 1 ? 7 : 0);
    map.add(g);
  }
  // Trained rotations drift off unit length: the cloud carries the unit quaternion.
  for (size_t i = 0; i < 3; ++i) map.rotations()[4 * i] = 2.0f;
  return map;
}

float field(const sensor_msgs::PointCloud2& c, size_t point, const std::string& name) {
  for (const auto& f : c.fields) {
    if (f.name == name) {
      float v;
      std::memcpy(&v, &c.data[point * c.point_step + f.offset], 4);
      return v;
    }
  }
  ADD_FAILURE() << "no field " << name;
  return NAN;
}

TEST(MappingConversions, GaussianCloudHoldsTheMapsAttributes) {
  const gs::GaussianMap map = three_gaussians();
  std_msgs::Header h;
  h.frame_id = "map";
  const sensor_msgs::PointCloud2 c = to_gaussian_cloud(map, h);
  ASSERT_EQ(c.width, 3u);
  ASSERT_EQ(c.data.size(), static_cast<size_t>(c.point_step) * 3);
  EXPECT_EQ(c.header.frame_id, "map");
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_FLOAT_EQ(field(c, i, "x"), map.positions()[3 * i]);
    EXPECT_FLOAT_EQ(field(c, i, "z"), map.positions()[3 * i + 2]);
    EXPECT_NEAR(field(c, i, "scale_1"), 0.02f * (i + 1), 1e-6);
    EXPECT_FLOAT_EQ(field(c, i, "rot_w"), 1.0f);
    EXPECT_FLOAT_EQ(field(c, i, "opacity"), 0.7f);
    EXPECT_FLOAT_EQ(field(c, i, "g"), 0.5f);
    uint32_t id, packed;
    std::memcpy(&id, &c.data[i * c.point_step + 4 * 14], 4);
    std::memcpy(&packed, &c.data[i * c.point_step + 4 * 15], 4);
    EXPECT_EQ(id, i == 1 ? 7u : 0u);
    EXPECT_EQ(packed, (64u << 16) | (128u << 8) | 255u) << "rviz's packed rgb";
  }
  EXPECT_EQ(to_gaussian_cloud(map, h, 2).width, 2u) << "every 2nd: Gaussians 0 and 2";
}

TEST(MappingConversions, ObjectsSurviveAMessage) {
  mapping::ObjectSummary s;
  s.known = true;
  s.num_gaussians = 321;
  s.object.id = 12;
  s.object.class_id = 3;
  s.object.class_name = "cup";
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.2, 0.3, 1.0).normalized()).toRotationMatrix();
  s.object.quadric = DualQuadric::from_params({0.5, -0.2, 0.8}, R, {0.1, 0.05, 0.2});
  s.object.box = OrientedBox{{0.51, -0.19, 0.79}, Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix(),
                             {0.09, 0.06, 0.21}};
  const dqo_map::Object msg = to_object_msg(s);
  EXPECT_EQ(msg.num_gaussians, 321u);
  const auto back = from_object_msg(msg);
  ASSERT_TRUE(back);
  EXPECT_EQ(back->id, 12u);
  EXPECT_EQ(back->class_name, "cup");
  EXPECT_LT((back->quadric.centre() - s.object.quadric.centre()).norm(), 1e-9);
  EXPECT_LT((back->quadric.matrix() - s.object.quadric.matrix()).norm(), 1e-9);
  EXPECT_LT((back->box.centre - s.object.box.centre).norm(), 1e-9);
  EXPECT_LT((back->box.rotation - s.object.box.rotation).norm(), 1e-9);
  EXPECT_LT((back->box.half_extents - s.object.box.half_extents).norm(), 1e-9);
  // One orientation everywhere: the record rebuilt from the 4x4 matrix (its axes come out of the
  // decomposition in another order) reports the pose and semi-axes the first message had.
  mapping::ObjectSummary again = s;
  again.object = *back;
  const dqo_map::Object msg2 = to_object_msg(again);
  const Eigen::Quaterniond q1(msg.pose.orientation.w, msg.pose.orientation.x, msg.pose.orientation.y,
                              msg.pose.orientation.z);
  const Eigen::Quaterniond q2(msg2.pose.orientation.w, msg2.pose.orientation.x, msg2.pose.orientation.y,
                              msg2.pose.orientation.z);
  EXPECT_NEAR(std::abs(q1.dot(q2)), 1.0, 1e-9);
  EXPECT_NEAR(msg.semi_axes.x, msg2.semi_axes.x, 1e-9);
  EXPECT_NEAR(msg.semi_axes.y, msg2.semi_axes.y, 1e-9);
  EXPECT_NEAR(msg.semi_axes.z, msg2.semi_axes.z, 1e-9);
  // ... and that pose is the canonical one: z nearest the map's up, x the longer horizontal axis.
  EXPECT_NEAR(msg.semi_axes.x, 0.1, 1e-12);
  EXPECT_NEAR(msg.semi_axes.z, 0.2, 1e-12);
  // An older publisher without a box: the ellipsoid's.
  dqo_map::Object no_box = msg;
  no_box.box_half_extents = geometry_msgs::Vector3();
  const auto b2 = from_object_msg(no_box);
  ASSERT_TRUE(b2);
  EXPECT_LT((b2->box.half_extents - b2->quadric.semi_axes()).norm(), 1e-9);
  EXPECT_LT((b2->box.rotation - b2->quadric.rotation()).norm(), 1e-9);
  // No proper ellipsoid anywhere: refused.
  dqo_map::Object bad = msg;
  for (double& q : bad.dual_quadric) q = 0.0;
  bad.semi_axes.x = -1.0;
  EXPECT_FALSE(from_object_msg(bad));
}

TEST(MappingConversions, KeyframesAndEvents) {
  dqo_map::KeyFrame kf;
  kf.id = 5;
  kf.header.stamp = ros::Time(12.5);
  kf.pose.orientation.w = 1.0;
  kf.camera_info = to_camera_info_msg(PinholeCamera{100, 100, 1.5, 1.5, 4, 4}, kf.header);
  ImageRgb8 rgb(4, 4, 3, 10);
  DepthImage depth(4, 4, 1, 1.25f);
  kf.rgb = to_rgb8_msg(rgb, kf.header);
  kf.depth = to_depth_mm_msg(depth, kf.header);  // 16UC1: read back as metres
  mapping::MappingKeyframe out;
  std::string error;
  ASSERT_TRUE(from_keyframe_msg(kf, &out, &error)) << error;
  EXPECT_EQ(out.id, 5u);
  EXPECT_DOUBLE_EQ(out.stamp, 12.5);
  EXPECT_FLOAT_EQ(out.depth.at(2, 2), 1.25f);
  EXPECT_EQ(out.rgb.at(1, 1, 2), 10);

  dqo_map::KeyFrame nan_pose = kf;
  nan_pose.pose.position.x = NAN;
  EXPECT_FALSE(from_keyframe_msg(nan_pose, &out, &error));
  EXPECT_NE(error.find("keyframe 5"), std::string::npos) << error;
  dqo_map::KeyFrame no_info = kf;
  no_info.camera_info.K = {};
  EXPECT_FALSE(from_keyframe_msg(no_info, &out, &error));
  dqo_map::KeyFrame yuv = kf;
  yuv.rgb.encoding = "yuv422";
  EXPECT_FALSE(from_keyframe_msg(yuv, &out, &error));
  EXPECT_NE(error.find("yuv422"), std::string::npos) << error;

  dqo_map::ObjectEvent e;
  e.type = dqo_map::ObjectEvent::MERGED;
  e.id = 4;
  e.into_id = 2;
  const auto m = from_event_msg(e);
  ASSERT_TRUE(m);
  EXPECT_EQ(m->type, mapping::MappingEvent::Type::kMerged);
  EXPECT_EQ(m->into_id, 2u);
  e.type = dqo_map::ObjectEvent::CONFIRMED;
  EXPECT_FALSE(from_event_msg(e)) << "nothing for the Gaussians to do";

  dqo_map::KeyFramePoses poses;
  poses.ids = {1, 2};
  poses.poses.resize(1);
  EXPECT_FALSE(from_keyframe_poses_msg(poses, &error));
}

}  // namespace
}  // namespace dqo::ros_bridge
