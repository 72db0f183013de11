#pragma once
// The association node's object_overlay: a keyframe's image with its detections and every object's
// projected conic drawn on it, so that a user sees at a glance whether association works (each
// detection box in the colour of the object it became, its class and score; each object's ellipse
// and ID in its own colour). Drawn with OpenCV (library dqo_object_overlay); the maths is
// geometry/'s (conic_ellipse).
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "dqo_map/common/image.h"
#include "dqo_map/geometry/box2d.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"
#include "dqo_map/objects/object_types.h"

namespace dqo::objects {

struct OverlayDetection {
  Box2d box;               // rectified pixels
  std::string class_name;
  float score = 0.0f;
  ObjectId object_id = 0;  // the object it became; 0 = none
};

using Rgb = std::array<uint8_t, 3>;
// The colour of an object (golden-ratio hue steps: neighbouring IDs differ), and of a detection
// that became no object.
Rgb overlay_colour(ObjectId id);
constexpr Rgb kUnmatchedColour = {255, 255, 255};

// A copy of `rgb` (3 channels, the size of `camera`) with, in this order, the objects' ellipses
// (those wholly in front of the camera), the detection boxes (2 px wide, their label above them)
// and each ellipse's centre (a filled dot of 3 px radius) and ID. An image of another size or
// channel count is returned unchanged.
ImageRgb8 draw_object_overlay(const ImageRgb8& rgb, const PinholeCamera& camera, const SE3& T_wc,
                              const std::vector<OverlayDetection>& detections,
                              const std::vector<MapObject>& objects);

}  // namespace dqo::objects
