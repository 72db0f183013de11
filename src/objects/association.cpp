#include "association.h"

#include <algorithm>

#include "assignment.h"
#include "depth_init.h"
#include "dqo_map/geometry/quadric_distance.h"

namespace dqo::objects {
namespace {

std::optional<DualQuadric> depth_quadric(const Box2d& box, const AssociationFrame& frame,
                                         const LifecycleParams& lifecycle) {
  if (!lifecycle.single_view_fallback || frame.depth.data == nullptr) return std::nullopt;
  const QuadricInitResult r =
      initialise_from_depth(box, *frame.camera, frame.T_wc, frame.depth, lifecycle.depth_init);
  if (!r.ok) return std::nullopt;
  return r.quadric;
}

std::optional<DualQuadric> box_quadric(const MapObject& object, const Box2d& box,
                                       const AssociationFrame& frame, const ViewLookup& lookup,
                                       int max_views, const LifecycleParams& lifecycle,
                                       const DualQuadric* box_depth) {
  std::vector<BoxObservation> views;
  std::vector<DepthEvidence> evidence;
  const int want = std::max(0, max_views - 1);
  for (auto it = object.observations.rbegin();
       it != object.observations.rend() && static_cast<int>(views.size()) < want; ++it) {
    if (auto v = lookup(*it)) {
      views.push_back(*v);
      if (frame.depth_lookup) evidence.push_back(frame.depth_lookup(*it));
    }
  }
  BoxObservation current;
  current.P = frame.P;
  current.box = box;
  current.width = frame.camera->width;
  current.height = frame.camera->height;
  views.push_back(current);
  if (static_cast<int>(views.size()) < std::max(3, lifecycle.min_box_views)) return std::nullopt;
  const QuadricInitResult r = initialise_from_boxes(views, lifecycle.box_init);
  if (!r.ok) return std::nullopt;
  // Departure from METHOD.md §2.4: a box-plane quadric that the depth contradicts is not compared
  // (the depth ellipsoid of the detection is, by the caller); see LifecycleParams.
  if (lifecycle.max_depth_disagreement > 0.0) {
    if (box_depth) evidence.push_back({frame.T_wc.inverse(), box_depth});
    const double disagreement = depth_disagreement(r.quadric, evidence);
    if (disagreement > lifecycle.max_depth_disagreement) return std::nullopt;
  }
  return r.quadric;
}

}  // namespace

std::optional<DualQuadric> observation_quadric(const MapObject& object, const Box2d& box,
                                               const AssociationFrame& frame,
                                               const ViewLookup& lookup, int max_views,
                                               const LifecycleParams& lifecycle,
                                               const DualQuadric* box_depth) {
  if (auto q = box_quadric(object, box, frame, lookup, max_views, lifecycle, box_depth)) return q;
  if (box_depth && lifecycle.single_view_fallback) return *box_depth;
  return depth_quadric(box, frame, lifecycle);
}

AssociationResult associate(const std::vector<AssociationTrack>& tracks,
                            const std::vector<Detection2d>& detections,
                            const AssociationFrame& frame, const ViewLookup& lookup,
                            const AssociationParams& params, const LifecycleParams& lifecycle) {
  AssociationResult result;
  result.track_to_detection.assign(tracks.size(), -1);
  if (tracks.empty() || detections.empty()) return result;
  const bool use_iou = params.strategy != AssociationStrategy::kQd;
  const bool use_qd = params.strategy != AssociationStrategy::kIou;

  // The detection's own depth ellipsoid is the same for every object: build it at most once.
  std::vector<std::optional<std::optional<DualQuadric>>> depth_cache(detections.size());
  if (frame.detection_depth && frame.detection_depth->size() == detections.size()) {
    for (size_t d = 0; d < detections.size(); ++d) depth_cache[d] = (*frame.detection_depth)[d];
  }
  Eigen::MatrixXd scores =
      Eigen::MatrixXd::Constant(static_cast<Eigen::Index>(tracks.size()),
                                static_cast<Eigen::Index>(detections.size()), kForbidden);
  for (size_t t = 0; t < tracks.size(); ++t) {
    const MapObject& object = *tracks[t].object;
    for (size_t d = 0; d < detections.size(); ++d) {
      const Detection2d& det = detections[d];
      if (params.require_same_class && det.class_id != object.class_id) continue;
      const double overlap = iou(tracks[t].box, det.box);
      if (use_iou && !(overlap > params.min_iou)) continue;
      ++result.coarse_pairs;
      double similarity = 0.0;
      if (use_qd) {
        if (!object.has_quadric) {
          // Nothing to compare with yet: the coarse gate decides (qd alone cannot).
          if (!use_iou) continue;
        } else {
          auto depth_of_detection = [&]() {
            auto& cached = depth_cache[d];
            if (!cached) cached = depth_quadric(det.box, frame, lifecycle);
            return *cached;
          };
          std::optional<DualQuadric> observed;
          if (params.fine_quadric == FineQuadric::kDepth && lifecycle.single_view_fallback) {
            observed = depth_of_detection();
          }
          if (!observed) {
            const std::optional<DualQuadric> depth = lifecycle.max_depth_disagreement > 0.0
                                                         ? depth_of_detection()
                                                         : std::nullopt;
            observed = box_quadric(object, det.box, frame, lookup, params.max_init_views, lifecycle,
                                   depth ? &*depth : nullptr);
          }
          if (!observed && params.fine_quadric == FineQuadric::kBoxes && lifecycle.single_view_fallback) {
            observed = depth_of_detection();
          }
          ++result.fine_inits;
          if (!observed) {
            if (!use_iou) continue;  // qd alone has nothing to go on
          } else {
            similarity = quadric_similarity(*observed, object.quadric, params.distance);
            // A projection that covers the detection this well is the object, whatever the fine
            // step's quadric says: that quadric, from a candidate's few views or one view's depth,
            // is what is unreliable then (a TV seen obliquely, its depth ellipsoid on the wall).
            if (!(similarity >= params.min_similarity) && !(use_iou && overlap >= params.accept_iou)) continue;
          }
        }
      }
      double score = 0.0;
      if (use_iou) score += overlap;
      if (use_qd) score += similarity;
      // Admissible pairs must score above zero for the assignment; a pair that passed its gates
      // is worth taking even when its similarity could not be computed.
      scores(static_cast<Eigen::Index>(t), static_cast<Eigen::Index>(d)) = std::max(score, 1e-6);
    }
  }
  result.track_to_detection = solve_assignment(scores);
  return result;
}

}  // namespace dqo::objects
