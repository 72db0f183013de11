// The object stage's skin without a ROS master (src/ros/object_conversions.h), each against an
// independent computation: the published dual quadric against T diag(a², b², c², −1) Tᵀ rebuilt from
// the published pose and semi-axes; instance renumbering pixel by pixel; markers against the
// objects; label images of every accepted encoding; raw boxes and instance images through a real
// (distorting) undistortion against densely sampled points.
#include <cmath>
#include <limits>
#include <random>
#include <set>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "conversions.h"
#include "object_conversions.h"
#include "dqo_map/objects/object_overlay.h"

namespace {

using namespace dqo;
using namespace dqo::ros_bridge;

objects::MapObject random_object(std::mt19937& rng, objects::ObjectId id) {
  std::uniform_real_distribution<double> u(-1.0, 1.0), pos(0.05, 0.5);
  Eigen::Quaterniond q(u(rng), u(rng), u(rng), u(rng));
  q.normalize();
  objects::MapObject o;
  o.id = id;
  o.state = objects::ObjectState::kConfirmed;
  o.quadric = DualQuadric::from_params(Eigen::Vector3d(u(rng), u(rng), u(rng)), q.toRotationMatrix(),
                                       Eigen::Vector3d(pos(rng), pos(rng), pos(rng)));
  o.has_quadric = true;
  o.class_id = static_cast<int>(id % 5);
  o.class_name = "class" + std::to_string(o.class_id);
  o.confidence = 0.75;
  o.observations.resize(4);
  o.observation_count = 7;
  return o;
}

TEST(ObjectConversions, DualQuadricMatchesPublishedPoseAndAxes) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 50; ++trial) {
    const objects::MapObject o = random_object(rng, 100 + trial);
    const dqo_map::Object msg = to_object_msg(o);
    EXPECT_EQ(msg.id, o.id);
    EXPECT_EQ(msg.class_name, o.class_name);
    EXPECT_EQ(msg.observations, 7u);
    EXPECT_FLOAT_EQ(msg.confidence, 0.75f);
    const auto& p = msg.pose;
    const Eigen::Quaterniond q(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z);
    EXPECT_NEAR(q.norm(), 1.0, 1e-12);
    Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
    T.topLeftCorner<3, 3>() = q.toRotationMatrix();
    T.topRightCorner<3, 1>() = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
    const Eigen::Vector4d d(msg.semi_axes.x * msg.semi_axes.x, msg.semi_axes.y * msg.semi_axes.y,
                            msg.semi_axes.z * msg.semi_axes.z, -1.0);
    const Eigen::Matrix4d expected = T * d.asDiagonal() * T.transpose();
    for (int r = 0; r < 4; ++r) {
      for (int c = 0; c < 4; ++c) EXPECT_NEAR(msg.dual_quadric[4 * r + c], expected(r, c), 1e-9) << r << "," << c;
    }
    // Row-major and symmetric, (3,3) = -1, centre = -Q*(0..2, 3).
    EXPECT_DOUBLE_EQ(msg.dual_quadric[15], -1.0);
    EXPECT_NEAR(-msg.dual_quadric[3], o.quadric.centre().x(), 1e-9);
    EXPECT_NEAR(-msg.dual_quadric[7], o.quadric.centre().y(), 1e-9);
    EXPECT_NEAR(-msg.dual_quadric[11], o.quadric.centre().z(), 1e-9);
  }
}

