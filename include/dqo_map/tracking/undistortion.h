#pragma once
// Undistortion of a raw camera into a pinhole one, built once per camera and applied to every
// frame: colour bilinearly, depth by nearest neighbour (blending depths across an edge would invent
// surfaces that are not there). Everything downstream of it (tracking, quadric projection, the
// rasteriser) assumes a pinhole camera with D = 0.
//
// The calibration is what a ROS CameraInfo holds, in ROS-free types (the node converts). Models:
// "plumb_bob" (k1 k2 p1 p2 k3) and "rational_polynomial" (k1 k2 p1 p2 k3 k4 k5 k6, the Azure
// Kinect's), the coefficient orders of OpenCV. A monocular camera is assumed: the rectifying
// rotation R is taken as identity (what a single camera's CameraInfo holds). OpenCV stays in the
// .cpp file.

#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "dqo_map/common/image.h"
#include "dqo_map/geometry/box2d.h"
#include "dqo_map/geometry/pinhole_camera.h"

namespace dqo::tracking {

struct CameraCalibration {
  int width = 0;
  int height = 0;
  std::array<double, 9> K{};  // row-major intrinsics of the raw image
  std::array<double, 12> P{}; // row-major projection of the rectified image; all zero = use K
  std::string distortion_model;  // "plumb_bob", "rational_polynomial"; "" with D empty = none
  std::vector<double> D;

  bool operator==(const CameraCalibration& o) const {
    return width == o.width && height == o.height && K == o.K && P == o.P &&
           distortion_model == o.distortion_model && D == o.D;
  }
  bool operator!=(const CameraCalibration& o) const { return !(*this == o); }
};

class Undistorter {
 public:
  // nullopt and *error when the calibration is unusable: non-positive size or focal lengths, an
  // unknown distortion model, or a coefficient count the model does not take (plumb_bob: 5,
  // rational_polynomial: 8; fewer are padded with zeros as OpenCV does, more are refused).
  static std::optional<Undistorter> create(const CameraCalibration& calibration,
                                           std::string* error);
  ~Undistorter();
  Undistorter(Undistorter&&) noexcept;
  Undistorter& operator=(Undistorter&&) noexcept;

  // The rectified camera: the fx fy cx cy of P (of K when P is zero), the raw image size.
  const PinholeCamera& camera() const;
  // True when D is all zero: apply() then copies the images unchanged.
  bool is_identity() const;

  // Images of the raw size (checked: false and *error otherwise). Pixels that map from outside
  // the raw image become 0 (black colour, no depth). Colour may have 1, 3 or 4 channels.
  bool rectify_rgb(const ImageRgb8& raw, ImageRgb8* rectified, std::string* error) const;
  bool rectify_depth(const DepthImage& raw, DepthImage* rectified, std::string* error) const;

  // Where a raw pixel lands in the rectified image (e.g. the corners of a detection box).
  Eigen::Vector2d rectify_point(const Eigen::Vector2d& uv_raw) const;
  // Where a rectified pixel comes from in the raw image.
  Eigen::Vector2d distort_point(const Eigen::Vector2d& uv_rectified) const;

  // A raw detection box in the rectified image: the box around its boundary mapped through the
  // undistortion (sampled along each edge, since straight edges bend). Boxes that are not finite
  // pass through unchanged for the object stage's filter to reject.
  Box2d rectify_box(const Box2d& raw) const;
  // A raw label image (e.g. detection index + 1) in the rectified image, by nearest neighbour
  // (labels must never blend); false and *error when it is not one channel of the raw size.
  bool rectify_labels(const InstanceImage& raw, InstanceImage* rectified, std::string* error) const;

 private:
  struct Maps;
  Undistorter();
  std::unique_ptr<Maps> maps_;
};

}  // namespace dqo::tracking
