#pragma once
// Where the trainer's iterations run when not on the host. GaussianTrainer keeps the map and does
// the once-per-keyframe work itself (the render for the masks, adding, pruning, relabelling); an
// engine runs a batch of its iterations — forward, the losses, backward, Adam, confidence — with
// the map, the optimiser state and the window's images where it computes (the GPU: cuda/train/),
// and hands the map and the optimiser state back once at the end of the batch.
//
// An iteration is the trainer's host iteration (GaussianTrainer::iterate) with L_rgb = L1
// (λ_ssim = 0), one backward pass over all pixels (no train_per_label) and opacity fixed
// (lr_opacity = 0): the trainer asks the engine only for batches of that kind.

#include <cstdint>
#include <utility>
#include <vector>

#include "dqo_map/common/image.h"
#include "dqo_map/gaussians/adam.h"
#include "dqo_map/gaussians/gaussian_map.h"
#include "dqo_map/gaussians/losses.h"
#include "dqo_map/gaussians/math/review.h"
#include "dqo_map/gaussians/rasteriser.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"

namespace dqo::gs {

// The review's view (math/review.h) of a keyframe: its pose (world to camera), intrinsics and
// images, as floats.
inline ReviewView review_view_of(const PinholeCamera& camera, const SE3& T_cw, const DepthImage& depth,
                                 const LabelImage& labels) {
  ReviewView view;
  const Eigen::Matrix3d R = T_cw.rotation();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) view.R[r][c] = static_cast<float>(R(r, c));
    view.t[r] = static_cast<float>(T_cw.translation()[r]);
  }
  view.fx = camera.fx, view.fy = camera.fy, view.cx = camera.cx, view.cy = camera.cy;
  view.width = camera.width, view.height = camera.height;
  view.depth = depth.data.data();
  view.labels = labels.data.data();
  return view;
}

// One keyframe of the window. `key` names its images: the same key, the same images (an engine
// may keep them from batch to batch); the trainer gives a keyframe a new key when its labels change.
struct TrainingView {
  uint64_t key = 0;
  const PinholeCamera* camera = nullptr;
  SE3 T_cw;                             // world to camera (the pose may change between batches)
  const ImageRgb8* rgb = nullptr;       // 3 channels; the colour is value / 255 (to_float_rgb)
  const DepthImage* depth = nullptr;    // metres; 0 / NaN: no measurement
  const LabelImage* labels = nullptr;   // object ID per pixel
};

// Iteration k trains on views[view] with L_ins on `object` (0: no L_ins).
struct TrainingStep {
  uint32_t view = 0;
  uint32_t object = 0;
};

struct TrainingLoss {
  RenderSettings settings;  // as the trainer renders for training; ins_object is set per step
  float lambda_depth = 0.f;
  float lambda_ins = 0.f;
};