TEST(ObjectConversions, EventsAndDetections) {
  std_msgs::Header h;
  h.stamp = ros::Time(12.5);
  objects::ObjectEvent e;
  e.type = objects::ObjectEvent::Type::kMerged;
  e.id = 4;
  e.into_id = 2;
  dqo_map::ObjectEvent m = to_event_msg(e, h);
  EXPECT_EQ(m.type, dqo_map::ObjectEvent::MERGED);
  EXPECT_EQ(m.id, 4u);
  EXPECT_EQ(m.into_id, 2u);
  EXPECT_EQ(m.header.stamp, h.stamp);
  e.type = objects::ObjectEvent::Type::kRemoved;
  m = to_event_msg(e, h);
  EXPECT_EQ(m.type, dqo_map::ObjectEvent::REMOVED);
  EXPECT_EQ(m.into_id, 0u);  // only MERGED names a target

  dqo_map::DetectionArray arr;
  dqo_map::Detection d;
  d.class_id = 3, d.class_name = "cup", d.score = 0.5f, d.x_min = 1, d.y_min = 2, d.x_max = 30, d.y_max = 40;
  arr.detections.push_back(d);
  d.x_min = std::numeric_limits<float>::quiet_NaN(), d.x_max = -5;  // passes through for the core to judge
  arr.detections.push_back(d);
  const auto dets = from_detection_array_msg(arr);
  ASSERT_EQ(dets.size(), 2u);
  EXPECT_EQ(dets[0].class_id, 3);
  EXPECT_EQ(dets[0].class_name, "cup");
  EXPECT_EQ(dets[0].box.y_max, 40.0);
  EXPECT_TRUE(std::isnan(dets[1].box.x_min));
  EXPECT_EQ(dets[1].box.x_max, -5.0);
}

TEST(ObjectConversions, InstanceRenumbering) {
  std::mt19937 rng(5);
  InstanceImage in(37, 23, 1, 0);
  std::uniform_int_distribution<int> v(0, 9);  // 0 = none, 1..9 = input detections 0..8; 9 also a stray value
  for (auto& x : in.data) x = static_cast<uint16_t>(v(rng));
  const std::vector<int> source = {1, 4, 5, 8};  // filtered detection j came from input source[j]
  const InstanceImage out = objects::renumber_instance(in, source);
  ASSERT_EQ(out.width, in.width);
  ASSERT_EQ(out.height, in.height);
  for (size_t i = 0; i < in.data.size(); ++i) {
    uint16_t expected = 0;
    for (size_t j = 0; j < source.size(); ++j) {
      if (in.data[i] == source[j] + 1) expected = static_cast<uint16_t>(j + 1);
    }
    EXPECT_EQ(out.data[i], expected) << i;
  }

  objects::KeyFrameAssociation a;
  a.keyframe_id = 17;
  for (int j = 0; j < 4; ++j) {
    Detection2d det;
    det.class_id = j;
    det.box = Box2d{1.0 * j, 2.0, 10.0 + j, 20.0};
    a.filtered.push_back(det);
    a.filtered_source.push_back(source[j]);
    a.filtered_object_ids.push_back(j == 2 ? 0 : 10 + j);
  }
  std_msgs::Header h;
  h.frame_id = "rgb_camera_link";
  const dqo_map::KeyFrameObjects msg = to_keyframe_objects_msg(a, h, out);
  EXPECT_EQ(msg.keyframe_id, 17u);
  ASSERT_EQ(msg.detections.detections.size(), msg.object_ids.size());
  ASSERT_EQ(msg.object_ids.size(), 4u);
  EXPECT_EQ(msg.object_ids[2], 0u);
  EXPECT_EQ(msg.object_ids[3], 13u);
  EXPECT_FLOAT_EQ(msg.detections.detections[3].x_min, 3.0f);
  ASSERT_EQ(msg.detections.instance.encoding, "mono16");
  ASSERT_EQ(msg.detections.instance.width, 37u);
  LabelImage back;
  std::string error;
  ASSERT_TRUE(from_label_msg(msg.detections.instance, &back, &error)) << error;
  for (size_t i = 0; i < out.data.size(); ++i) ASSERT_EQ(back.data[i], out.data[i]);
  // Without an instance image the message carries none.
  EXPECT_EQ(to_keyframe_objects_msg(a, h, InstanceImage()).detections.instance.width, 0u);
}

