#pragma once
// Private to io/: the intrinsics files of the dataset formats.
//   camera.yaml (own format and TUM): width, height, fx, fy, cx, cy, depth_scale (a flat map).
//   cam_params.json (Replica / NICE-SLAM): {"camera": {"w", "h", "fx", "fy", "cx", "cy", "scale"}}
// read through yaml-cpp (JSON is YAML). Numbers are parsed from their text exactly.

#include <string>

#include "dqo_map/geometry/pinhole_camera.h"

namespace dqo {
namespace io_detail {

// Unknown keys are errors (naming file and line): a misspelt key must not fall back silently to a
// default. When depth_scale_required is false and the key is absent, *depth_scale is left as is.
bool read_camera_yaml(const std::string& path, bool depth_scale_required, PinholeCamera* camera,
                      double* depth_scale, std::string* error);

std::string camera_yaml_text(const PinholeCamera& camera, double depth_scale);

// Unknown keys under "camera" are ignored there (other tools add their own, e.g. "crop_edge");
// "scale" is optional and *depth_scale is left as is without it.
bool read_replica_cam_params(const std::string& path, PinholeCamera* camera, double* depth_scale,
                             std::string* error);

// Positive, finite focal lengths and sizes; finite principal point.
bool check_camera(const std::string& path, const PinholeCamera& camera, double depth_scale,
                  std::string* error);

}  // namespace io_detail
}  // namespace dqo
