#pragma once
// The incremental mapping step of METHOD.md §4 (RTG-SLAM's scheme with DQO-MAP's object IDs), for
// one RGB-D keyframe with its pose and pixel labels at a time:
//   1. render the map from the keyframe; masks: missing (transmittance > 0.5), depth error
//      (|d − d̂| > θ_d), colour error (|c − ĉ| > θ_c), instance (ins_k < θ_α on the pixels of
//      object k); from the same render, each Gaussian's contribution (for pruning) and whether
//      it sits on pixels of another label (for relabelling);
//   2. add Gaussians: on the missing region at a stride (a first keyframe is covered densely), on
//      a random sample of the error pixels; each at the pixel's back-projected depth, flat along
//      the surface normal estimated from depth neighbours, sized by the pixel footprint, with the
//      pixel's colour and object ID;
//   3. optimise the unstable Gaussians over the window of recent keyframes (one keyframe picked at
//      random per iteration, the newest more often, one of its objects for L_ins), with Adam; a
//      Gaussian's confidence grows by one per step that moved it, and it is stable (frozen) past
//      a threshold (off by default: see Params);
//   4. prune: unstable ones older than N keyframes (off with stabilisation), oversized ones, and
//      ones that stayed in view yet contributed (almost) nothing for several keyframes.
// The keyframe store holds the window only. Parallelism comes from the rasteriser (and the training
// engine, where one is given: cuda/train/) and the review's per-Gaussian loop. Not
// thread-safe: one caller at a time (the mapping node's worker).

#include <atomic>
#include <cstdint>
#include <deque>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "dqo_map/common/image.h"
#include "dqo_map/gaussians/adam.h"
#include "dqo_map/gaussians/gaussian_map.h"
#include "dqo_map/gaussians/losses.h"
#include "dqo_map/gaussians/pixel_labels.h"
#include "dqo_map/gaussians/rasteriser.h"
#include "dqo_map/gaussians/training_engine.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"

namespace dqo::gs {

// One keyframe as the mapper gets it.
struct TrainingKeyframe {
  uint32_t id = 0;  // the tracker's keyframe ID (for pose updates)
  PinholeCamera camera;
  SE3 T_wc;
  ImageRgb8 rgb;
  DepthImage depth;   // metres; 0 / NaN = no measurement
  LabelImage labels;  // object ID per pixel, 0 = background; empty = all background
};

// What one add_keyframe() did.
struct KeyframeReport {
  size_t added_missing = 0;  // on the missing region
  size_t added_error = 0;    // on sampled error pixels
  size_t became_stable = 0;
  size_t relabelled = 0;  // Gaussians whose ID followed the labels (relabel_fraction)
  size_t pruned_stale = 0, pruned_oversized = 0, pruned_invisible = 0;
  size_t pruned_budget = 0;  // removed to keep Params::max_gaussians
  // The device ran out of memory (its message; empty: it did not): the least useful quarter of
  // the map was removed (pruned_memory) and the step tried again; a step that failed twice was
  // skipped (nothing added, or no training for this keyframe).
  std::string device_error;
  size_t pruned_memory = 0;
  size_t num_gaussians = 0, num_unstable = 0;
  size_t missing_pixels = 0, error_pixels = 0;
  int iterations = 0;
  bool abandoned = false;  // the stop flag ended the training early (iterations < Params::iterations)
  double loss_first = 0.0, loss_last = 0.0;  // total loss of the first and last iteration
  std::vector<double> losses;                 // of every iteration
  double seconds = 0.0;
  // Where the time went (ms): the render from the keyframe and the review of the Gaussians
  // (visibility, labels, usefulness), adding, training, stabilising and pruning.
  double review_ms = 0.0, add_ms = 0.0, train_ms = 0.0, prune_ms = 0.0;
};

class GaussianTrainer {
 public:
  struct Params {
    // Masks (METHOD.md §4).
    float missing_transmittance = 0.5f;  // T_final above this: the map is missing there
    float depth_error = 0.1f;            // θ_d, metres
    float colour_error = 0.1f;           // θ_c, mean |c − ĉ| over RGB in [0, 1]
    float ins_threshold = 0.5f;          // θ_α, on the pixels labelled with the object

    // New Gaussians.
    int missing_stride = 2;          // missing pixels on this grid become Gaussians
    float error_sample_rate = 0.2f;  // fraction of error pixels that do (released code: 5 %;
                                     // 20 % gave +0.4 dB on `tabletop`)
    float min_depth = 0.3f;          // metres: pixels outside the range add nothing
    float max_depth = 5.0f;
    float scale_factor = 0.5f;  // in-plane σ = factor · stride · depth / f
    float flatness = 0.1f;      // σ along the normal = flatness · in-plane σ
    float max_stretch = 3.f;    // in-plane σ along the slope grows by 1/cos(view angle),
                                // up to this factor
    int normal_radius_px = 2;   // neighbours at ± this many pixels give the normal
    // RTG-SLAM adds transparent Gaussians (TG) where only the colour is wrong; off: all opaque.
    bool transparent_for_colour_error = false;