TEST(ObjectConversions, LabelEncodings) {
  auto make = [](const std::string& enc, int bytes, bool big) {
    sensor_msgs::Image m;
    m.width = 2, m.height = 2, m.encoding = enc, m.is_bigendian = big;
    m.step = 2 * bytes + 1;  // padded rows
    m.data.assign(m.step * 2, 0);
    return m;
  };
  LabelImage labels;
  std::string error;
  sensor_msgs::Image rgb = make("rgb8", 3, false);
  rgb.data[rgb.step + 3 + 0] = 0x12, rgb.data[rgb.step + 3 + 1] = 0x34, rgb.data[rgb.step + 3 + 2] = 0x56;
  ASSERT_TRUE(from_label_msg(rgb, &labels, &error)) << error;
  EXPECT_EQ(labels.at(1, 1), pack_rgb(0x12, 0x34, 0x56));
  EXPECT_EQ(labels.at(0, 0), 0u);
  sensor_msgs::Image bgr = rgb;
  bgr.encoding = "bgr8";
  ASSERT_TRUE(from_label_msg(bgr, &labels, &error)) << error;
  EXPECT_EQ(labels.at(1, 1), pack_rgb(0x56, 0x34, 0x12));
  sensor_msgs::Image m16 = make("mono16", 2, true);
  m16.data[m16.step + 2] = 0x01, m16.data[m16.step + 3] = 0x02;  // big-endian 0x0102 at (1, 1)
  ASSERT_TRUE(from_label_msg(m16, &labels, &error)) << error;
  EXPECT_EQ(labels.at(1, 1), 0x0102u);
  m16.is_bigendian = false;
  ASSERT_TRUE(from_label_msg(m16, &labels, &error)) << error;
  EXPECT_EQ(labels.at(1, 1), 0x0201u);
  sensor_msgs::Image m8 = make("mono8", 1, false);
  m8.data[1] = 200;
  ASSERT_TRUE(from_label_msg(m8, &labels, &error)) << error;
  EXPECT_EQ(labels.at(1, 0), 200u);

  sensor_msgs::Image bad = make("32FC1", 4, false);
  EXPECT_FALSE(from_label_msg(bad, &labels, &error));
  EXPECT_NE(error.find("32FC1"), std::string::npos) << error;
  sensor_msgs::Image short_data = make("mono16", 2, false);
  short_data.data.resize(3);
  EXPECT_FALSE(from_label_msg(short_data, &labels, &error));
}

