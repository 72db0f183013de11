#include "dqo_map/gaussians/gaussian_map.h"

#include <algorithm>
#include <atomic>
#include <stdexcept>
#include <string>
#include <unordered_map>

#include "compaction.h"

namespace dqo::gs {

uint64_t MapRevision::next() {
  static std::atomic<uint64_t> counter{0};
  return counter.fetch_add(1, std::memory_order_relaxed) + 1;
}

namespace {

template <typename V>
size_t capacity_bytes(const std::vector<V>& v) {
  return v.capacity() * sizeof(V);
}

}  // namespace

GaussianInit GaussianMap::gaussian(size_t i) const {
  GaussianInit g;
  g.position = Eigen::Map<const Eigen::Vector3f>(&position_[3 * i]);
  g.log_scale = Eigen::Map<const Eigen::Vector3f>(&log_scale_[3 * i]);
  g.rotation = Eigen::Map<const Eigen::Vector4f>(&rotation_[4 * i]);
  g.colour = Eigen::Map<const Eigen::Vector3f>(&colour_[3 * i]);
  g.opacity = opacity_[i];
  g.object_id = object_id_[i];
  g.type = static_cast<GaussianType>(type_[i]);
  g.birth_keyframe = birth_keyframe_[i];
  return g;
}

GaussianMap GaussianMap::subset(const std::vector<uint32_t>& indices) const {
  GaussianMap out;
  out.reserve(indices.size());
  for (const uint32_t i : indices) {
    const size_t j = out.add(gaussian(i));
    out.confidence_[j] = confidence_[i];
    out.stable_[j] = stable_[i];
  }
  return out;
}

size_t GaussianMap::add(const GaussianInit& g) {
  revision_.bump();
  const size_t index = size();
  position_.insert(position_.end(), g.position.data(), g.position.data() + 3);
  log_scale_.insert(log_scale_.end(), g.log_scale.data(), g.log_scale.data() + 3);
  rotation_.insert(rotation_.end(), g.rotation.data(), g.rotation.data() + 4);
  colour_.insert(colour_.end(), g.colour.data(), g.colour.data() + 3);
  const float type_opacity = g.type == GaussianType::kOpaque ? kOpaqueOpacity : kTransparentOpacity;
  opacity_.push_back(g.opacity < 0.f ? type_opacity : g.opacity);
  confidence_.push_back(0.f);
  stable_.push_back(0);
  object_id_.push_back(g.object_id);
  birth_keyframe_.push_back(g.birth_keyframe);
  type_.push_back(static_cast<uint8_t>(g.type));
  return index;
}

void GaussianMap::reserve(size_t n) {
  position_.reserve(3 * n);
  log_scale_.reserve(3 * n);
  rotation_.reserve(4 * n);
  colour_.reserve(3 * n);
  opacity_.reserve(n);
  confidence_.reserve(n);
  stable_.reserve(n);
  object_id_.reserve(n);
  birth_keyframe_.reserve(n);
  type_.reserve(n);
}

size_t GaussianMap::remove_if(const std::vector<uint8_t>& remove) {
  if (remove.size() != size())
    throw std::invalid_argument("GaussianMap::remove_if: mask has " +
                                std::to_string(remove.size()) + " entries for " +
                                std::to_string(size()) + " Gaussians");
  return this->remove(plan_removal(remove));
}

size_t GaussianMap::remove(const RemovalPlan& plan) {
  if (plan.size != size())
    throw std::invalid_argument("GaussianMap::remove: the plan is for " + std::to_string(plan.size) +
                                " Gaussians, the map has " + std::to_string(size()));
  const size_t before = size();
  detail::Compaction c(plan);
  c.add(&position_, 3);
  c.add(&log_scale_, 3);
  c.add(&rotation_, 4);
  c.add(&colour_, 3);
  c.add(&opacity_, 1);
  c.add(&confidence_, 1);
  c.add(&stable_, 1);
  c.add(&object_id_, 1);
  c.add(&birth_keyframe_, 1);
  c.add(&type_, 1);
  c.run();
  const size_t removed = before - size();
  if (removed) revision_.bump();
  return removed;
}

std::vector<uint32_t> GaussianMap::indices_of(uint32_t object_id) const {
  std::vector<uint32_t> indices;
  for (size_t i = 0; i < object_id_.size(); ++i) {
    if (object_id_[i] == object_id) indices.push_back(static_cast<uint32_t>(i));
  }
  return indices;
}

std::vector<uint32_t> GaussianMap::object_ids() const {
  std::vector<uint32_t> ids;
  for (const auto& [id, count] : counts_by_object()) ids.push_back(id);
  return ids;
}

std::map<uint32_t, size_t> GaussianMap::counts_by_object() const {
  const size_t n = object_id_.size();
  // Fixed chunks, each counted by runs into its own table, merged in order.
  constexpr size_t kChunk = size_t{1} << 16;
  const size_t chunks = (n + kChunk - 1) / kChunk;
  std::vector<std::unordered_map<uint32_t, size_t>> partial(chunks);
  detail::parallel_for_dynamic(chunks > 1 ? detail::resolve_threads(0) : 1, chunks, [&](size_t c) {
    const size_t end = std::min(n, (c + 1) * kChunk);
    for (size_t i = c * kChunk; i < end;) {
      size_t j = i + 1;
      while (j < end && object_id_[j] == object_id_[i]) ++j;
      partial[c][object_id_[i]] += j - i;
      i = j;
    }
  });
  std::map<uint32_t, size_t> counts;
  for (const auto& p : partial)
    for (const auto& [id, count] : p) counts[id] += count;
  return counts;
}

size_t GaussianMap::relabel(uint32_t from, uint32_t to) {
  if (from == to) return 0;
  size_t n = 0;
  for (uint32_t& id : object_id_) {
    if (id == from) {
      id = to;
      ++n;
    }
  }
  if (n) revision_.bump(), flags_revision_.bump();
  return n;
}

size_t GaussianMap::relabel_each(const std::vector<std::pair<uint32_t, uint32_t>>& changes) {
  for (const auto& [index, id] : changes) {
    if (index >= size())
      throw std::invalid_argument("GaussianMap::relabel_each: index " + std::to_string(index) + " of " +
                                  std::to_string(size()) + " Gaussians");
  }
  size_t n = 0;
  for (const auto& [index, id] : changes) {
    if (object_id_[index] == id) continue;
    object_id_[index] = id;
    ++n;
  }
  if (n) revision_.bump(), flags_revision_.bump();
  return n;
}

size_t GaussianMap::bytes_used() const {
  return capacity_bytes(position_) + capacity_bytes(log_scale_) + capacity_bytes(rotation_) +
         capacity_bytes(opacity_) + capacity_bytes(colour_) + capacity_bytes(confidence_) +
         capacity_bytes(object_id_) + capacity_bytes(birth_keyframe_) + capacity_bytes(type_) +
         capacity_bytes(stable_);
}

}  // namespace dqo::gs
