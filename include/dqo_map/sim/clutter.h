#pragma once
// Where a real detector keeps firing on things that are not objects: fixed spots on the room's and
// the furniture's surfaces, seen from the scene's own trajectory (so they come into view), for the
// recurring false positives of the simulated detector (detections.h).

#include <cstdint>
#include <vector>

#include "dqo_map/sim/detections.h"
#include "dqo_map/sim/scene.h"

namespace dqo::sim {

// `count` spots, a pure function of (scene geometry, trajectory, classes, seed) and independent of
// the image size (rays are drawn through fractions of the image, so `--scale` keeps them): each
// where the ray through a random point of a random trajectory frame first meets the background
// (room or furniture) between 0.3 and 4 m away, at least 0.1 m from every object's bounding sphere
// and 0.3 m from the other spots; 0.08 to 0.28 m wide, half to one and a half times as tall, of a
// random class of the scene. Fewer when the scene has no such places (an empty result where it has
// no background, trajectory or classes).
std::vector<ClutterSpot> place_clutter_spots(const Scene& scene, int count, uint64_t seed);

}  // namespace dqo::sim