TEST(ObjectConversions, Markers) {
  std::mt19937 rng(2);
  std::vector<objects::MapObject> objs = {random_object(rng, 3), random_object(rng, 4)};
  std_msgs::Header h;
  h.frame_id = "map";
  const auto arr = to_marker_array(objs, {9}, h);
  ASSERT_EQ(arr.markers.size(), 6u);  // 2 x (ellipsoid + label) + 2 deletes
  for (size_t i = 0; i < objs.size(); ++i) {
    const auto& s = arr.markers[2 * i];
    const auto& t = arr.markers[2 * i + 1];
    const dqo_map::Object o = to_object_msg(objs[i]);
    EXPECT_EQ(s.type, visualization_msgs::Marker::SPHERE);
    EXPECT_EQ(s.id, static_cast<int>(objs[i].id));
    EXPECT_EQ(s.header.frame_id, "map");
    // The marker is the ellipsoid: R diag(scale / 2)² Rᵀ is the quadric's shape (its axes in the one
    // reported order, canonical_axes), and its pose and scale are the object message's.
    const Eigen::Quaterniond q(s.pose.orientation.w, s.pose.orientation.x, s.pose.orientation.y, s.pose.orientation.z);
    const Eigen::Matrix3d R = q.toRotationMatrix();
    const Eigen::Vector3d half(0.5 * s.scale.x, 0.5 * s.scale.y, 0.5 * s.scale.z);
    const Eigen::Matrix3d shape = R * half.array().square().matrix().asDiagonal() * R.transpose();
    const DualQuadric& Q = objs[i].quadric;
    const Eigen::Matrix3d truth = Q.rotation() * Q.semi_axes().array().square().matrix().asDiagonal() * Q.rotation().transpose();
    EXPECT_LT((shape - truth).norm(), 1e-9);
    EXPECT_DOUBLE_EQ(s.scale.x, 2.0 * o.semi_axes.x);
    EXPECT_DOUBLE_EQ(s.scale.z, 2.0 * o.semi_axes.z);
    EXPECT_NEAR(std::abs(q.dot(Eigen::Quaterniond(o.pose.orientation.w, o.pose.orientation.x, o.pose.orientation.y,
                                                  o.pose.orientation.z))),
                1.0, 1e-12);
    EXPECT_NEAR(s.pose.position.x, objs[i].quadric.centre().x(), 1e-12);
    EXPECT_EQ(t.type, visualization_msgs::Marker::TEXT_VIEW_FACING);
    EXPECT_EQ(t.text, std::to_string(objs[i].id) + " " + objs[i].class_name);
    EXPECT_GT(t.pose.position.z, s.pose.position.z);
    // The object overlay's palette of the same objects (one colour per object in both).
    const objects::Rgb drawn = objects::palette_of_confirmed(objs).colour(objs[i].id);
    EXPECT_NEAR(s.color.r * 255.0f, drawn[0], 1e-3);
    EXPECT_NEAR(s.color.g * 255.0f, drawn[1], 1e-3);
    EXPECT_NEAR(s.color.b * 255.0f, drawn[2], 1e-3);
    EXPECT_EQ(t.color.r, s.color.r);
  }
  EXPECT_EQ(arr.markers[4].action, visualization_msgs::Marker::DELETE);
  EXPECT_EQ(arr.markers[4].id, 9);
  EXPECT_EQ(arr.markers[5].action, visualization_msgs::Marker::DELETE);
  EXPECT_NE(arr.markers[4].ns, arr.markers[5].ns);
  // Stable per ID, and consecutive IDs look different.
  for (objects::ObjectId id = 1; id < 30; ++id) {
    const auto a = colour_of_id(id), b = colour_of_id(id), c = colour_of_id(id + 1);
    EXPECT_EQ(a.r, b.r);
    EXPECT_EQ(a.g, b.g);
    EXPECT_GT(std::abs(a.r - c.r) + std::abs(a.g - c.g) + std::abs(a.b - c.b), 0.1) << id;
    // The same colour as the object overlay draws the object in (rviz beside the overlay image).
    const objects::Rgb drawn = objects::overlay_colour(id);
    EXPECT_NEAR(a.r * 255.0f, drawn[0], 1e-3) << id;
    EXPECT_NEAR(a.g * 255.0f, drawn[1], 1e-3) << id;
    EXPECT_NEAR(a.b * 255.0f, drawn[2], 1e-3) << id;
  }
}

tracking::CameraCalibration distorted_camera() {
  tracking::CameraCalibration c;
  c.width = 160, c.height = 120;
  c.K = {140.0, 0.0, 79.5, 0.0, 140.0, 59.5, 0.0, 0.0, 1.0};
  c.distortion_model = "plumb_bob";
  c.D = {-0.25, 0.08, 0.001, -0.001, 0.0};
  return c;
}