    // Optimisation.
    int iterations = 50;  // per keyframe
    // Recent keyframes trained jointly, and all that is stored (memory: window · W · H · 20 bytes).
    // RTG-SLAM trains 3 at a time; with Gaussians kept trainable (below), older views must stay
    // in the window or training on new views spoils them (`tabletop`: 30 beat 8 by 2 dB).
    int window = 30;
    // Share of the iterations spent on the newest keyframe (its new Gaussians need them most); the
    // rest go to the others of the window, uniformly. <= 0: uniform over the whole window.
    float newest_share = 0.3f;
    float lambda_depth = 2.f;  // METHOD.md §4 weighs L_depth 1; 2 gave −0.05 cm depth L1
    float lambda_ins = 0.1f;
    float lambda_ssim = 0.f;  // L_rgb = (1 − λ) L1 + λ (1 − SSIM), as in 3DGS; 0 = L1 only
    bool normalise_depth = true;  // train and compare depth divided by accumulated alpha
    // render() gives the depth of the one surface each pixel sees (RenderSettings::surface_depth),
    // not the normalised depth, which at a silhouette mixes the foreground's fringe with the
    // surface behind it: on `tabletop`, the 2 % of pixels at depth edges held a sixth of the
    // depth L1 (BENCHMARKS.md, bench_mapping). Training and the masks keep the normalised depth:
    // its gradient reaches every Gaussian on a pixel, so it pulls a fringe off the pixels it
    // should not cover, and its error mask flags the mixed pixels for new Gaussians. Trained on
    // the surface depth, whose gradient reaches the chosen surface only (and drags a fringe that
    // wrongly won a pixel towards the depth behind it), depth L1 rose from 0.94 to 1.09 cm on 8
    // keyframes of `tabletop`; masks on it gave 0.96.
    bool surface_depth = true;
    float surface_gap = 0.02f;           // metres: a larger step in depth starts another surface
    float surface_gap_relative = 0.03f;  // of the depth, where that is more
    // Per-label training masks (one reading of METHOD.md §4's Mask^{O_k}): background Gaussians
    // learn from background pixels only, object Gaussians from object pixels only; costs a second
    // backward pass. Off by default: nothing then corrects a Gaussian of one label that covers
    // the other's pixels, and on `tabletop` PSNR fell by 5 dB and depth L1 tripled; relabelling
    // (below) keeps the IDs right instead.
    bool train_per_label = false;
    // METHOD.md's rates, but for position: 1e-3 m per step made the map noisier the longer it
    // trained (tabletop: 27.9 dB at 1e-3, 29.0 at 5e-4, 30.1 at 2.5e-4 and 1.25e-4).
    GaussianAdam::Params adam = [] {
      GaussianAdam::Params a;
      a.lr_position = 1.25e-4f;
      return a;
    }();

    // Stability and pruning. RTG-SLAM (METHOD.md §4): stable_confidence 100, max_unstable_age
    // ≈ 20 keyframes (120 frames at a keyframe every ~6). With 50 CPU iterations per keyframe a
    // Gaussian reaches 100 steps within two keyframes, frozen before other views have shaped it:
    // on `tabletop` (30 keyframes) 100 gave 24.9 dB, 500 26.7 dB, never 27.9 dB (same settings
    // otherwise), and the age rule then deletes whatever did not freeze in time. So both are off
    // by default; the rasteriser computes every gradient anyway, freezing saves no time here.
    float stable_confidence = 0.f;    // confidence (steps) at which a Gaussian freezes; 0: never
    int max_unstable_age = 0;         // keyframes; older unstable ones are removed; 0: never
    float max_scale = 0.5f;           // metres; any σ beyond this removes the Gaussian
    int max_invisible_keyframes = 5;  // in view (centre in the image, not behind the measured
                                      // surface) with contribution < min_contribution this many
                                      // keyframes in a row: removed
    float min_contribution = 0.05f;   // Σ over pixels of T_i α_i
    // Labels follow the observations: a Gaussian on the measured surface whose contribution to a
    // keyframe lies, for at least this fraction, on pixels labelled otherwise than it is (and
    // whose centre falls on such a pixel) takes that label after relabel_keyframes keyframes in a
    // row. 0: IDs never change after birth.
    float relabel_fraction = 0.8f;
    int relabel_keyframes = 2;
    // The Gaussian budget: past it, after the other pruning rules, the least useful Gaussians go
    // first. Usefulness is a Gaussian's contribution to the views that had it in sight (Σ over
    // pixels of T_i α_i), the largest of them with older views' decaying by `budget_decay` per
    // review, so that a Gaussian seen edge-on now keeps the weight it had face-on before; object
    // Gaussians count `budget_object_weight` times theirs (the objects are what the map is for, and
    // small ones far away contribute little to any view: on `room` at a quarter of its Gaussians,
    // the objects' completion ratio < 5 cm fell 8 points with weight 1, 5.4 with 4; BENCHMARKS.md). Gaussians not yet reviewed (added by this keyframe) count as most useful:
    // they were added because the map was missing or wrong there. 0: no budget.
    int max_gaussians = 0;
    float budget_decay = 0.9f;
    float budget_object_weight = 10.f;

