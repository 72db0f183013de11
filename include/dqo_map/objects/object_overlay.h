#pragma once
// The association node's object_overlay (and dqo_map_offline --overlays): a keyframe's image with
// its detections and every object's projected conic drawn on it, so that a user sees at a glance
// whether association works: each detection box in the colour of the object it became with
// "class score", each object's ellipse with "#ID class" in its own colour; confirmed objects
// solid, candidates thin and dashed (the lifecycle). Labels are placed so that none covers another
// (place_labels). Drawn with OpenCV (library dqo_object_overlay); the conic maths is geometry/'s
// (conic_ellipse).
#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "dqo_map/common/image.h"
#include "dqo_map/geometry/box2d.h"
#include "dqo_map/geometry/conic.h"
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

// Colours that tell the objects of one map apart. Golden-ratio hues keep neighbouring IDs apart
// but not all: IDs 13 or 21 apart land within 0.035 of each other's hue (two blues on the demo,
// #4 and #17). Here each object keeps its overlay_colour unless an object with a lower ID already
// has a hue within kMinHueGap; it then takes the nearest hue that has none (steps of kHueStep,
// either way). Lower IDs never change colour when objects are added; an ID not in the palette
// gets its overlay_colour. The object overlay and the rviz markers build it from the same
// confirmed objects, so an object has one colour in both.
class ObjectPalette {
 public:
  ObjectPalette() = default;
  explicit ObjectPalette(std::vector<ObjectId> ids);
  Rgb colour(ObjectId id) const;
  double hue(ObjectId id) const;  // in [0, 1)

  static constexpr double kMinHueGap = 0.06;
  static constexpr double kHueStep = 0.01;

 private:
  std::vector<std::pair<ObjectId, double>> hues_;  // sorted by ID
};
// The palette of the confirmed objects among `objects` (candidates keep their overlay_colour).
ObjectPalette palette_of_confirmed(const std::vector<MapObject>& objects);

// ---- Label placement -------------------------------------------------------------------------

// A label to place next to what it names: a box (a detection, an ellipse's extent) or a point (an
// ellipse's centre), and the size of its text with padding.
struct LabelRequest {
  enum class Anchor { kBox, kPoint };
  Anchor kind = Anchor::kBox;
  Box2d anchor;           // the box; for kPoint a small box around the point (its mark)
  double width = 0.0;     // pixels
  double height = 0.0;
};

struct PlacedLabel {
  Box2d rect;             // where the label goes; empty (not valid()) when it fits nowhere
  bool adjacent = false;  // at one of its anchor's own positions (false: moved away; draw a leader)
};

// Greedy placement in the order given (put the most important labels first). Each label takes the
// first of its anchor's positions that overlaps no label placed before: a box's label above it,
// below it, inside its top edge, inside its bottom edge, right of it, left of it; a point's right
// of it, left, above, below; those inside the image as they are first, then those moved into it
// (a box at the top edge: below it). When all are taken, the free position nearest
// the first one within `max_shift` pixels (a grid search); when there is none, the label is left
// out (rect empty). Placed rectangles lie inside [0, width] x [0, height] and have disjoint
// interiors. A label larger than the image is left out.
std::vector<PlacedLabel> place_labels(const std::vector<LabelRequest>& labels, int image_width,
                                      int image_height, double max_shift = 120.0);

// ---- The overlay -----------------------------------------------------------------------------

// What draw_object_overlay draws, computed without drawing (tests check it; the drawing uses it).
struct OverlayLayout {
  struct Ellipse {
    ObjectId id = 0;
    Rgb colour = kUnmatchedColour;
    bool confirmed = true;  // false: a candidate (thin, dashed)
    Ellipse2d ellipse;
    bool centre_in_image = false;
  };
  struct Box {
    Box2d box;
    Rgb colour = kUnmatchedColour;
    bool solid = true;      // false: its object is a candidate
  };
  struct Label {
    std::string text;
    Rgb colour = kUnmatchedColour;
    PlacedLabel placed;
    Box2d anchor;           // what it names (for the leader line of a moved label)
    double baseline = 0.0;  // pixels from the rect's bottom to the text's baseline
  };
  std::vector<Ellipse> ellipses;
  std::vector<Box> boxes;
  std::vector<Label> labels;  // object labels ("#ID class") first, then detections' ("class score")
  double font_scale = 0.45;
};

// The layout of the overlay of `objects` (confirmed and candidates; those without a quadric or not
// wholly in front of the camera are skipped) and `detections` on an image of `camera`'s size.
OverlayLayout layout_object_overlay(const PinholeCamera& camera, const SE3& T_wc,
                                    const std::vector<OverlayDetection>& detections,
                                    const std::vector<MapObject>& objects);

// A copy of `rgb` (3 channels, the size of `camera`) with, in this order, the objects' ellipses
// (confirmed 2 px solid, candidates 1 px dashed), the detection boxes (2 px; 1 px for a candidate's
// detection), each ellipse's centre (a filled dot) and the labels of layout_object_overlay. An
// image of another size or channel count is returned unchanged.
ImageRgb8 draw_object_overlay(const ImageRgb8& rgb, const PinholeCamera& camera, const SE3& T_wc,
                              const std::vector<OverlayDetection>& detections,
                              const std::vector<MapObject>& objects);

}  // namespace dqo::objects
