#include "object_conversions.h"

#include "dqo_map/objects/object_overlay.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include <sensor_msgs/image_encodings.h>

#include "conversions.h"

namespace dqo::ros_bridge {

void set_object_geometry(const DualQuadric& q, const OrientedBox& box, dqo_map::Object* msg) {
  // One orientation everywhere (canonical_axes): the association node's ellipsoid and the mapping
  // nodelet's (rebuilt from the 4x4 matrix, its axes in another order) report the same pose.
  Eigen::Matrix3d R = q.rotation();
  Eigen::Vector3d axes = q.semi_axes();
  canonical_axes(&R, &axes);
  msg->pose = to_pose_msg(SE3::from_rotation_translation(R, q.centre()));
  msg->semi_axes.x = axes.x();
  msg->semi_axes.y = axes.y();
  msg->semi_axes.z = axes.z();
  const Eigen::Matrix4d Q = q.matrix();
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) msg->dual_quadric[4 * r + c] = Q(r, c);
  }
  Eigen::Matrix3d B = box.rotation;
  Eigen::Vector3d half = box.half_extents;
  canonical_axes(&B, &half);
  msg->box_pose = to_pose_msg(SE3::from_rotation_translation(B, box.centre));
  msg->box_half_extents.x = half.x();
  msg->box_half_extents.y = half.y();
  msg->box_half_extents.z = half.z();
}

dqo_map::Object to_object_msg(const objects::MapObject& object, const std::map<int, std::string>& class_names,
                              int top_classes) {
  dqo_map::Object msg;
  msg.id = object.id;
  msg.class_id = object.class_id;
  msg.class_name = object.class_name;
  const DualQuadric& q = object.quadric;
  // The box the meshes are cut to (the mapping nodelet's, as the offline runner's records): the
  // fitted one where there is one.
  set_object_geometry(q, object.has_box ? object.box : OrientedBox{q.centre(), q.rotation(), q.semi_axes()}, &msg);
  // observation_count also counts observations from before a restart and of merged pieces.
  msg.observations = static_cast<uint32_t>(std::max<size_t>(object.observation_count, object.observations.size()));
  msg.confidence = static_cast<float>(object.confidence);
  for (const objects::ClassShare& c : objects::top_classes(object, top_classes, class_names)) {
    msg.top_class_ids.push_back(c.class_id);
    msg.top_class_names.push_back(c.class_name);
    msg.top_class_shares.push_back(static_cast<float>(c.share));
  }
  msg.existence = static_cast<float>(objects::existence_probability(object));
  msg.num_gaussians = 0;
  return msg;
}

dqo_map::ObjectEvent to_event_msg(const objects::ObjectEvent& event, const std_msgs::Header& header) {
  dqo_map::ObjectEvent msg;
  msg.header = header;
  switch (event.type) {
    case objects::ObjectEvent::Type::kCreated: msg.type = dqo_map::ObjectEvent::CREATED; break;
    case objects::ObjectEvent::Type::kMerged: msg.type = dqo_map::ObjectEvent::MERGED; break;
    case objects::ObjectEvent::Type::kRemoved: msg.type = dqo_map::ObjectEvent::REMOVED; break;
    case objects::ObjectEvent::Type::kRenamed: msg.type = dqo_map::ObjectEvent::RENAMED; break;
  }
  if (event.type == objects::ObjectEvent::Type::kRenamed) {
    msg.class_id = event.class_id;
    msg.class_name = event.class_name;
  }
  msg.id = event.id;
  msg.into_id = event.type == objects::ObjectEvent::Type::kMerged ? event.into_id : 0;
  return msg;
}

std::vector<Detection2d> from_detection_array_msg(const dqo_map::DetectionArray& msg) {
  std::vector<Detection2d> out;
  out.reserve(msg.detections.size());
  for (const auto& d : msg.detections) {
    Detection2d det;
    det.class_id = d.class_id;
    det.class_name = d.class_name;
    det.score = d.score;
    det.box = Box2d{d.x_min, d.y_min, d.x_max, d.y_max};
    out.push_back(det);
  }
  return out;
}