TEST(ObjectConversions, RectifiedBoxesEncloseTheBoundary) {
  std::string error;
  const auto und = tracking::Undistorter::create(distorted_camera(), &error);
  ASSERT_TRUE(und) << error;
  ASSERT_FALSE(und->is_identity());
  const Box2d raw{10.0, 8.0, 70.0, 50.0};
  const Box2d r = und->rectify_box(raw);
  // Independently: the bounding box of many boundary points, each rectified.
  Box2d dense{1e9, 1e9, -1e9, -1e9};
  for (int i = 0; i <= 400; ++i) {
    const double s = i / 400.0;
    for (const Eigen::Vector2d& p :
         {Eigen::Vector2d(raw.x_min + s * raw.width(), raw.y_min), Eigen::Vector2d(raw.x_min + s * raw.width(), raw.y_max),
          Eigen::Vector2d(raw.x_min, raw.y_min + s * raw.height()), Eigen::Vector2d(raw.x_max, raw.y_min + s * raw.height())}) {
      const Eigen::Vector2d q = und->rectify_point(p);
      dense.x_min = std::min(dense.x_min, q.x()), dense.x_max = std::max(dense.x_max, q.x());
      dense.y_min = std::min(dense.y_min, q.y()), dense.y_max = std::max(dense.y_max, q.y());
    }
  }
  EXPECT_NEAR(r.x_min, dense.x_min, 0.05);
  EXPECT_NEAR(r.x_max, dense.x_max, 0.05);
  EXPECT_NEAR(r.y_min, dense.y_min, 0.05);
  EXPECT_NEAR(r.y_max, dense.y_max, 0.05);
  EXPECT_GT(std::abs(r.x_min - raw.x_min) + std::abs(r.y_min - raw.y_min), 0.5) << "the distortion should move the box";

  const Box2d nan_box{std::numeric_limits<double>::quiet_NaN(), 1.0, 5.0, 6.0};
  EXPECT_TRUE(std::isnan(und->rectify_box(nan_box).x_min));
  EXPECT_EQ(und->rectify_box(nan_box).x_max, 5.0);
}

TEST(ObjectConversions, RectifiedInstanceImageByNearestNeighbour) {
  std::string error;
  const auto und = tracking::Undistorter::create(distorted_camera(), &error);
  ASSERT_TRUE(und) << error;
  InstanceImage raw(160, 120, 1, 0);
  for (int y = 0; y < 120; ++y) {
    for (int x = 0; x < 160; ++x) raw.at(x, y) = static_cast<uint16_t>(1 + (x / 20) + 8 * (y / 20));
  }
  InstanceImage rect;
  ASSERT_TRUE(und->rectify_labels(raw, &rect, &error)) << error;
  ASSERT_EQ(rect.width, 160);
  std::set<uint16_t> values(raw.data.begin(), raw.data.end());
  int agree = 0, total = 0;
  for (int y = 0; y < 120; ++y) {
    for (int x = 0; x < 160; ++x) {
      const uint16_t v = rect.at(x, y);
      EXPECT_TRUE(v == 0 || values.count(v)) << "a blended label " << v;
      const Eigen::Vector2d src = und->distort_point(Eigen::Vector2d(x, y));
      const int u = static_cast<int>(std::lround(src.x())), w = static_cast<int>(std::lround(src.y()));
      if (u < 0 || w < 0 || u >= 160 || w >= 120) continue;
      ++total;
      agree += v == raw.at(u, w);
    }
  }
  // Nearest-neighbour rounding may differ exactly on cell borders; everywhere else it agrees.
  EXPECT_GT(agree, 0.97 * total);
  InstanceImage wrong(10, 10, 1, 0);
  EXPECT_FALSE(und->rectify_labels(wrong, &rect, &error));
}

