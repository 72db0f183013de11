#pragma once
// Conversions between the object stage's value types (include/dqo_map/objects) and ROS messages:
// objects, events, detections, KeyFrameObjects, instance images and rviz markers. Field copies and
// relabelling only; the object maths lives in the core. Private to src/ros.

#include <map>
#include <string>
#include <vector>

#include <dqo_map/DetectionArray.h>
#include <dqo_map/KeyFrame.h>
#include <dqo_map/KeyFrameObjects.h>
#include <dqo_map/Object.h>
#include <dqo_map/ObjectEvent.h>
#include <sensor_msgs/Image.h>
#include <std_msgs/Header.h>
#include <visualization_msgs/MarkerArray.h>

#include "dqo_map/common/mask_detections.h"
#include "dqo_map/objects/object_types.h"
#include "dqo_map/tracking/undistortion.h"

namespace dqo::ros_bridge {

// Pose = the quadric's centre and rotation (columns = the semi-axes' directions), semi_axes in that
// order, dual_quadric = Q* normalised to Q*(3,3) = -1, row-major. num_gaussians stays 0: the
// mapping nodelet owns the Gaussians.
// class_names: class ID -> name for the top classes (ObjectMapper::class_names()).
dqo_map::Object to_object_msg(const objects::MapObject& object,
                              const std::map<int, std::string>& class_names = {}, int top_classes = 3);
// The geometry fields of an Object message (pose, semi_axes, dual_quadric, box_pose,
// box_half_extents): one place for the object stage's objects and the mapping nodelet's.
void set_object_geometry(const DualQuadric& quadric, const OrientedBox& box, dqo_map::Object* msg);
dqo_map::ObjectEvent to_event_msg(const objects::ObjectEvent& event, const std_msgs::Header& header);

// Field copies; NaN or inverted boxes pass through unchanged (the core's filter gives the verdict).
std::vector<Detection2d> from_detection_array_msg(const dqo_map::DetectionArray& msg);

// An instance / label image message as integer labels: mono8 / 8UC1 and mono16 / 16UC1 give the
// value, rgb8 / bgr8 the colour packed as pack_rgb(r, g, b). False and *error (naming the
// encoding and those accepted) otherwise, or when the size fields disagree with the data.
bool from_label_msg(const sensor_msgs::Image& msg, LabelImage* labels, std::string* error);

// The mapper's input from a KeyFrame and its DetectionArray: the rectified pinhole camera from the
// keyframe's camera_info, T_wc from its pose, the depth as metres in *depth (the returned view
// points into it), the boxes through `undistorter` (nullptr: they are rectified already), and the
// instance image (detection index + 1), rectified the same way, in *instance (empty when absent).
// A depth or instance image that cannot be used leaves the keyframe usable without it, with a line
// in *warnings; false and *error only when the camera_info is unusable.
bool to_object_keyframe(const dqo_map::KeyFrame& kf, const dqo_map::DetectionArray& detections,
                        const tracking::Undistorter* undistorter, objects::ObjectKeyFrame* out,
                        DepthImage* depth, InstanceImage* instance, std::vector<std::string>* warnings,
                        std::string* error);

// KeyFrameObjects of one processed keyframe: the filtered detections (rectified pixels) and,
// parallel to them, the object IDs. `instance` (already rectified and renumbered) is attached when
// it is not empty.
dqo_map::KeyFrameObjects to_keyframe_objects_msg(const objects::KeyFrameAssociation& association,
                                                 const std_msgs::Header& header,
                                                 const InstanceImage& instance);

// rviz markers: per object an oriented SPHERE scaled to 2x the semi-axes (namespace "ellipsoids")
// and a TEXT_VIEW_FACING label "id class" above it ("labels"), marker id = object id, one colour
// per ID; DELETE of both markers for every ID in `deleted` (merged or removed objects).
visualization_msgs::MarkerArray to_marker_array(const std::vector<objects::MapObject>& objects,
                                                const std::vector<objects::ObjectId>& deleted,
                                                const std_msgs::Header& header);
// A stable, well-spread colour per ID (golden-ratio hue steps: objects::overlay_colour), components
// in [0, 1]. The markers take the colours of objects::palette_of_confirmed of their objects.
std_msgs::ColorRGBA colour_of_id(objects::ObjectId id);

}  // namespace dqo::ros_bridge
