#pragma once
// Adam over the Gaussian map's attribute arrays, with one learning rate per attribute
// (METHOD.md §4, Replica settings) and its moments kept per Gaussian, so that they follow the map
// through additions (append: zero moments) and removals (the same keep-mask as
// GaussianMap::remove_if). Relabelling does not move Gaussians and needs nothing.
//
// Sparse, as the incremental update needs: a step only touches the Gaussians the caller selects
// (the unstable ones that the current view reached); the others keep their values and their
// moments, and each Gaussian counts its own steps for the bias correction, so one that joined late
// or sat out some iterations gets the same first steps as one trained from the start.

#include <cstdint>
#include <vector>

#include "dqo_map/gaussians/gaussian_map.h"
#include "dqo_map/gaussians/rasteriser.h"

namespace dqo::gs {

class GaussianAdam {
 public:
  struct Params {
    float lr_position = 1e-3f;
    float lr_log_scale = 1.6e-2f;
    float lr_rotation = 4e-3f;
    float lr_colour = 2e-3f;
    // 0: opacity is not trained (fixed by type, METHOD.md §4). Otherwise Adam runs on the logit of
    // the opacity, so it stays in (0, 1).
    float lr_opacity = 0.f;
    float beta1 = 0.9f;
    float beta2 = 0.999f;
    float epsilon = 1e-15f;          // as in 3DGS: gradients are small, a larger ε would damp them
    bool normalise_rotation = true;  // keep quaternions unit after a step (rendering is unchanged)
    bool clamp_colour = true;        // keep colours in [0, 1]
  };

  GaussianAdam() = default;
  explicit GaussianAdam(const Params& params) : params_(params) {}

  const Params& params() const { return params_; }
  size_t size() const { return s_.steps.size(); }

  // Grows (zero moments for the new Gaussians, which are appended) or shrinks to map.size().
  void resize_for(const GaussianMap& map);
  // false: an engine that runs the steps on a device keeps the moments (cuda/train/). The host
  // then keeps each Gaussian's step count alone; the moments stay empty, or hold the latest copy
  // fetched from the engine until the map next changes (resize_for, remove_if). That spares the
  // host 112 bytes per Gaussian and their compaction at every pruning (5 ms a keyframe at 1.3 M
  // Gaussians). step() refuses to run without them.
  void keep_moments_on_host(bool keep);
  bool moments_on_host() const { return keep_moments_; }
  // Drops the state of every Gaussian i with remove[i] != 0, as GaussianMap::remove_if does.
  void remove_if(const std::vector<uint8_t>& remove);
  void remove(const RemovalPlan& plan);  // the same by the map's plan
  void reset();

  // One step on every Gaussian i with update[i] != 0 (update.size() == map->size()); the gradient
  // arrays are laid out as the map's (MapGradients). Empty gradient arrays count as zero.
  void step(const MapGradients& grad, const std::vector<uint8_t>& update, GaussianMap* map);

  // The moments and each Gaussian's step count, laid out as the map's arrays: for an engine that
  // runs the steps on a device and hands the state back (cuda/train/).
  struct Moments {
    std::vector<float> m, v;  // width per Gaussian as the attribute
  };
  struct State {
    Moments position, log_scale, rotation, opacity, colour;
    std::vector<uint32_t> steps;
  };
  const State& state() const { return s_; }
  State& mutable_state() { return s_; }  // keep it sized for the map (resize_for)

 private:
  void drop_moments();

  Params params_;
  State s_;
  bool keep_moments_ = true;
};

}  // namespace dqo::gs
