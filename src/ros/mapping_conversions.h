#pragma once
// Conversions between the mapping stage's value types (include/dqo_map/mapping) and ROS messages:
// keyframes, their objects, object records and events in; objects with Gaussian counts, Gaussians
// as PointCloud2 and rendered images out. Field copies and unit changes; private to src/ros.

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <dqo_map/KeyFrame.h>
#include <dqo_map/KeyFrameObjects.h>
#include <dqo_map/KeyFramePoses.h>
#include <dqo_map/Object.h>
#include <dqo_map/ObjectEvent.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/Header.h>

#include "dqo_map/gaussians/gaussian_map.h"
#include "dqo_map/mapping/gaussian_mapper.h"

namespace dqo::ros_bridge {

// A KeyFrame as the mapping stage takes it: rectified pinhole camera, T_wc, RGB and depth in
// metres. False and *error (naming the keyframe) for an unusable camera_info, pose or image.
bool from_keyframe_msg(const dqo_map::KeyFrame& msg, mapping::MappingKeyframe* out, std::string* error);

// KeyFrameObjects: detections (rectified), their instance image (value j+1 = detection j) when
// attached, and the object IDs. False and *error for an instance image of an encoding that cannot
// hold the labels; sizes are the mapper's to check.
bool from_keyframe_objects_msg(const dqo_map::KeyFrameObjects& msg, mapping::KeyframeObjects* out,
                               std::string* error);

// The corrected poses of KeyFramePoses; nullopt and *error when ids and poses differ in number.
std::optional<std::map<mapping::KeyframeId, SE3>> from_keyframe_poses_msg(const dqo_map::KeyFramePoses& msg,
                                                                         std::string* error);

// An Object message as the mapping stage's record: the quadric from dual_quadric (pose and
// semi_axes where that is not a proper ellipsoid), the box from box_pose / box_half_extents (the
// ellipsoid's where those are zero, as from an older publisher). nullopt for an object whose
// ellipsoid is degenerate.
std::optional<mapping::ObjectRecord> from_object_msg(const dqo_map::Object& msg);

// The events the mapping stage acts on (CREATED, MERGED, REMOVED); nullopt for any other type.
std::optional<mapping::MappingEvent> from_event_msg(const dqo_map::ObjectEvent& msg);

// An object of the map with its Gaussian count (objects never reported by the object stage keep
// the defaults but their ID and count).
dqo_map::Object to_object_msg(const mapping::ObjectSummary& summary);

// Gaussians as a PointCloud2 (header's frame = the map): float32 fields x y z scale_0 scale_1
// scale_2 (metres) rot_w rot_x rot_y rot_z (unit quaternion) opacity r g b (in [0, 1]), uint32
// object_id, and rgb (the colour packed as rviz's PointCloud2 display reads it). Every `stride`-th
// Gaussian (1: all), dense, little-endian.
sensor_msgs::PointCloud2 to_gaussian_cloud(const gs::GaussianMap& map, const std_msgs::Header& header,
                                           size_t stride = 1);

}  // namespace dqo::ros_bridge