    uint64_t seed = 1;

    // The review's settings (math/review.h) from these, both checks on.
    ReviewSettings review_settings() const {
      ReviewSettings rs{};
      rs.min_depth = min_depth;
      rs.depth_error = depth_error;
      rs.min_contribution = min_contribution;
      rs.relabel_fraction = relabel_fraction;
      rs.budget_decay = budget_decay;
      rs.relabel_keyframes = relabel_keyframes;
      rs.check_visibility = true;
      rs.check_labels = true;
      return rs;
    }
  };

  // rasteriser null: the CPU one on all cores. engine: where the iterations run (the GPU's,
  // cuda/train/); null, or for settings it does not cover (uses_engine()), the host runs them
  // through the rasteriser.
  explicit GaussianTrainer(const Params& params, std::unique_ptr<Rasteriser> rasteriser = nullptr,
                           std::unique_ptr<TrainingEngine> engine = nullptr);

  // Whether the iterations run on the engine: there is one and the settings are what it covers
  // (λ_ssim = 0, no train_per_label, opacity fixed).
  bool uses_engine() const;
  const TrainingEngine* engine() const { return engine_.get(); }

  const Params& params() const { return params_; }

  // The whole step for one keyframe (takes the images over). Throws std::invalid_argument when
  // an image is not of the camera's size.
  KeyframeReport add_keyframe(TrainingKeyframe keyframe);

  // More iterations over the window (idle time); returns the loss of the last one.
  double optimise(int iterations);

  // A flag another thread sets to end the training of the step in progress early (a shutdown
  // that must not wait for a long step): checked between two host iterations, so the map and the
  // optimiser stay consistent and the step still adds and prunes. An engine's batch (the GPU's,
  // milliseconds) runs to its end. Null: never. The flag must outlive the trainer's use of it.
  void set_stop_flag(const std::atomic<bool>* stop) { stop_ = stop; }

  // A stored keyframe's corrected pose (after bundle adjustment). False when not stored.
  bool set_keyframe_pose(uint32_t id, const SE3& T_wc);

  // Object `from` merged into `to` (0: back to the background): the map and the stored labels.
  size_t relabel(uint32_t from, uint32_t to);

  // Removes Gaussians (remove.size() == map().size()), keeping the optimiser state in step.
  size_t remove_if(const std::vector<uint8_t>& remove);

  // Replaces the map (a loaded one); optimiser and visibility state restart.
  void set_map(GaussianMap map);

  // The map. With an engine that keeps the trained attributes on its device between batches
  // (TrainingEngine::defer_attributes: the CUDA engine), they are brought down first where they
  // are newer there (56 bytes a Gaussian, at most once a batch). Not for concurrent callers: the
  // trainer, like its map, has one user at a time (the mapper's lock).
  const GaussianMap& map() const;
  // The map as the host holds it: its size, object IDs, flags and birth keyframes current, its
  // trained attributes as of the last fetch (map() brings them). For counts and reports, which
  // then cost no copy from the device.
  const GaussianMap& structure() const { return map_; }
  // The optimiser state (fetched from the engine, which holds it between batches).
  const GaussianAdam::State& adam_state();
  Rasteriser& rasteriser() { return *rasteriser_; }

  // Renders the map: colours as training does; depth of the surfaces (Params::surface_depth) or
  // as training does.
  void render(const PinholeCamera& camera, const SE3& T_wc, RenderOutput* out,
              uint32_t ins_object = 0);

  size_t keyframes_seen() const { return keyframe_count_; }
  size_t keyframes_stored() const { return window_.size(); }