bool from_label_msg(const sensor_msgs::Image& msg, LabelImage* labels, std::string* error) {
  namespace enc = sensor_msgs::image_encodings;
  int bytes = 0;
  bool colour = false, bgr = false;
  if (msg.encoding == enc::MONO8 || msg.encoding == enc::TYPE_8UC1) {
    bytes = 1;
  } else if (msg.encoding == enc::MONO16 || msg.encoding == enc::TYPE_16UC1) {
    bytes = 2;
  } else if (msg.encoding == enc::RGB8 || msg.encoding == enc::BGR8) {
    bytes = 3, colour = true, bgr = msg.encoding == enc::BGR8;
  } else {
    if (error) *error = "instance image encoding '" + msg.encoding + "' is not supported (mono8, mono16, rgb8, bgr8)";
    return false;
  }
  if (!check_image_layout(msg, bytes, "instance", error)) return false;
  *labels = LabelImage(static_cast<int>(msg.width), static_cast<int>(msg.height), 1, 0);
  uint32_t* out = labels->data.data();
  for (uint32_t y = 0; y < msg.height; ++y) {
    const uint8_t* in = msg.data.data() + static_cast<size_t>(y) * msg.step;
    for (uint32_t x = 0; x < msg.width; ++x, in += bytes, ++out) {
      if (bytes == 1) {
        *out = in[0];
      } else if (bytes == 2) {
        *out = msg.is_bigendian ? (uint32_t(in[0]) << 8 | in[1]) : (uint32_t(in[1]) << 8 | in[0]);
      } else if (colour) {
        *out = bgr ? pack_rgb(in[2], in[1], in[0]) : pack_rgb(in[0], in[1], in[2]);
      }
    }
  }
  return true;
}

bool to_object_keyframe(const dqo_map::KeyFrame& kf, const dqo_map::DetectionArray& detections,
                        const tracking::Undistorter* undistorter, objects::ObjectKeyFrame* out,
                        DepthImage* depth, InstanceImage* instance, std::vector<std::string>* warnings,
                        std::string* error) {
  PinholeCamera camera;
  if (!from_camera_info_msg(kf.camera_info, &camera, nullptr)) {
    if (error) *error = "keyframe " + std::to_string(kf.id) + " has no usable camera_info (K and size)";
    return false;
  }
  out->id = kf.id;
  out->stamp = kf.header.stamp.toSec();
  out->camera = camera;
  out->T_wc = from_pose_msg(kf.pose);
  out->depth = DepthView{};
  std::string why;
  if (!from_depth_msg(kf.depth, depth, &why)) {
    warnings->push_back(why + ": used without depth (no single-view initialisation)");
  } else if (!depth->same_size(camera.width, camera.height)) {
    warnings->push_back("depth is " + std::to_string(depth->width) + "x" + std::to_string(depth->height) +
                        ", the camera " + std::to_string(camera.width) + "x" + std::to_string(camera.height) +
                        ": used without depth");
  } else {
    out->depth = DepthView{depth->data.data(), depth->width, depth->height};
  }
  out->detections = from_detection_array_msg(detections);
  if (undistorter) {
    for (Detection2d& d : out->detections) d.box = undistorter->rectify_box(d.box);
  }
  *instance = InstanceImage();
  if (detections.instance.width == 0 || detections.instance.height == 0) return true;
  LabelImage labels;
  if (!from_label_msg(detections.instance, &labels, &why)) {
    warnings->push_back(why + ": detections used without their instance image");
    return true;
  }
  InstanceImage raw = to_instance_image(labels);
  if (!raw.same_size(camera.width, camera.height)) {
    warnings->push_back("instance image is " + std::to_string(raw.width) + "x" + std::to_string(raw.height) +
                        ", the camera " + std::to_string(camera.width) + "x" + std::to_string(camera.height) +
                        ": detections used without it");
  } else if (undistorter && !undistorter->rectify_labels(raw, instance, &why)) {
    warnings->push_back(why + ": detections used without their instance image");
  } else if (!undistorter) {
    *instance = std::move(raw);
  }
  return true;
}

