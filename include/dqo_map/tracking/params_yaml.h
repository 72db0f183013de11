#pragma once
// The tracking configuration as YAML: TrackerParams and the mapping keyframe policy
// (KeyframeSelectorParams), read by dqo_track --config and by tracking_node (from its private ROS
// parameters, which launch/tracking.launch loads from the same file). config/tracking.yaml holds
// the defaults.
//
//   tracker:            # TrackerParams: use_features, use_dense, min_inliers_ok, frames_to_lost
//     orb: {...}        #   and one map per stage: orb, dense, pose, keyframes, local_ba, reloc
//   mapping_keyframes:  # KeyframeSelectorParams: max_rotation_deg, max_translation_m, max_frames
//   stream:             # StreamParams (TrackingSession): out_of_order_s
//
// Strict: an unknown key, a key given twice, a value of the wrong type or out of range is an error
// "SOURCE:LINE:COLUMN: message" naming the key's full path (tracker.orb.num_features), and nothing
// is loaded. Absent keys keep their defaults, so a file may hold only what it changes.
// yaml-cpp stays in the .cpp file.

#include <optional>
#include <string>

#include "dqo_map/common/keyframe_selector.h"
#include "dqo_map/tracking/tracker_params.h"

namespace dqo::tracking {

// How TrackingSession treats a live stream's stamps.
struct StreamParams {
  // A frame stamped before the last one by at most this (seconds) came out of order (a driver or a
  // network that reorders): it is skipped. Further back is a new run (a looping bag): a reset.
  double out_of_order_s = 1.0;
};

struct TrackingConfig {
  TrackerParams tracker;
  KeyframeSelectorParams mapping_keyframes;
  StreamParams stream;
};

// Reads a file; nullopt and *error ("FILE:LINE:COLUMN: ...") on any problem.
std::optional<TrackingConfig> load_tracking_config(const std::string& path, std::string* error);

// Parses YAML text over `base` (keys absent from the text keep base's values). `source` names the
// text in messages; with positions = false they carry no line and column (text generated from
// ROS parameters, whose lines mean nothing to the user).
std::optional<TrackingConfig> parse_tracking_config(const std::string& text,
                                                    const std::string& source, std::string* error,
                                                    const TrackingConfig& base = {},
                                                    bool positions = true);

// Every parameter, as a file load_tracking_config reads back to the same values.
std::string tracking_config_to_yaml(const TrackingConfig& config);

}  // namespace dqo::tracking
