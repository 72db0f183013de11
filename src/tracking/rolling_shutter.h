#pragma once
// Rolling-shutter compensation of a frame's keypoints. A rolling-shutter colour camera (the
// Kinect v1 of TUM fr1) exposes its rows one after the other: row v is seen at
//   t(v) = t_frame + (v − height/2) / height · readout_s
// (the stamp taken as the middle row's instant). Under motion the image is then no pinhole image
// of one pose: on fr1/xyz, moving 0.3-0.5 m/s along the optical axis, the poses came out 1-2 cm
// off, coupled with a rotation about the image's x axis (BENCHMARKS.md, issue 25, session 16).
// Each keypoint is moved to where a global shutter at t_frame would have seen its point, the
// camera's motion over the row's offset taken from a constant twist (the motion model's):
//   p = T_frame,row · back_project(uv, z),   uv' = π(p),
// with z the keypoint's depth, or the frame's median keypoint depth where it has none. The
// keypoint's depth is left as measured: the depth camera does not share the colour camera's rows.
//
// Private to tracking/.

#include <Eigen/Core>

#include "dqo_map/geometry/pinhole_camera.h"
#include "orb_frame.h"

namespace dqo::tracking {

// The instant (seconds after the frame's stamp) at which row `v` of a rolling-shutter image was
// exposed.
double rolling_shutter_row_offset(double v, int height, double readout_s);

// Moves every keypoint of `frame` (level-0 pixels of a rectified, pinhole image) to its
// global-shutter position at the frame's stamp, for a camera moving with `twist_per_s` = [v; ω]
// (SE3::log() convention: translation part first, in the camera's own frame, per second), and
// rebuilds the frame's keypoint grid. readout_s <= 0: nothing changes.
void compensate_rolling_shutter(const PinholeCamera& camera,
                                const Eigen::Matrix<double, 6, 1>& twist_per_s, double readout_s,
                                OrbFrame* frame);

}  // namespace dqo::tracking