 private:
  struct StoredKeyframe {
    uint32_t id = 0;
    PinholeCamera camera;
    SE3 T_wc;
    ImageRgb8 rgb;     // as received: 2.4 MB at 1200×680, where floats are 9.8 (and 3 ms to make)
    ImageF rgb_float;  // rgb / 255 (to_float_rgb), made for the host's own iterations only
    DepthImage depth;
    LabelImage labels;
    std::vector<uint32_t> objects;  // IDs with pixels in `labels`
    uint64_t key = 0;               // names the images for the engine; new when labels change
  };

  // map_'s trained attributes from the engine where it holds newer ones (map() is const: the
  // values it shows do not change, only where they are kept).
  void fetch_attributes() const;
  void fetch_counters();
  // Training and the masks: the normalised depth (normalise_depth); render(): the surface
  // depth where surface_depth is set.
  RenderSettings settings(uint32_t ins_object, bool for_render) const;
  // Visibility, labels and usefulness from one view; usefulness_only: the budget's measure alone.
  void review_gaussians(const StoredKeyframe& kf, const RenderState& state,
                        bool usefulness_only = false);
  void relabel_gaussians(const std::vector<std::pair<uint32_t, uint32_t>>& changes);
  // The masks' render: settings(0, false) with each pixel's own object's instance opacity.
  RenderSettings mask_settings(const StoredKeyframe& kf) const;
  // out: the render from the keyframe with mask_settings(); null when the map is empty
  // (everything is missing). ins_current: its `ins` is still the map's (no relabelling since).
  void add_gaussians(const StoredKeyframe& kf, const RenderOutput* out, KeyframeReport* report,
                     bool ins_current = true);
  // `stride`: the pixel spacing the new Gaussian stands for (its in-plane size).
  // The Gaussian of pixel (u, v) of the keyframe (const: called from several threads at once).
  GaussianInit gaussian_at(const StoredKeyframe& kf, int u, int v, int stride, bool transparent) const;
  double iterate(const StoredKeyframe& kf);
  // `iterations` iterations on the engine, keyframes and objects drawn as iterate() draws them;
  // the loss of each.
  std::vector<double> iterate_on_engine(int iterations);
  size_t pick_keyframe_index();
  const StoredKeyframe& pick_keyframe() { return window_[pick_keyframe_index()]; }
  // iterate()'s draw of the object whose L_ins a keyframe trains (0: none).
  uint32_t pick_object(const StoredKeyframe& kf);
  // `iterations` iterations wherever they run; the loss of each.
  std::vector<double> train(int iterations);
  void prune(KeyframeReport* report);
  // Removes by a plan over the map (remove_if's, or the pruning's made from its list of removals
  // without a pass over a mask): the map, the optimiser, the engine and the counters follow it.
  size_t remove_by(const RemovalPlan& plan);
  // Out of device memory: removes the least useful `fraction` of the map by the budget's measure
  // (as last reviewed: a new render could fail the same way). Returns how many.
  size_t shrink(double fraction);
  // Runs `step`; out of device memory, shrinks the map and runs it once more. False when it
  // failed twice (the report says so).
  template <typename Step>
  bool with_memory_retry(Step step, KeyframeReport* report);
  void sync_state();
  // Where the engine holds the map: brings its copy in step, so that the next renders use it.
  void sync_engine();

  Params params_;
  const std::atomic<bool>* stop_ = nullptr;  // see set_stop_flag
  std::unique_ptr<Rasteriser> rasteriser_;
  std::unique_ptr<TrainingEngine> engine_;
  uint64_t next_key_ = 1;
  GaussianMap map_;
  // The engine may hold newer trained attributes than map_'s (it defers them): fetched before
  // the host reads them (fetch_attributes()).
  mutable bool attributes_on_device_ = false;
  // Likewise the review counters below (TrainingEngine::holds_review_counters): fetch_counters()
  // before the host reads them. Removals and appends keep both copies in step meanwhile.
  bool counters_on_device_ = false;
  GaussianAdam adam_;
  // Per Gaussian, in step with map_.
  std::vector<uint16_t> invisible_count_;
  std::vector<uint8_t> relabel_votes_;
  std::vector<float> usefulness_;  // see Params::max_gaussians; +inf until first reviewed
  size_t relabelled_ = 0;
  std::deque<StoredKeyframe> window_;
  size_t keyframe_count_ = 0;
  std::mt19937_64 rng_;
  MapGradients grad_, grad_objects_;  // reused across iterations
  // The once-per-keyframe buffers, kept from keyframe to keyframe: at 1200×680 and a million
  // Gaussians they are 50 MB, whose fresh pages cost more than filling them.
  struct Scratch {
    RenderOutput render;   // the masks' render
    OutputGradients probe;  // the review's output gradients
    MapGradients review;    // its colour gradients
  } scratch_;
};

}  // namespace dqo::gs
