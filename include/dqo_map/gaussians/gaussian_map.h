#pragma once
// The Gaussian map as a structure of arrays: each attribute one flat, contiguous float/int array
// (3 floats per position, 4 per rotation, ...), so that the CPU rasteriser streams through them and
// the CUDA backend copies them to the device as they are. Every Gaussian carries the ID of the
// object it belongs to (0 = background), its type (opaque OG / transparent TG, METHOD.md §4), a
// confidence and a stable flag for the incremental update.
//
// Indices are not stable across remove_if(); object IDs are.

#include <cstddef>
#include <cstdint>
#include <map>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "dqo_map/gaussians/removal_plan.h"

namespace dqo::gs {

enum class GaussianType : uint8_t { kOpaque = 0, kTransparent = 1 };

// Opacities fixed per type unless opacity training is on (METHOD.md §4: OG 0.9, TG 0.1).
constexpr float kOpaqueOpacity = 0.9f;
constexpr float kTransparentOpacity = 0.1f;

struct GaussianInit {
  Eigen::Vector3f position = Eigen::Vector3f::Zero();  // world frame, metres
  Eigen::Vector3f log_scale = Eigen::Vector3f::Constant(-4.6f);  // log of the standard deviations
  Eigen::Vector4f rotation = Eigen::Vector4f(1, 0, 0, 0);        // unit quaternion (w, x, y, z)
  Eigen::Vector3f colour = Eigen::Vector3f::Constant(0.5f);      // RGB in [0, 1] (degree-0 SH)
  float opacity = -1.f;  // < 0: the type's fixed opacity
  uint32_t object_id = 0;
  GaussianType type = GaussianType::kOpaque;
  uint32_t birth_keyframe = 0;
};

// A stamp that takes a new value, unique in the process, whenever a map is created, copied or
// assigned, or adds, removes or relabels Gaussians: a GPU backend that holds a copy of a map on
// the device renders from it only while the map still carries the stamp it copied (cuda/train/
// resident_map.h). Attribute values changed through the non-const accessors do not change it:
// that is the trainer's business, which keeps its engine told (gaussians/training_engine.h).
class MapRevision {
 public:
  MapRevision() : value_(next()) {}
  MapRevision(const MapRevision&) : value_(next()) {}
  MapRevision& operator=(const MapRevision&) {
    value_ = next();
    return *this;
  }
  void bump() { value_ = next(); }
  uint64_t value() const { return value_; }

 private:
  static uint64_t next();
  uint64_t value_;
};

class GaussianMap {
 public:
  size_t size() const { return object_id_.size(); }
  bool empty() const { return object_id_.empty(); }

  // Appends one Gaussian; returns its index.
  size_t add(const GaussianInit& g);
  void reserve(size_t n);

  // Removes every Gaussian i with remove[i] != 0 (remove.size() == size()): the removed entries
  // below the new size take the last kept Gaussians (gaussians/removal_plan.h), the others stay
  // where they are. Returns how many were removed.
  size_t remove_if(const std::vector<uint8_t>& remove);
  // The same by a plan made beforehand (plan.size == size()): the owners of per-Gaussian arrays
  // (the map, the optimiser, a device's copy) then follow one plan, made once.
  size_t remove(const RemovalPlan& plan);

  // Gaussian i as add() takes it (its opacity explicit); confidence and stable flag apart.
  GaussianInit gaussian(size_t i) const;
  // The Gaussians at `indices`, in that order, as a map of their own (confidence and stable kept).
  GaussianMap subset(const std::vector<uint32_t>& indices) const;

  // Gaussians of one object (0 = background), in index order. A scan of the IDs (~0.1 ms per 100k
  // Gaussians) rather than a cached index: a const call stays safe from several threads at once,
  // and extraction of one object is rare next to the trainer's edits that would invalidate a cache.
  std::vector<uint32_t> indices_of(uint32_t object_id) const;
  // Object IDs present in the map, ascending.
  std::vector<uint32_t> object_ids() const;
  // How many Gaussians each object ID present has (0: the background), by runs of equal IDs
  // (Gaussians come a keyframe's object at a time) over threads: 1.5 ms on one core at 1.3 M
  // Gaussians, asked after every keyframe.
  std::map<uint32_t, size_t> counts_by_object() const;

  // Every Gaussian of `from` becomes `to`'s (an object merged into another; to = 0 returns them to
  // the background). Returns how many were relabelled.
  size_t relabel(uint32_t from, uint32_t to);
  // Gaussians one by one: each (index, new ID) of `changes` (the labels that follow the
  // observations, GaussianTrainer: a handful a keyframe). Returns how many changed; an index out
  // of range throws std::invalid_argument before anything changes.
  size_t relabel_each(const std::vector<std::pair<uint32_t, uint32_t>>& changes);

  // Bytes held by the attribute arrays (capacity, not size).
  size_t bytes_used() const;

  // See MapRevision.
  uint64_t revision() const { return revision_.value(); }
  // A stamp of the per-Gaussian flags the host sets (object IDs, stable flags): new whenever they
  // may have changed other than by add() and remove_if() — a relabelling, or any use of the
  // non-const stable() — so that a device copy sends them whole only then (and the appended
  // Gaussians' otherwise). Reading them through a const map leaves it as it is.
  uint64_t flags_revision() const { return flags_revision_.value(); }

  // Flat attribute arrays, index i at [i * width, (i + 1) * width).
  std::vector<float>& positions() { return position_; }            // 3 per Gaussian
  std::vector<float>& log_scales() { return log_scale_; }          // 3
  std::vector<float>& rotations() { return rotation_; }            // 4: w x y z (not kept unit:
                                                                    // normalised where used)
  std::vector<float>& opacities() { return opacity_; }             // 1, in (0, 1)
  std::vector<float>& colours() { return colour_; }                // 3, RGB
  std::vector<float>& confidences() { return confidence_; }        // 1
  std::vector<uint8_t>& stable() {                                 // 1: frozen when non-zero
    flags_revision_.bump();
    return stable_;
  }
  const std::vector<float>& positions() const { return position_; }
  const std::vector<float>& log_scales() const { return log_scale_; }
  const std::vector<float>& rotations() const { return rotation_; }
  const std::vector<float>& opacities() const { return opacity_; }
  const std::vector<float>& colours() const { return colour_; }
  const std::vector<float>& confidences() const { return confidence_; }
  const std::vector<uint8_t>& stable() const { return stable_; }
  const std::vector<uint32_t>& object_ids_per_gaussian() const { return object_id_; }
  const std::vector<uint8_t>& types() const { return type_; }           // GaussianType values
  const std::vector<uint32_t>& birth_keyframes() const { return birth_keyframe_; }

 private:
  std::vector<float> position_, log_scale_, rotation_, opacity_, colour_, confidence_;
  std::vector<uint32_t> object_id_, birth_keyframe_;
  std::vector<uint8_t> type_, stable_;
  MapRevision revision_, flags_revision_;
};

}  // namespace dqo::gs
