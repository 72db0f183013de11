#include "dqo_map/tracking/frame_states.h"

#include <cstdio>
#include <sstream>

namespace dqo::tracking {

std::string frame_states_header() {
  return "# timestamp state reasons inliers depth_inliers spread dense_ok dense_rms "
         "dense_inlier_ratio disagreement_m disagreement_deg relocalised";
}

std::string format_frame_state(double timestamp, const TrackResult& r) {
  const TrackQuality& q = r.quality;
  const std::string reasons = reasons_to_string(q.reasons);
  char buffer[512];
  std::snprintf(buffer, sizeof(buffer), "%.6f %s %s %d %d %.4f %d %.4f %.4f %.5f %.4f %d", timestamp,
                to_string(r.state), reasons.empty() ? "-" : reasons.c_str(), q.inliers,
                q.depth_inliers, q.spread, q.dense_ok ? 1 : 0, q.dense_rms, q.dense_inlier_ratio,
                q.disagreement_m, q.disagreement_deg, r.relocalised ? 1 : 0);
  return buffer;
}

std::optional<TrackingState> tracking_state_from_string(const std::string& name) {
  for (const TrackingState s : {TrackingState::kNotInitialised, TrackingState::kOk,
                                TrackingState::kDegraded, TrackingState::kLost}) {
    if (name == to_string(s)) return s;
  }
  return std::nullopt;
}

std::optional<FrameStateLine> parse_frame_state(const std::string& line) {
  const size_t first = line.find_first_not_of(" \t");
  if (first == std::string::npos || line[first] == '#') return std::nullopt;
  std::istringstream in(line);
  FrameStateLine out;
  std::string state;
  int dense_ok = 0, relocalised = 0;
  TrackQuality& q = out.quality;
  if (!(in >> out.timestamp >> state >> out.reasons >> q.inliers >> q.depth_inliers >> q.spread >>
        dense_ok >> q.dense_rms >> q.dense_inlier_ratio >> q.disagreement_m >>
        q.disagreement_deg >> relocalised))
    return std::nullopt;
  std::string rest;
  if (in >> rest) return std::nullopt;
  const auto s = tracking_state_from_string(state);
  if (!s) return std::nullopt;
  out.state = *s;
  if (out.reasons == "-") out.reasons.clear();
  q.dense_ok = dense_ok != 0;
  out.relocalised = relocalised != 0;
  return out;
}

}  // namespace dqo::tracking
