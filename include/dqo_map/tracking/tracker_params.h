#pragma once
// Parameters of the RGB-D tracker, one struct per stage, loaded once (from the node's YAML or the
// CLI's --config). Defaults are the shipped configuration (config/tracking.yaml mirrors them).
#include <array>

namespace dqo::tracking {

struct OrbParams {
  int num_features = 1000;     // per frame, spread over a grid and the pyramid
  float scale_factor = 1.2f;
  int num_levels = 8;
  int fast_threshold = 20;     // ORB-SLAM2's iniThFAST
  int min_fast_threshold = 7;  // retried per grid cell where the first finds nothing
  int grid_cell_px = 30;
  double min_depth = 0.1;      // metres: keypoints without depth in [min, max] get no 3D point
  double max_depth = 6.0;
};

struct DenseParams {
  int pyramid_levels = 4;            // level 0 = the input size; each level halves it (at most 4)
  int finest_level = 1;              // skip the full resolution for speed (0 = use it)
  std::array<int, 4> iterations = {4, 6, 8, 10};  // Gauss-Newton iterations per level, finest first
  double max_depth = 6.0;
  double max_point_distance = 0.1;   // metres, finest level (doubling per level above): farther
                                     // correspondences are outliers
  double max_normal_angle_deg = 30.0;
  double colour_weight = 0.1;        // weight of the photometric term against point-to-plane
  double huber_delta = 0.02;         // metres (geometric residual)
  // Noise model whitening the point-to-plane residual: σ(z)² = min_depth_sigma_m² + (k z²)², so
  // that far, noisy points count less (k as PoseOptimiserParams::depth_sigma_per_m2).
  double depth_sigma_per_m2 = 0.0015;
  double min_depth_sigma_m = 0.002;  // floor: discretisation and normal errors
  double intensity_sigma = 0.02;     // photometric residual's σ, intensity in [0, 1]
  double huber_delta_intensity = 0.1;
  double min_gradient = 0.01;        // intensity/pixel; flatter pixels skip the photometric term
  int min_inliers = 500;             // at the finest level used; fewer: failure
  double min_inlier_ratio = 0.25;    // inliers / valid current points there; lower: failure
  double max_update_m = 0.3;         // a solution farther than this from the guess has diverged
  double max_update_deg = 30.0;
  double max_whitened_rms = 1.5;     // larger (in σ): a wrong local minimum, failure
  double convergence_px = 0.05;      // a level stops when a step moves the image less (its pixels)
};

struct PoseOptimiserParams {
  double huber_reprojection_px = 2.45;  // sqrt(5.991), ORB-SLAM2's chi-square 95 % for 2 DoF
  double huber_depth_m = 0.05;
  double depth_sigma_per_m2 = 0.0015;   // σ_z = k z² (the Azure Kinect's and the sim's noise)
  int rounds = 4;                       // outlier rejection rounds, ORB-SLAM2 style
  double dense_prior_weight = 1.0;      // scale of the dense alignment's information matrix
  // Floor of the depth residual's σ: a map point's own position error (its depth noise when it
  // was created, a keypoint landing beside a depth edge) is not smaller than this.
  double depth_sigma_min_m = 0.002;
  int iterations = 10;                  // Ceres iterations per round
  // The dense prior's chi-square at the feature solution above which dense and features disagree
  // (6 DoF): the features are then trusted alone when they hold by themselves.
  double max_prior_chi2 = 100.0;
  // Depth captured more than this apart from the colour image (RgbdInput::depth_timestamp; a
  // Kinect v1 on TUM fr1: 15 ms by the stamps): the dense alignment then measures the motion
  // between depth captures, the features that between colour captures. Fused as a prior (and as
  // the odometry between keyframes) it pulls the trajectory towards the depth's instants, late
  // by the gap times the speed (1 cm at 0.3 m/s on fr1/xyz). So the features give the pose alone
  // where they hold by themselves; the dense pose still seeds their search, stands in where they
  // fail and is compared with them (TrackQuality).
  double max_depth_gap_s = 0.005;
  // On such frames a keypoint's depth also counts as this coarse (σ_z = k z², in quadrature with
  // the sensor's): the two images disagree by the motion between them, and by more than the stamps
  // say (TUM fr1: 15 ms apart by the stamps; a trajectory pulled by the depth lags the ground truth
  // by ~25 ms, one weighted as here by ~3 ms). The depth still gives the scale, the colour image
  // the instant. 0.025 is ORB-SLAM2's model of TUM's Kinect v1 (a virtual stereo of bf = 40 px m:
  // σ_z = z² / bf per pixel of disparity).
  double asynchronous_depth_sigma_per_m2 = 0.025;
};

struct SearchParams {               // data association by projection (ORB-SLAM2's radii)
  double frame_radius_px = 7.0;     // last frame's points, from the motion model's guess
  double dense_radius_px = 5.0;     // local map points, from the dense alignment's pose
  double local_map_radius_px = 5.0; // local map points, from a pose refined on features
  float local_map_ratio = 0.8f;     // best / second best Hamming distance at the same level
  int local_map_keyframes = 20;     // keyframes whose points make the local map
  int min_matches = 20;             // fewer after the frame-to-frame search: widen, then PnP
};

struct KeyframeParams {             // the tracker's own map (ORB-SLAM2's policy)
  int min_frames = 0;
  int max_frames = 30;
  double min_tracked_ratio = 0.9;   // new keyframe when tracked / reference-tracked falls below
  int min_close_points = 100;
  // Where features are too few to count (dense alignment alone holds the pose), a keyframe
  // whenever the camera has moved this far from the last one, so the map keeps up.
  double weak_translation_m = 0.1;
  double weak_rotation_deg = 10.0;
  int max_new_points = 500;         // map points created per keyframe (nearest first)
  // With features holding: a keyframe (if the tracked ratio asks for one) once the camera is this
  // far from the last keyframe, even while bundle adjustment is busy, so that at wide baselines
  // the map keeps up with the view (ORB-SLAM2 waits for an idle mapper, i.e. frames, not metres).
  double far_translation_m = 0.15;
  double far_rotation_deg = 15.0;
};

struct LocalBaParams {
  bool enabled = true;
  int covisible_keyframes = 10;
  int iterations = 10;
  int fixed_keyframes = 10;         // keyframes outside the window that see its points, held fixed
  // Run the adjustment inside track() instead of on the worker (deterministic, for tests).
  bool synchronous = false;
  // With `deterministic` (below): a result enters the map at the start of the frame this many
  // frames after the keyframe that asked for it, the tracker waiting for it there if it is late.
  // Larger hides more of the adjustment behind tracking; smaller applies corrections sooner.
  int apply_after_frames = 3;
  // The offline tools (dqo_track, dqo_map_offline, bench_tracking) set it whatever their config
  // says, so that their output is bit-identical on any machine load: a result
  // enters the map at the fixed point above, and "mapping is busy" (the keyframe policy) means "a
  // result is outstanding", not "the thread is still running". The live node leaves it false:
  // results enter whenever they land, the tracker never waits.
  bool deterministic = false;
};

// Loop closing over the tracker's keyframes (loop_closing.h): each new keyframe is matched by
// descriptor against older keyframes it shares no map point with; the best are verified by PnP
// RANSAC with depth; a verified loop corrects every keyframe by a pose graph (SE(3)) and then a
// global bundle adjustment. Runs on the tracker's thread at the start of the frame after the
// keyframe (deterministic). optimise_map() (the end of an offline run) adjusts the whole map once more.
struct LoopParams {
  bool enabled = true;
  int min_keyframe_gap = 10;      // a candidate is at least this many keyframes older than the query
  int min_matches = 60;           // descriptor matches (ratio test, orientation) to be verified
  // Ranking in two steps, so that its cost grows slowly with the map: every candidate against
  // this many of the query's descriptors (evenly spread; 0: all of them), then the best
  // shortlist (4 x max_verify) against all of them.
  int sample_descriptors = 200;
  int max_verify = 3;             // candidates, the best matched first, given to PnP RANSAC
  int min_inliers = 80;           // PnP inliers (after refinement with depth) for a loop
  int pose_graph_iterations = 20;
  int min_edge_shared = 30;       // covisibility edges of the pose graph: at least this many shared points
  bool global_ba = true;          // a global bundle adjustment after each loop correction
  int global_ba_iterations = 10;
  bool final_global_ba = true;    // optimise_map() runs a global BA (offline: dqo_track's output)
};

// The final refinement of every registered frame (Tracker::optimise_map, after the global BA;
// trajectory_refiner.h): each frame re-registered against the final map by its own feature
// matches, then a batch smoother ties consecutive frames (at most max_gap_s apart) to a bounded
// acceleration. σ of a frame's measured pose: sigma_m, sigma_deg (× degraded_sigma_scale for a
// frame reported degraded).
struct RefineParams {
  bool enabled = true;
  bool reregister = true;            // pose-only against the final map; false: follow the keyframe
  // Ok frames join the global bundle adjustment (their matches refine the points too) in place of
  // the pose-only re-registration.
  bool full_ba = true;
  double sigma_m = 0.005;
  double sigma_deg = 0.5;
  double degraded_sigma_scale = 10.0;
  double acceleration_sigma = 1.0;               // m/s²
  double angular_acceleration_sigma_deg = 100.0; // °/s²
  double max_gap_s = 0.2;
  int iterations = 20;
};

struct RelocParams {
  int candidate_keyframes = 20;   // matched by descriptor against this many recent/covisible
  int min_inliers = 30;
  int max_pnp = 5;                // candidates (the best matched first) given to PnP RANSAC
};

// When a tracked frame is ok, degraded or lost (TrackQuality). Features hold when they have
// ok_inliers inliers spread over min_spread of the image; dense alignment holds when it converged
// with a whitened RMS of at most dense_max_rms over at least dense_min_inlier_ratio of the points.
// ok: the features hold and dense alignment does not contradict them (or dense alone holds when
// features are off). degraded: dense holds without the features' support, or the features have
// at least min_inliers_ok inliers, or the two disagree and the features hold. lost: otherwise
// (also when they disagree and the features do not hold).
struct QualityParams {
  int ok_inliers = 50;
  // Of them with depth, for ok: without depth the features give a monocular pose, whose
  // translation the RGB-D map does not check (depth dropped: degraded, not ok).
  int ok_depth_inliers = 25;
  double min_spread = 0.25;          // of the 4x4 cells of the image
  double dense_max_rms = 1.5;        // Kinect v1 (TUM fr1) frames fit at 0.9-1.5
  double dense_min_inlier_ratio = 0.4;
  double max_disagreement_m = 0.03;  // between the dense and the feature pose of one frame
  double max_disagreement_deg = 2.0;
  // Where the features give the pose alone (depth captured apart from the colour) and dense
  // alignment from the motion model failed: align again from the features' pose (to the last
  // frame) and call the frame ok only if that converges with a whitened RMS of at most
  // confirm_max_rms and lands within confirm_max_disagreement_m / _deg of the features. On
  // fr1/desk the features alone were 5-7 cm off, with 200+ inliers, on motion-blurred frames
  // (the check there: RMS 1.9-2.3, or 4 cm or 2 degrees apart). The limits are calibrated on
  // the shared fr1 sequences: right poses fit at 1.4-2.0 (wide baselines up to 2.3) and agree
  // within 1.5 cm and 1 degree mostly. false: the features holding suffice, as before.
  bool confirm_features = true;
  // ... and for this many frames after the last frame tracked ok, while the frame before was not
  // ok, the check is against that last ok frame instead of the last one, even where dense from
  // the motion model held: a step from an unconfirmed pose confirms nothing. Longer gaps fail
  // on fast motion whatever the pose (fr1/desk: whitened RMS 2-2.8 beyond three frames).
  int confirm_window_frames = 3;
  double confirm_max_rms = 2.0;
  double confirm_max_disagreement_m = 0.025;
  double confirm_max_disagreement_deg = 1.5;
};

// Objects as landmarks (issue 25, item 1; object_landmarks.h): local BA gains a robust cost between
// a keyframe's pose and the confirmed objects its registered frames saw, the detection box against
// the box of the object's projected conic (QuadricSLAM), weighted by the object's confidence.
struct ObjectLandmarkParams {
  // Off by default: on the shared sequences it did not lower the ATE (BENCHMARKS.md, "fused +
  // objects"); the object stage's boxes are coarser than the features' pixels.
  bool enabled = false;
  double box_sigma_px = 10.0;   // σ of a box edge: detector jitter plus the ellipsoid's misfit
  double huber = 2.0;           // Huber threshold of a box residual, in σ
  double min_confidence = 0.5;  // objects believed less are not used
  int min_observations = 3;     // ... nor those behind fewer detections
  double border_px = 10.0;      // a detection edge this close to the border is not a measurement
  // A sighting whose object's box (at the keyframe's pose before adjustment) overlaps its detection
  // less than this is a wrong association or a stale object, and is not used.
  double min_iou = 0.3;
};

// A rolling-shutter colour camera (tracking/rolling_shutter.h): its rows are exposed one after
// the other over readout_s (top to bottom), the stamp taken as the middle row's instant. Each
// frame's keypoints are moved to where a global shutter at the stamp would have seen them, the
// camera's motion taken from the motion model (the last step's constant velocity). 0: a global
// shutter (the simulator; the default). TUM fr1's Kinect v1: 0.02 s (a sweep of 0.01-0.04 s on
// fr1/xyz and fr1/desk, best at 0.02-0.025; BENCHMARKS.md, issue 25, session 16), which
// config/cameras/tum_fr1.yaml gives as the camera's rolling_shutter_s.
struct RollingShutterParams {
  double readout_s = 0.0;
  // The velocity of a step longer than this (sparse frames, a gap) says too little about the
  // motion during one frame's readout: such frames are left as they are. Compensated, fr1/desk at
  // every 10th frame (0.33 s steps) had a pose 5.4 cm off, at every 3rd (0.1 s) ATE 2.00 -> 2.37
  // cm and a pose 5.9 cm off; at every 2nd (0.064-0.069 s) it gains (1.64 -> 1.19 cm).
  double max_step_s = 0.08;
};

struct TrackerParams {
  OrbParams orb;
  DenseParams dense;
  PoseOptimiserParams pose;
  KeyframeParams keyframes;
  LocalBaParams local_ba;
  RelocParams reloc;
  LoopParams loop;
  RefineParams refine;
  SearchParams search;
  QualityParams quality;
  ObjectLandmarkParams objects;
  RollingShutterParams rolling_shutter;
  bool use_dense = true;        // fuse dense depth alignment with the features
  bool use_features = true;
  int min_inliers_ok = 15;      // below: this frame's tracking failed
  int frames_to_lost = 3;       // consecutive lost frames before relocalisation takes over
  // Where dense alignment from the motion model failed or had no reference (after a jump, a
  // relocalisation, frames without depth) but the features hold, align again from the features'
  // pose: to the last frame, or where that was lost or had no depth, to the last frame tracked
  // ok with depth before it (the anchor). A relocalised or monocular pose carries the features'
  // error (1 cm on `tabletop`), which the dense chain after it would otherwise keep. Only with
  // synchronous depth (PoseOptimiserParams::max_depth_gap_s), where the fusion is used.
  bool realign_dense = true;
};

}  // namespace dqo::tracking
