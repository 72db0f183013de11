#pragma once
// What dqo_map_offline writes about a run besides the map: timings.json and the keyframe renders
// (the map from a keyframe: colour | object IDs). In system/'s core: the GPU machine's reduced
// runner writes them too.

#include <string>

#include "dqo_map/common/image.h"
#include "dqo_map/mapping/gaussian_mapper.h"
#include "dqo_map/system/offline_mapping.h"

namespace dqo::system {

// A JSON string literal of `text` (quotes and backslashes escaped, control characters dropped).
std::string json_quoted(const std::string& text);

// This process's peak resident memory, megabytes.
double peak_memory_mb();

// timings.json: sizes, totals, frames per second, peak memory, per stage (count, mean, median, max,
// total, every item) and per mapped keyframe what the mapping stage did.
// The mean over mapped keyframes of the last training iteration's loss (to compare backends).
double mean_final_loss(const OfflineResult& run);

std::string timings_json(const OfflineResult& run, const mapping::GaussianMapper& mapper,
                         const std::string& input, double mesh_seconds);

// A render's colour (clamped to [0, 1]) as RGB, and each pixel's object ID as a colour per ID (the
// background, and pixels less than half opaque, dark grey; nothing black). Also the mapping
// nodelet's map_render and map_render_ids.
ImageRgb8 render_colour_image(const gs::RenderOutput& render);
ImageRgb8 render_ids_image(const gs::RenderOutput& render);

// The map rendered from a keyframe: colour on the left, each pixel's object ID on the right (a
// colour per ID, the background dark grey, nothing black).
ImageRgb8 render_colour_and_ids(mapping::GaussianMapper& mapper, const mapping::KeyframePose& k);

}  // namespace dqo::system
