#pragma once
// Each frame's tracking state and its evidence as one text line, written beside a trajectory
// (dqo_track --states FILE) so that an evaluation can score the ok frames alone and see why the
// others were not ok. Format (one line per frame tracked, lost ones included; '#' starts a comment):
//   timestamp state reasons inliers depth_inliers spread dense_ok dense_rms dense_inlier_ratio
//   disagreement_m disagreement_deg relocalised
// `reasons` is reasons_to_string() of the flags, "-" for none.

#include <optional>
#include <string>

#include "dqo_map/tracking/tracker.h"

namespace dqo::tracking {

struct FrameStateLine {
  double timestamp = 0.0;
  TrackingState state = TrackingState::kNotInitialised;
  std::string reasons;  // "" for none
  TrackQuality quality;  // reasons is not read back into quality.reasons (names, not bits)
  bool relocalised = false;
};

// The header line (a comment naming the columns).
std::string frame_states_header();
// One line, without the newline; the stamp with microseconds, as TUM trajectories are written.
std::string format_frame_state(double timestamp, const TrackResult& result);
// The line read back; nullopt for a comment, a blank line or a malformed one.
std::optional<FrameStateLine> parse_frame_state(const std::string& line);
// The inverse of to_string(TrackingState).
std::optional<TrackingState> tracking_state_from_string(const std::string& name);

}  // namespace dqo::tracking
