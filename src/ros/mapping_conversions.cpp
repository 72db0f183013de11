#include "mapping_conversions.h"

#include <cmath>
#include <cstring>

#include "conversions.h"
#include "object_conversions.h"

namespace dqo::ros_bridge {

namespace {

Eigen::Vector3d to_vector(const geometry_msgs::Vector3& v) { return {v.x, v.y, v.z}; }

bool finite_pose(const geometry_msgs::Pose& p) {
  return std::isfinite(p.position.x) && std::isfinite(p.position.y) && std::isfinite(p.position.z) &&
         std::isfinite(p.orientation.w) && std::isfinite(p.orientation.x) && std::isfinite(p.orientation.y) &&
         std::isfinite(p.orientation.z) &&
         (p.orientation.w * p.orientation.w + p.orientation.x * p.orientation.x +
          p.orientation.y * p.orientation.y + p.orientation.z * p.orientation.z) > 1e-12;
}

}  // namespace

bool from_keyframe_msg(const dqo_map::KeyFrame& msg, mapping::MappingKeyframe* out, std::string* error) {
  const std::string what = "keyframe " + std::to_string(msg.id) + ": ";
  std::string why;
  if (!from_camera_info_msg(msg.camera_info, &out->camera, &why)) {
    *error = what + why;
    return false;
  }
  if (!finite_pose(msg.pose)) {
    *error = what + "pose is not finite";
    return false;
  }
  if (!from_colour_msg(msg.rgb, &out->rgb, &why) || !from_depth_msg(msg.depth, &out->depth, &why)) {
    *error = what + why;
    return false;
  }
  out->id = msg.id;
  out->stamp = msg.header.stamp.toSec();
  out->T_wc = from_pose_msg(msg.pose);
  return true;
}

bool from_keyframe_objects_msg(const dqo_map::KeyFrameObjects& msg, mapping::KeyframeObjects* out,
                               std::string* error) {
  out->keyframe_id = msg.keyframe_id;
  out->detections = from_detection_array_msg(msg.detections);
  out->object_ids.assign(msg.object_ids.begin(), msg.object_ids.end());
  out->instance = InstanceImage();
  const sensor_msgs::Image& inst = msg.detections.instance;
  if (inst.width == 0 || inst.height == 0) return true;
  LabelImage labels;
  std::string why;
  if (!from_label_msg(inst, &labels, &why)) {
    *error = "keyframe objects " + std::to_string(msg.keyframe_id) + ": " + why;
    return false;
  }
  out->instance = to_instance_image(labels);
  return true;
}

std::optional<std::map<mapping::KeyframeId, SE3>> from_keyframe_poses_msg(const dqo_map::KeyFramePoses& msg,
                                                                         std::string* error) {
  if (msg.ids.size() != msg.poses.size()) {
    *error = "keyframe_poses: " + std::to_string(msg.ids.size()) + " ids but " + std::to_string(msg.poses.size()) +
             " poses";
    return std::nullopt;
  }
  std::map<mapping::KeyframeId, SE3> out;
  for (size_t i = 0; i < msg.ids.size(); ++i) {
    if (finite_pose(msg.poses[i])) out[msg.ids[i]] = from_pose_msg(msg.poses[i]);
  }
  return out;
}

std::optional<mapping::ObjectRecord> from_object_msg(const dqo_map::Object& msg) {
  mapping::ObjectRecord r;
  r.id = msg.id;
  r.class_id = msg.class_id;
  r.class_name = msg.class_name;
  r.observations = static_cast<int>(msg.observations);
  r.confidence = msg.confidence;
  Eigen::Matrix4d Q;
  for (int i = 0; i < 16; ++i) Q(i / 4, i % 4) = msg.dual_quadric[i];
  std::optional<DualQuadric> q = Q.allFinite() ? DualQuadric::from_matrix(Q) : std::nullopt;
  if (!q) {
    const Eigen::Vector3d axes = to_vector(msg.semi_axes);
    if (!finite_pose(msg.pose) || !axes.allFinite() || (axes.array() <= 0.0).any()) return std::nullopt;
    const SE3 T = from_pose_msg(msg.pose);
    q = DualQuadric::from_params(T.translation(), T.rotation(), axes);
  }
  r.quadric = *q;
  const Eigen::Vector3d half = to_vector(msg.box_half_extents);
  if (finite_pose(msg.box_pose) && half.allFinite() && (half.array() > 0.0).all()) {
    const SE3 B = from_pose_msg(msg.box_pose);
    r.box = OrientedBox{B.translation(), B.rotation(), half};
  } else {
    r.box = OrientedBox{r.quadric.centre(), r.quadric.rotation(), r.quadric.semi_axes()};
  }
  return r;
}

std::optional<mapping::MappingEvent> from_event_msg(const dqo_map::ObjectEvent& msg) {
  mapping::MappingEvent e;
  switch (msg.type) {
    case dqo_map::ObjectEvent::CREATED: e.type = mapping::MappingEvent::Type::kCreated; break;
    case dqo_map::ObjectEvent::MERGED: e.type = mapping::MappingEvent::Type::kMerged; break;
    case dqo_map::ObjectEvent::REMOVED: e.type = mapping::MappingEvent::Type::kRemoved; break;
    default: return std::nullopt;
  }
  e.id = msg.id;
  e.into_id = msg.into_id;
  return e;
}

dqo_map::Object to_object_msg(const mapping::ObjectSummary& summary) {
  const mapping::ObjectRecord& r = summary.object;
  dqo_map::Object msg;
  msg.id = r.id;
  msg.num_gaussians = static_cast<uint32_t>(summary.num_gaussians);
  if (!summary.known) return msg;
  msg.class_id = r.class_id;
  msg.class_name = r.class_name;
  set_object_geometry(r.quadric, r.box, &msg);
  msg.observations = static_cast<uint32_t>(std::max(0, r.observations));
  msg.confidence = static_cast<float>(r.confidence);
  return msg;
}

sensor_msgs::PointCloud2 to_gaussian_cloud(const gs::GaussianMap& map, const std_msgs::Header& header,
                                           size_t stride) {
  static const char* const kFloatFields[] = {"x",     "y",     "z",     "scale_0", "scale_1", "scale_2",
                                             "rot_w", "rot_x", "rot_y", "rot_z",   "opacity", "r",
                                             "g",     "b"};
  constexpr size_t kFloats = sizeof(kFloatFields) / sizeof(kFloatFields[0]);
  sensor_msgs::PointCloud2 msg;
  msg.header = header;
  uint32_t offset = 0;
  auto add_field = [&](const char* name, uint8_t type) {
    sensor_msgs::PointField f;
    f.name = name;
    f.offset = offset;
    f.datatype = type;
    f.count = 1;
    msg.fields.push_back(f);
    offset += 4;
  };
  for (const char* name : kFloatFields) add_field(name, sensor_msgs::PointField::FLOAT32);
  add_field("object_id", sensor_msgs::PointField::UINT32);
  add_field("rgb", sensor_msgs::PointField::FLOAT32);
  stride = std::max<size_t>(1, stride);
  const size_t n = (map.size() + stride - 1) / stride;
  msg.height = 1;
  msg.width = static_cast<uint32_t>(n);
  msg.is_bigendian = false;
  msg.point_step = offset;
  msg.row_step = msg.point_step * msg.width;
  msg.is_dense = true;
  msg.data.resize(static_cast<size_t>(msg.row_step));
  const auto& P = map.positions();
  const auto& S = map.log_scales();
  const auto& R = map.rotations();
  const auto& O = map.opacities();
  const auto& C = map.colours();
  const auto& ids = map.object_ids_per_gaussian();
  for (size_t k = 0; k < n; ++k) {
    const size_t i = k * stride;
    float v[kFloats];
    for (int a = 0; a < 3; ++a) v[a] = P[3 * i + a];
    for (int a = 0; a < 3; ++a) v[3 + a] = std::exp(S[3 * i + a]);
    const float qn = std::sqrt(R[4 * i] * R[4 * i] + R[4 * i + 1] * R[4 * i + 1] + R[4 * i + 2] * R[4 * i + 2] +
                               R[4 * i + 3] * R[4 * i + 3]);
    for (int a = 0; a < 4; ++a) v[6 + a] = qn > 0.f ? R[4 * i + a] / qn : (a == 0 ? 1.f : 0.f);
    v[10] = O[i];
    uint32_t packed = 0;
    for (int a = 0; a < 3; ++a) {
      v[11 + a] = std::clamp(C[3 * i + a], 0.f, 1.f);
      packed = (packed << 8) | static_cast<uint32_t>(std::lround(v[11 + a] * 255.f));
    }
    uint8_t* out = &msg.data[k * msg.point_step];
    std::memcpy(out, v, sizeof(v));
    const uint32_t id = ids[i];
    std::memcpy(out + 4 * kFloats, &id, 4);
    std::memcpy(out + 4 * kFloats + 4, &packed, 4);  // rviz reads the bytes of a float as 0x00RRGGBB
  }
  return msg;
}

}  // namespace dqo::ros_bridge