dqo_map::KeyFrameObjects to_keyframe_objects_msg(const objects::KeyFrameAssociation& association,
                                                 const std_msgs::Header& header,
                                                 const InstanceImage& instance) {
  dqo_map::KeyFrameObjects msg;
  msg.header = header;
  msg.keyframe_id = association.keyframe_id;
  msg.detections = to_detection_array_msg(association.filtered, header);
  msg.object_ids.assign(association.filtered_object_ids.begin(), association.filtered_object_ids.end());
  // The two arrays must stay parallel even if the core handed back a shorter ID list.
  msg.object_ids.resize(msg.detections.detections.size(), 0);
  if (!instance.empty()) msg.detections.instance = to_mono16_msg(instance, header);
  return msg;
}

std_msgs::ColorRGBA to_rgba(const objects::Rgb& rgb) {
  std_msgs::ColorRGBA c;
  c.r = rgb[0] / 255.0f;
  c.g = rgb[1] / 255.0f;
  c.b = rgb[2] / 255.0f;
  c.a = 1.0f;
  return c;
}

std_msgs::ColorRGBA colour_of_id(objects::ObjectId id) { return to_rgba(objects::overlay_colour(id)); }

visualization_msgs::MarkerArray to_marker_array(const std::vector<objects::MapObject>& objects,
                                                const std::vector<objects::ObjectId>& deleted,
                                                const std_msgs::Header& header) {
  visualization_msgs::MarkerArray out;
  // The object overlay's palette of the same objects: an object has one colour in both.
  const objects::ObjectPalette palette = objects::palette_of_confirmed(objects);
  for (const objects::MapObject& o : objects) {
    if (!o.has_quadric) continue;
    const dqo_map::Object obj = to_object_msg(o);
    visualization_msgs::Marker m;
    m.header = header;
    m.ns = "ellipsoids";
    m.id = static_cast<int32_t>(o.id);
    m.type = visualization_msgs::Marker::SPHERE;
    m.action = visualization_msgs::Marker::ADD;
    m.pose = obj.pose;
    // A SPHERE marker's scale is its diameter along each of its pose's axes.
    m.scale.x = 2.0 * obj.semi_axes.x;
    m.scale.y = 2.0 * obj.semi_axes.y;
    m.scale.z = 2.0 * obj.semi_axes.z;
    m.color = to_rgba(palette.colour(o.id));
    m.color.a = 0.5f;  // see-through, so the Gaussians / point cloud inside stay visible
    out.markers.push_back(m);

    visualization_msgs::Marker t;
    t.header = header;
    t.ns = "labels";
    t.id = m.id;
    t.type = visualization_msgs::Marker::TEXT_VIEW_FACING;
    t.action = visualization_msgs::Marker::ADD;
    t.pose.orientation.w = 1.0;
    t.pose.position = obj.pose.position;
    // Above the ellipsoid whatever its orientation: the largest semi-axis bounds its extent.
    t.pose.position.z += o.quadric.semi_axes().maxCoeff() + 0.05;
    t.scale.z = 0.08;  // text height, metres
    t.color = to_rgba(palette.colour(o.id));
    t.text = std::to_string(o.id) + " " + o.class_name;
    out.markers.push_back(t);
  }
  for (const objects::ObjectId id : deleted) {
    for (const char* ns : {"ellipsoids", "labels"}) {
      visualization_msgs::Marker d;
      d.header = header;
      d.ns = ns;
      d.id = static_cast<int32_t>(id);
      d.action = visualization_msgs::Marker::DELETE;
      out.markers.push_back(d);
    }
  }
  return out;
}

}  // namespace dqo::ros_bridge
