#pragma once
// The value types of an RGB-D dataset with ground truth, shared by sim/ (which renders them), io/
// (which writes and reads them: own format, TUM, Replica) and everything that consumes frames.
// The on-disk layout of the own format is in the design notes (Data on disk).

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "dqo_map/common/image.h"
#include "dqo_map/common/triangle_mesh.h"
#include "dqo_map/geometry/box2d.h"
#include "dqo_map/geometry/oriented_box.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"

namespace dqo {

// A 2D detection (from a detector, or simulated from ground truth).
struct Detection2d {
  int class_id = 0;
  std::string class_name;
  float score = 1.0f;
  Box2d box;
  uint32_t gt_id = 0;  // ground-truth object ID when known (simulated detections), 0 otherwise
};

// Ground truth of one object as seen in one frame.
struct FrameObject {
  uint32_t id = 0;
  Box2d box;                     // box of the visible instance pixels
  double visible_fraction = 0.0; // visible pixels / pixels the object would cover unoccluded
};

struct Frame {
  int index = 0;
  double timestamp = 0.0;  // seconds
  // The depth image's own stamp where the dataset has one (TUM lists colour and depth apart; a
  // Kinect v1 captures them at different instants): the tracker needs to know.
  std::optional<double> depth_timestamp;
  SE3 T_wc;                // camera (optical frame) to world; ground truth when the dataset has it
  bool has_pose = false;
  ImageRgb8 rgb;           // 3 channels, RGB
  DepthImage depth;        // metres
  InstanceImage instance;  // ground-truth object IDs; empty when the dataset has none
  std::vector<FrameObject> objects;      // ground truth per visible object (synthetic data)
  std::vector<Detection2d> detections;   // empty when the dataset has none
};

// Ground truth of one object of the scene.
struct GtObject {
  uint32_t id = 0;
  int class_id = 0;
  std::string class_name;
  OrientedBox box;   // world frame; for meshes the tight box in the object's own frame
  TriangleMesh mesh; // world coordinates; may be empty when not loaded
};

struct DatasetInfo {
  PinholeCamera camera;
  // Lens distortion of the stored images (camera.yaml's distortion_model and distortion, OpenCV's
  // coefficient order: plumb_bob k1 k2 p1 p2 k3, rational_polynomial k1 k2 p1 p2 k3 k4 k5 k6).
  // Empty: the images are pinhole already. Consumers that assume a pinhole camera rectify first
  // (tracking/rectified_frame_source.h), as tracking_node does with a CameraInfo's D.
  std::string distortion_model;
  std::vector<double> distortion;
  // The colour sensor's rolling-shutter readout (camera.yaml's rolling_shutter_s; 0: a global
  // shutter): the tracker compensates it (TrackerParams::rolling_shutter).
  double rolling_shutter_s = 0.0;
  double depth_scale = 1000.0;            // stored uint16 value per metre
  std::map<int, std::string> class_names; // class ID -> name
  std::vector<GtObject> objects;          // empty when the dataset has no object ground truth
};

}  // namespace dqo
