#pragma once
// Private to io/: the intrinsics files of the dataset formats.
//   camera.yaml (own format and TUM): width, height, fx, fy, cx, cy, depth_scale (a flat map), and
//   optionally the lens distortion of the stored images: distortion_model (plumb_bob or
//   rational_polynomial) with distortion: [k1, k2, p1, p2, k3(, k4, k5, k6)], and the colour
//   sensor's rolling_shutter_s (the readout of its rows, top to bottom; absent or 0: global shutter).
//   cam_params.json (Replica / NICE-SLAM): {"camera": {"w", "h", "fx", "fy", "cx", "cy", "scale"}}
// read through yaml-cpp (JSON is YAML). Numbers are parsed from their text exactly.

#include <string>
#include <vector>

#include "dqo_map/geometry/pinhole_camera.h"

namespace dqo {
namespace io_detail {

// Unknown keys are errors (naming file and line): a misspelt key must not fall back silently to a
// default. When depth_scale_required is false and the key is absent, *depth_scale is left as is.
struct CameraDistortion {
  std::string model;           // "" when the file gives none
  std::vector<double> coefficients;
  double rolling_shutter_s = 0.0;  // read with the lens: what else departs from a pinhole snapshot
};

// `distortion` may be null: the keys are then refused (a format whose images are pinhole).
// rolling_shutter_s must lie in [0, 1] seconds.
// A model without coefficients, coefficients without a model, an unknown model or a coefficient
// count it does not take (plumb_bob 5, rational_polynomial 8; fewer are padded with zeros, as
// OpenCV does) are errors naming the file and line.
bool read_camera_yaml(const std::string& path, bool depth_scale_required, PinholeCamera* camera,
                      double* depth_scale, CameraDistortion* distortion, std::string* error);

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