class TrainingEngine {
 public:
  virtual ~TrainingEngine() = default;
  // Runs `steps` in order on `map` (its unstable Gaussians: those a step's gradient reaches move,
  // and their confidence grows by one) with `adam`'s rates and state; returns each step's loss.
  // Throws OutOfDeviceMemory when the device is full (the map then is as before the batch).
  //
  // An engine may keep the map and the optimiser state between batches (the GPU's does: moving
  // them each batch cost more than training). It then takes from `adam` only the state of the
  // Gaussians appended since the last batch, leaves the rest of `adam` stale (see
  // fetch_optimiser_state()), and relies on being told what else the caller changed: the caller
  // may append Gaussians and change stable flags and object IDs freely, removes Gaussians only
  // through GaussianMap::remove (or remove_if) with map_removed() given the same plan, and calls
  // map_replaced() after any other change. After a failed batch the engine holds nothing, and the
  // optimiser state restarts from `adam` as last fetched.
  virtual std::vector<double> run(const std::vector<TrainingView>& views, const std::vector<TrainingStep>& steps,
                                  const TrainingLoss& loss, GaussianMap* map, GaussianAdam* adam) = 0;
  // Brings what it holds in step with `map` and `adam` (sized for the map) now rather than at the
  // next batch: a backend whose rasteriser shares the engine's copy (cuda/cuda_backend.h) then
  // renders `map` without sending it. Never throws; a failure only costs that saving.
  virtual void sync(const GaussianMap& map, const GaussianAdam& adam) {
    (void)map;
    (void)adam;
  }
  virtual void map_removed(const RemovalPlan& plan) { (void)plan; }
  // The caller relabelled Gaussians of `map` by GaussianMap::relabel_each(changes); flags_before
  // is the map's flags_revision() before. An engine that holds the map's flags may apply the same
  // changes to its copy rather than take every flag again at the next sync (a few relabels a
  // keyframe against 5 bytes a Gaussian).
  virtual void map_relabelled(const GaussianMap& map, const std::vector<std::pair<uint32_t, uint32_t>>& changes,
                              uint64_t flags_before) {
    (void)map;
    (void)changes;
    (void)flags_before;
  }
  virtual void map_replaced() {}
  // The keyframe review (GaussianTrainer::review_gaussians) where the engine holds `map` (after
  // sync()): one pass of `view` with settings, its colour gradient under the probe
  // dL/d(rgb) = (1, [label = 0], [label != 0]) summed per Gaussian, then math/review.h's step for
  // every Gaussian with `rv`'s pose and intrinsics (its image pointers are the host's and not
  // read), `rs`, and the trainer's counters [map.size()], updated in place — or in the engine's
  // own copy (holds_review_counters()). A relabelled Gaussian's votes start over. Returns false
  // where it does not review (the trainer's own loop then runs); true with `relabels` (index, new
  // ID), ascending. Throws OutOfDeviceMemory when the device is full (the counters are then as
  // before).
  virtual bool review(const GaussianMap& map, const TrainingView& view, const RenderSettings& settings,
                      const ReviewView& rv, const ReviewSettings& rs, float* usefulness, uint16_t* invisible,
                      uint8_t* votes, std::vector<std::pair<uint32_t, uint32_t>>* relabels) {
    (void)map, (void)view, (void)settings, (void)rv, (void)rs, (void)usefulness, (void)invisible, (void)votes;
    (void)relabels;
    return false;
  }
  // Deferred attributes: where asked (on = true) and able, run() leaves the trained attributes
  // (position, log-scale, rotation, colour, confidence) on the engine's device instead of writing
  // them into the map after every batch (at 1.3 M Gaussians, 72 MB a keyframe the host seldom
  // reads); the caller then reads them only after fetch_attributes(). Returns whether it defers.
  virtual bool defer_attributes(bool on) {
    (void)on;
    return false;
  }
  // Writes the attributes the engine holds newer than `map`'s into it: the Gaussians it held when
  // it trained them (the first ones; those appended since keep the host's). Nothing where none
  // are pending. An engine that has to drop its copy (a failure on the device) brings them down
  // first where it can, and writes them here.
  virtual void fetch_attributes(GaussianMap* map) { (void)map; }
  // Whether its copy shows `map` as it is now (after sync()): renders and reviews then use it.
  virtual bool holds(const GaussianMap& map) const {
    (void)map;
    return false;
  }
  // The pruning's tests where it holds `map`, on the values it holds: flags[i] bit 0 where
  // Gaussian i's largest log-scale exceeds max_log_scale (math/prune.h), bit 1 where its count of
  // keyframes it gave almost nothing reaches max_invisible (> 0; 0: not tested) — the count of
  // the review counters it keeps, or of `invisible` [map.size()] where it keeps none (it may take
  // the caller's counters then, as review() does). True; false where it cannot (the caller tests
  // its own values).
  virtual bool flag_prune(const GaussianMap& map, float max_log_scale, int max_invisible, float* usefulness,
                          uint16_t* invisible, uint8_t* votes, std::vector<uint8_t>* flags) {
    (void)map, (void)max_log_scale, (void)max_invisible, (void)usefulness, (void)invisible, (void)votes;
    (void)flags;
    return false;
  }
  // Review counters kept: with deferred attributes, review() and flag_prune() may keep the
  // counters they were given on the device from call to call (the caller's arrays are then stale;
  // the engine applies appends and removals to its own). Whether it keeps them now; and they
  // brought into the caller's arrays [map size] and handed back (the next call takes the
  // caller's again). A device failure that drops the map drops them too: the caller's last
  // fetched counters stand (they only steer pruning and relabelling).
  virtual bool holds_review_counters() const { return false; }
  virtual void fetch_review_counters(float* usefulness, uint16_t* invisible, uint8_t* votes) {
    (void)usefulness, (void)invisible, (void)votes;
  }
  // Writes the optimiser state it holds into *adam (sized for the map); nothing if it holds none.
  virtual void fetch_optimiser_state(GaussianAdam* adam) { (void)adam; }
  // Device bytes held now (the map, optimiser state, gradients, the rasteriser's buffers, cached
  // images), for diagnostics.
  virtual size_t device_bytes() const = 0;
};

}  // namespace dqo::gs
