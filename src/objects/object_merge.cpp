#include "object_merge.h"

#include <algorithm>

#include "dqo_map/geometry/oriented_box.h"

namespace dqo::objects {

bool inside_grown_ellipsoid(const DualQuadric& q, const Eigen::Vector3d& p_w, double margin) {
  const Eigen::Vector3d x = q.rotation().transpose() * (p_w - q.centre());
  const Eigen::Vector3d axes = q.semi_axes().array() + std::max(0.0, margin);
  return (x.array() / axes.array()).square().sum() <= 1.0;
}

bool seen_apart(const MapObject& a, const MapObject& b, double max_iou) {
  // Observations are oldest first, at most one per keyframe: walk both lists together.
  auto i = a.observations.begin();
  auto j = b.observations.begin();
  while (i != a.observations.end() && j != b.observations.end()) {
    if (i->keyframe_id < j->keyframe_id) {
      ++i;
    } else if (j->keyframe_id < i->keyframe_id) {
      ++j;
    } else {
      if (iou(i->box, j->box) < max_iou) return true;
      ++i;
      ++j;
    }
  }
  return false;
}

std::vector<MergePair> find_merges(const std::vector<const MapObject*>& objects,
                                   const std::vector<VisibleObject>& visible,
                                   const MergeParams& params) {
  std::vector<MergePair> pairs;
  if (!params.enabled) return pairs;
  std::vector<int> order(visible.size());
  for (size_t k = 0; k < order.size(); ++k) order[k] = static_cast<int>(k);
  std::sort(order.begin(), order.end(),
            [&](int a, int b) { return visible[a].box.area() > visible[b].box.area(); });
  std::vector<bool> used(visible.size(), false);
  for (size_t a = 0; a < order.size(); ++a) {
    const VisibleObject& big = visible[order[a]];
    if (used[order[a]]) continue;
    for (size_t b = a + 1; b < order.size(); ++b) {
      const VisibleObject& small = visible[order[b]];
      if (used[order[b]] || !(small.box.area() < big.box.area())) continue;
      const MapObject& i = *objects[big.index];
      const MapObject& j = *objects[small.index];
      if (!i.has_quadric || !j.has_quadric) continue;
      // Of one class (the votes' modes): the paper's test below. Of two classes, only ellipsoids
      // that overlap this much in 3D are one object (twins a detector's confusions started): a
      // book next to a laptop it is sometimes called must not join it because its projection
      // falls inside the laptop's.
      if (i.class_id != j.class_id &&
          !(params.min_iou_3d_any_class <= 1.0 &&
            iou_3d(box_from_quadric(i.quadric), box_from_quadric(j.quadric)) >= params.min_iou_3d_any_class)) {
        continue;
      }
      if (!(overlap_ratio(big.box, small.box) > params.min_overlap)) continue;
      // Two detections of one keyframe that went to the two objects: two things stood there
      // (two chairs side by side, one behind the other from some views), not one object's pieces.
      if (params.max_seen_apart_iou > 0.0 && seen_apart(i, j, params.max_seen_apart_iou)) continue;
      if (!inside_grown_ellipsoid(i.quadric, j.quadric.centre(), params.max_distance)) continue;
      pairs.push_back({small.index, big.index});
      used[order[a]] = used[order[b]] = true;
      break;
    }
  }
  return pairs;
}

bool update_class(MapObject* object, double rename_margin) {
  double total = 0.0, best = -1.0;
  int best_id = object->class_id;
  for (const auto& [class_id, votes] : object->class_votes) {
    total += votes;
    if (votes > best) {
      best = votes;
      best_id = class_id;
    }
  }
  const auto current = object->class_votes.find(object->class_id);
  // Hysteresis: two look-alike classes with about equal votes would otherwise rename the object
  // back and forth with every detection.
  const bool keep = current != object->class_votes.end() && best_id != object->class_id &&
                    best <= rename_margin * current->second;
  const int chosen = keep ? object->class_id : best_id;
  const bool changed = chosen != object->class_id;
  object->class_id = chosen;
  const auto c = object->class_votes.find(chosen);
  object->confidence = total > 0.0 && c != object->class_votes.end() ? c->second / total : 0.0;
  return changed;
}

void merge_object_into(const MapObject& from, MapObject* into, double rename_margin) {
  std::vector<ObjectObservation> merged = into->observations;
  for (const ObjectObservation& o : from.observations) {
    const bool taken = std::any_of(merged.begin(), merged.end(), [&](const ObjectObservation& m) {
      return m.keyframe_id == o.keyframe_id;
    });
    if (!taken) merged.push_back(o);
  }
  // Keyframe IDs grow with time (trackers number them in order), so this keeps oldest first.
  std::stable_sort(merged.begin(), merged.end(),
                   [](const ObjectObservation& a, const ObjectObservation& b) {
                     return a.keyframe_id < b.keyframe_id;
                   });
  into->observations = std::move(merged);
  for (const auto& [class_id, votes] : from.class_votes) into->class_votes[class_id] += votes;
  into->observation_count += from.observation_count;
  into->missed = std::min(into->missed, from.missed);
  // Both were evidence of one object; the stronger belief stands for it.
  into->existence = std::max(into->existence, from.existence);
  into->first_keyframe = std::min(into->first_keyframe, from.first_keyframe);
  into->last_keyframe = std::max(into->last_keyframe, from.last_keyframe);
  if (from.state == ObjectState::kConfirmed) into->state = ObjectState::kConfirmed;
  if (from.class_name.size() && into->class_name.empty()) into->class_name = from.class_name;
  update_class(into, rename_margin);
}

}  // namespace dqo::objects
