#include "map_store.h"

#include <algorithm>
#include <limits>

namespace dqo::tracking {

int MapPoint::observation_of(uint64_t keyframe) const {
  for (const auto& [kf, index] : observations)
    if (kf == keyframe) return index;
  return -1;
}

uint64_t MapStore::add_keyframe(KeyFrame keyframe) {
  const uint64_t id = next_keyframe_id_++;
  keyframe.id = id;
  keyframes_.emplace(id, std::move(keyframe));
  return id;
}

uint64_t MapStore::add_map_point(MapPoint point) {
  const uint64_t id = next_point_id_++;
  point.id = id;
  point.created_at_keyframe_count = keyframes_created();
  points_.emplace(id, std::move(point));
  return id;
}

KeyFrame* MapStore::keyframe(uint64_t id) {
  const auto it = keyframes_.find(id);
  return it == keyframes_.end() ? nullptr : &it->second;
}
const KeyFrame* MapStore::keyframe(uint64_t id) const {
  const auto it = keyframes_.find(id);
  return it == keyframes_.end() ? nullptr : &it->second;
}
MapPoint* MapStore::map_point(uint64_t id) {
  const auto it = points_.find(id);
  return it == points_.end() ? nullptr : &it->second;
}
const MapPoint* MapStore::map_point(uint64_t id) const {
  const auto it = points_.find(id);
  return it == points_.end() ? nullptr : &it->second;
}

void MapStore::add_observation(uint64_t point, uint64_t keyframe_id, int keypoint) {
  MapPoint* p = map_point(point);
  KeyFrame* kf = keyframe(keyframe_id);
  if (p == nullptr || kf == nullptr || keypoint < 0 ||
      keypoint >= static_cast<int>(kf->map_points.size()))
    return;
  const uint64_t previous = kf->map_points[keypoint];
  if (previous == point) return;
  if (previous != kNoId) erase_observation(previous, keyframe_id);
  // A point is seen at most once per keyframe: a second keypoint replaces the first.
  const int old = p->observation_of(keyframe_id);
  if (old >= 0) {
    kf->map_points[old] = kNoId;
    for (auto& o : p->observations)
      if (o.first == keyframe_id) o.second = keypoint;
  } else {
    p->observations.emplace_back(keyframe_id, keypoint);
  }
  kf->map_points[keypoint] = point;
}

void MapStore::erase_observation(uint64_t point, uint64_t keyframe_id) {
  MapPoint* p = map_point(point);
  if (p == nullptr) return;
  auto& obs = p->observations;
  for (auto it = obs.begin(); it != obs.end(); ++it) {
    if (it->first != keyframe_id) continue;
    if (KeyFrame* kf = keyframe(keyframe_id)) {
      if (it->second >= 0 && it->second < static_cast<int>(kf->map_points.size()) &&
          kf->map_points[it->second] == point)
        kf->map_points[it->second] = kNoId;
    }
    obs.erase(it);
    break;
  }
  if (obs.empty()) points_.erase(point);
}

void MapStore::erase_map_point(uint64_t point) {
  MapPoint* p = map_point(point);
  if (p == nullptr) return;
  for (const auto& [kf_id, index] : p->observations) {
    KeyFrame* kf = keyframe(kf_id);
    if (kf != nullptr && index >= 0 && index < static_cast<int>(kf->map_points.size()) &&
        kf->map_points[index] == point)
      kf->map_points[index] = kNoId;
  }
  points_.erase(point);
}

void MapStore::update_covisibility(uint64_t keyframe_id) {
  KeyFrame* kf = keyframe(keyframe_id);
  if (kf == nullptr) return;
  std::unordered_map<uint64_t, int> counts;
  for (const uint64_t id : kf->map_points) {
    const MapPoint* p = map_point(id);
    if (p == nullptr) continue;
    for (const auto& [other, index] : p->observations)
      if (other != keyframe_id) ++counts[other];
  }
  // ORB-SLAM2 links keyframes sharing at least 15 points, or else the best one.
  constexpr int kMinShared = 15;
  std::unordered_map<uint64_t, int> links;
  uint64_t best = kNoId;
  int best_count = 0;
  for (const auto& [other, count] : counts) {
    if (count > best_count) {
      best = other;
      best_count = count;
    }
    if (count >= kMinShared) links.emplace(other, count);
  }
  if (links.empty() && best != kNoId) links.emplace(best, best_count);

  auto reorder = [](KeyFrame* k) {
    k->ordered_covisible.clear();
    for (const auto& [id, w] : k->covisibility) k->ordered_covisible.emplace_back(w, id);
    std::sort(k->ordered_covisible.begin(), k->ordered_covisible.end(),
              [](const auto& a, const auto& b) { return a.first > b.first; });
  };
  // Drop this keyframe from neighbours it no longer links to; set the weight on the others.
  for (const auto& [other, w] : kf->covisibility) {
    if (links.count(other) != 0) continue;
    if (KeyFrame* o = keyframe(other)) {
      o->covisibility.erase(keyframe_id);
      reorder(o);
    }
  }
  kf->covisibility = links;
  for (const auto& [other, w] : links) {
    if (KeyFrame* o = keyframe(other)) {
      o->covisibility[keyframe_id] = w;
      reorder(o);
    }
  }
  reorder(kf);
}

int MapStore::tracked_points(uint64_t keyframe_id, int min_observations) const {
  const KeyFrame* kf = keyframe(keyframe_id);
  if (kf == nullptr) return 0;
  int n = 0;
  for (const uint64_t id : kf->map_points) {
    const MapPoint* p = map_point(id);
    n += p != nullptr && static_cast<int>(p->observations.size()) >= min_observations;
  }
  return n;
}

std::vector<uint64_t> MapStore::covisible(uint64_t keyframe_id, size_t n) const {
  std::vector<uint64_t> out;
  const KeyFrame* kf = keyframe(keyframe_id);
  if (kf == nullptr) return out;
  for (const auto& [w, id] : kf->ordered_covisible) {
    if (out.size() >= n) break;
    if (keyframes_.count(id) != 0) out.push_back(id);
  }
  return out;
}

void MapStore::update_point_appearance(uint64_t point, const ScalePyramid& scales) {
  MapPoint* p = map_point(point);
  if (p == nullptr || p->observations.empty()) return;
  std::vector<const Descriptor*> descriptors;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  int n = 0;
  const KeyFrame* reference = nullptr;
  int reference_index = -1;
  for (const auto& [kf_id, index] : p->observations) {
    const KeyFrame* kf = keyframe(kf_id);
    if (kf == nullptr || index < 0 || index >= static_cast<int>(kf->features.size())) continue;
    descriptors.push_back(&kf->features.descriptors[index]);
    normal += (p->p_w - kf->T_wc.translation()).normalized();
    ++n;
    if (reference == nullptr || kf_id == p->first_keyframe) {
      reference = kf;
      reference_index = index;
    }
  }
  if (n == 0) return;
  p->normal = normal.normalized();

  // The descriptor with the least median distance to the others (ORB-SLAM2).
  if (descriptors.size() <= 2) {
    p->descriptor = *descriptors.front();
  } else {
    const size_t m = descriptors.size();
    std::vector<int> dist(m * m, 0);
    for (size_t i = 0; i < m; ++i)
      for (size_t j = i + 1; j < m; ++j)
        dist[i * m + j] = dist[j * m + i] = hamming(*descriptors[i], *descriptors[j]);
    int best_median = std::numeric_limits<int>::max();
    size_t best = 0;
    std::vector<int> row(m);
    for (size_t i = 0; i < m; ++i) {
      std::copy(dist.begin() + static_cast<long>(i * m), dist.begin() + static_cast<long>(i * m + m),
                row.begin());
      std::nth_element(row.begin(), row.begin() + static_cast<long>((m - 1) / 2), row.end());
      const int median = row[(m - 1) / 2];
      if (median < best_median) {
        best_median = median;
        best = i;
      }
    }
    p->descriptor = *descriptors[best];
  }

  // Scale invariance range from the reference observation's level.
  const float distance =
      static_cast<float>((p->p_w - reference->T_wc.translation()).norm());
  const int level = reference->features.keypoints[reference_index].octave;
  const int levels = scales.levels();
  p->max_distance = distance * scales.scale[level];
  p->min_distance = p->max_distance / scales.scale[levels - 1];
}

void MapStore::clear() {
  keyframes_.clear();
  points_.clear();
  next_keyframe_id_ = 1;
  next_point_id_ = 1;
}

}  // namespace dqo::tracking
