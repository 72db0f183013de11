#pragma once
// Which per-Gaussian entries move where when some Gaussians are removed: the removed entries below
// the new size are filled, in ascending order, by the kept entries at or above it, in ascending
// order; everything else stays where it is. The kept Gaussians' order changes (a few from the end
// fill the holes), but a removal moves as many entries as it removes, not the whole map: pruning
// tens of a million Gaussians no longer copies every array (room: 4.8 ms a keyframe on the host).
// The host's arrays (GaussianMap, GaussianAdam, the trainer's counters) and the device's copies
// (cuda/train/resident_map.cpp) follow the same plan, so they stay entry for entry alike.

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>

namespace dqo::gs {

struct RemovalPlan {
  size_t size = 0;                 // the entries before the removal
  size_t kept = 0;                 // the new size
  std::vector<uint32_t> holes;     // removed entries below `kept`, ascending
  std::vector<uint32_t> sources;   // kept entries at or above `kept`, ascending: holes[k] <- sources[k]
  size_t removed() const { return size - kept; }
};

// The plan of a mask over all the entries (remove[i] != 0: entry i goes).
inline RemovalPlan plan_removal(const std::vector<uint8_t>& remove) {
  if (remove.size() > UINT32_MAX) throw std::invalid_argument("plan_removal: more than 2^32 Gaussians");
  RemovalPlan plan;
  plan.size = remove.size();
  size_t removed = 0;
  for (const uint8_t r : remove) removed += r != 0;
  plan.kept = remove.size() - removed;
  for (size_t i = 0; i < plan.kept; ++i) {
    if (remove[i]) plan.holes.push_back(static_cast<uint32_t>(i));
  }
  for (size_t i = plan.kept; i < remove.size(); ++i) {
    if (!remove[i]) plan.sources.push_back(static_cast<uint32_t>(i));
  }
  return plan;  // as many sources as holes: the kept entries above `kept` are the holes' count
}

// The same plan from the removed entries' indices (ascending, each below n), in time linear in
// their count rather than in n: the holes are the list's entries below the new size, the sources
// the others of the last `removed` entries. The pruning of a large map removes few.
inline RemovalPlan plan_removal(const std::vector<uint32_t>& removed, size_t n) {
  if (n > UINT32_MAX) throw std::invalid_argument("plan_removal: more than 2^32 Gaussians");
  for (size_t k = 0; k < removed.size(); ++k) {
    if (removed[k] >= n || (k > 0 && removed[k] <= removed[k - 1]))
      throw std::invalid_argument("plan_removal: the removed indices must ascend and lie below the size");
  }
  RemovalPlan plan;
  plan.size = n;
  plan.kept = n - removed.size();
  size_t k = 0;
  for (; k < removed.size() && removed[k] < plan.kept; ++k) plan.holes.push_back(removed[k]);
  for (size_t i = plan.kept; i < n; ++i) {
    if (k < removed.size() && removed[k] == i) {
      ++k;
    } else {
      plan.sources.push_back(static_cast<uint32_t>(i));
    }
  }
  return plan;
}

// Applies the plan to an array of `width` values per Gaussian, in place.
template <typename T>
void apply_removal(std::vector<T>* values, size_t width, const RemovalPlan& plan) {
  T* v = values->data();
  for (size_t k = 0; k < plan.holes.size(); ++k) {
    for (size_t c = 0; c < width; ++c) v[plan.holes[k] * width + c] = v[plan.sources[k] * width + c];
  }
  values->resize(plan.kept * width);
}

}  // namespace dqo::gs