TEST(ObjectConversions, KeyFrameToMapperInput) {
  // A keyframe of the rectified camera, 16UC1 millimetre depth, raw boxes and a raw instance image.
  dqo_map::KeyFrame kf;
  kf.id = 42;
  kf.header.stamp = ros::Time(100.25);
  kf.pose.position.x = 1.0, kf.pose.position.z = -2.0;
  kf.pose.orientation.w = std::cos(0.3), kf.pose.orientation.z = std::sin(0.3);
  PinholeCamera cam{150.0, 151.0, 80.0, 60.0, 160, 120};
  kf.camera_info = to_camera_info_msg(cam, kf.header);
  DepthImage depth(160, 120, 1, 1.5f);
  depth.at(7, 9) = 0.0f;
  kf.depth = to_depth_mm_msg(depth, kf.header);
  dqo_map::DetectionArray det;
  dqo_map::Detection d;
  d.class_id = 2, d.x_min = 10, d.y_min = 8, d.x_max = 70, d.y_max = 50;
  det.detections.push_back(d);
  InstanceImage inst(160, 120, 1, 0);
  for (int y = 8; y < 50; ++y) {
    for (int x = 10; x < 70; ++x) inst.at(x, y) = 1;
  }
  det.instance = to_mono16_msg(inst, kf.header);

  std::string error;
  const auto und = tracking::Undistorter::create(distorted_camera(), &error);
  ASSERT_TRUE(und) << error;
  objects::ObjectKeyFrame okf;
  DepthImage storage;
  InstanceImage instance;
  std::vector<std::string> warnings;
  ASSERT_TRUE(to_object_keyframe(kf, det, &*und, &okf, &storage, &instance, &warnings, &error)) << error;
  EXPECT_TRUE(warnings.empty());
  EXPECT_EQ(okf.id, 42u);
  EXPECT_DOUBLE_EQ(okf.stamp, 100.25);
  EXPECT_EQ(okf.camera.fx, 150.0);
  EXPECT_EQ(okf.camera.fy, 151.0);
  EXPECT_EQ(okf.camera.cy, 60.0);
  EXPECT_EQ(okf.camera.width, 160);
  EXPECT_NEAR(okf.T_wc.translation().z(), -2.0, 1e-12);
  EXPECT_NEAR(okf.T_wc.quaternion().angularDistance(Eigen::Quaterniond(std::cos(0.3), 0, 0, std::sin(0.3))), 0.0, 1e-12);
  ASSERT_NE(okf.depth.data, nullptr);
  EXPECT_FLOAT_EQ(okf.depth.at(3, 4), 1.5f);
  EXPECT_EQ(okf.depth.at(7, 9), 0.0f);
  ASSERT_EQ(okf.detections.size(), 1u);
  const Box2d expected_box = und->rectify_box(Box2d{10, 8, 70, 50});
  EXPECT_DOUBLE_EQ(okf.detections[0].box.x_min, expected_box.x_min);
  EXPECT_DOUBLE_EQ(okf.detections[0].box.y_max, expected_box.y_max);
  InstanceImage expected_instance;
  ASSERT_TRUE(und->rectify_labels(inst, &expected_instance, &error));
  EXPECT_EQ(instance.data, expected_instance.data);

  // Rectified detections: boxes and instance image as they came.
  ASSERT_TRUE(to_object_keyframe(kf, det, nullptr, &okf, &storage, &instance, &warnings, &error));
  EXPECT_EQ(okf.detections[0].box.x_min, 10.0);
  EXPECT_EQ(instance.data, inst.data);

  // An unsupported depth encoding and an instance image of the wrong size: usable, with warnings.
  kf.depth.encoding = "yuv422";
  det.instance = to_mono16_msg(InstanceImage(20, 20, 1, 1), kf.header);
  warnings.clear();
  ASSERT_TRUE(to_object_keyframe(kf, det, nullptr, &okf, &storage, &instance, &warnings, &error));
  EXPECT_EQ(okf.depth.data, nullptr);
  EXPECT_TRUE(instance.empty());
  ASSERT_EQ(warnings.size(), 2u);
  EXPECT_NE(warnings[0].find("yuv422"), std::string::npos) << warnings[0];

  // No camera: refused.
  kf.camera_info.K[0] = 0.0;
  EXPECT_FALSE(to_object_keyframe(kf, det, nullptr, &okf, &storage, &instance, &warnings, &error));
  EXPECT_NE(error.find("camera_info"), std::string::npos) << error;
}

}  // namespace
