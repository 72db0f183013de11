#include "dqo_map/objects/object_mapper.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <set>

#include <Eigen/Geometry>

#include "association.h"
#include "box_fit.h"
#include "depth_init.h"
#include "existence.h"
#include "detection_filter.h"
#include "dqo_map/geometry/conic.h"
#include "dqo_map/objects/object_refinement.h"
#include "object_merge.h"
#include "object_surface.h"
#include "state_file.h"
#include "visibility.h"

namespace dqo::objects {
namespace {

using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// What the mapper keeps of a keyframe: enough to turn an observation box back into a view.
struct KeyframeRecord {
  PinholeCamera camera;
  SE3 T_wc;
  Eigen::Matrix<double, 3, 4> P = Eigen::Matrix<double, 3, 4>::Zero();
  uint64_t sequence = 0;  // how many keyframes came before it
  // What the keyframe's depth said of each kept detection (depth images are not kept), found by
  // its box (the filter leaves no two boxes alike).
  struct DetectionDepth {
    Box2d box;
    // The single-view depth ellipsoid, where there is one: the depth evidence that box-plane
    // quadrics of the observations are checked against.
    std::optional<DualQuadric> ellipsoid;
    // Depth samples inside the box, camera frame (SurfaceParams): the object's own surface, moved
    // with the keyframe when bundle adjustment corrects its pose.
    std::vector<Eigen::Vector3f> points;
    double stand_out = std::nan("");  // stand_out_share of the box
    std::optional<BackPlane> back_plane;  // find_back_plane's, camera frame
  };
  std::vector<DetectionDepth> detections;

  const DetectionDepth* find(const Box2d& b) const {
    for (const DetectionDepth& d : detections) {
      if (d.box.x_min == b.x_min && d.box.y_min == b.y_min && d.box.x_max == b.x_max && d.box.y_max == b.y_max) {
        return &d;
      }
    }
    return nullptr;
  }
};

Eigen::Vector3d sorted(Eigen::Vector3d v) {
  std::sort(v.data(), v.data() + 3);
  return v;
}

bool finite_pose(const SE3& T) {
  return T.translation().allFinite() && T.quaternion().coeffs().allFinite();
}

}  // namespace

struct ObjectMapper::Impl {
  ObjectMapperParams params;
  ObjectId next_id = 1;
  uint64_t sequence = 0;
  std::map<ObjectId, MapObject> objects;
  std::map<ObjectId, uint64_t> first_sequence;  // for the candidates' age
  std::map<KeyFrameId, KeyframeRecord> keyframes;
  std::map<int, std::string> class_names;
  std::string map_id;

  // What its keyframe's depth said of an observation's detection (nullptr: unknown keyframe, or
  // no depth there).
  const KeyframeRecord::DetectionDepth* depth_record_of(const ObjectObservation& o) const {
    const auto it = keyframes.find(o.keyframe_id);
    return it == keyframes.end() ? nullptr : it->second.find(o.box);
  }

  // The depth ellipsoid of an observation's detection.
  const DualQuadric* depth_of(const ObjectObservation& o) const {
    const KeyframeRecord::DetectionDepth* d = depth_record_of(o);
    return d && d->ellipsoid ? &*d->ellipsoid : nullptr;
  }

  DepthEvidence evidence_of(const ObjectObservation& o) const {
    DepthEvidence e;
    const auto it = keyframes.find(o.keyframe_id);
    if (it == keyframes.end()) return e;
    e.T_cw = it->second.T_wc.inverse();
    e.depth = depth_of(o);
    return e;
  }

  // The world points of an object's newest observations (at most max_views) and the camera
  // centres that saw them.
  void surface_of(const MapObject& object, int max_views, std::vector<Eigen::Vector3d>* points,
                  std::vector<Eigen::Vector3d>* cameras, std::vector<BackPlane>* back_planes = nullptr) const {
    std::vector<std::pair<const KeyframeRecord*, const KeyframeRecord::DetectionDepth*>> views;
    size_t total = 0;
    for (auto o = object.observations.rbegin(); o != object.observations.rend() && static_cast<int>(views.size()) < max_views; ++o) {
      const auto it = keyframes.find(o->keyframe_id);
      if (it == keyframes.end()) continue;
      const KeyframeRecord::DetectionDepth* d = it->second.find(o->box);
      if (!d) continue;
      views.emplace_back(&it->second, d);
      total += d->points.size();
    }
    // At most max_points in all: every stride-th sample of each view (bounded cost per object).
    const size_t limit = static_cast<size_t>(std::max(1, params.surface.max_points));
    const size_t stride = std::max<size_t>(1, (total + limit - 1) / limit);
    for (const auto& [record, d] : views) {
      const Eigen::Matrix3d R = record->T_wc.rotation();
      const Eigen::Vector3d t = record->T_wc.translation();
      for (size_t i = 0; i < d->points.size(); i += stride) points->push_back(R * d->points[i].cast<double>() + t);
      cameras->push_back(t);
      if (back_planes && d->back_plane) {
        BackPlane w;
        w.n = R * d->back_plane->n;
        w.d = d->back_plane->d + w.n.dot(t);
        back_planes->push_back(w);
      }
    }
  }

  // Confirmation needs an ellipsoid where the observations' depth puts the object ("seen
  // consistently in space"): a box-plane fit from an early short baseline (a laptop as a
  // 4 m needle) waits for a better one. True where there is no depth evidence.
  bool agrees_with_depth(const MapObject& object) const {
    if (params.lifecycle.max_depth_disagreement <= 0.0) return true;
    std::vector<DepthEvidence> evidence;
    for (const ObjectObservation& o : object.observations) evidence.push_back(evidence_of(o));
    const double d = depth_disagreement(object.quadric, evidence);
    return !(d > params.lifecycle.max_depth_disagreement);
  }

  // The stand-out shares (object_surface.h stand_out_share) of the object's detections that can
  // tell, ascending.
  std::vector<double> stand_out_shares(const MapObject& object) const {
    std::vector<double> shares;
    for (const ObjectObservation& o : object.observations) {
      const KeyframeRecord::DetectionDepth* d = depth_record_of(o);
      if (d && std::isfinite(d->stand_out)) shares.push_back(d->stand_out);
    }
    std::sort(shares.begin(), shares.end());
    return shares;
  }

  // Whether the depth in the object's detection boxes stands out of the surface around them (the
  // median of `shares`, stand_out_shares, over the observations that can tell): a detector's
  // clutter on a wall or a table does not.
  bool stands_out(const std::vector<double>& shares) const {
    return !params.surface.enabled || shares.empty() || shares[shares.size() / 2] >= params.surface.min_stand_out;
  }

  // The depth's shape as evidence that the object exists, counted once per object (views of one
  // spot are not independent evidence of its shape): where more than half of its detections that
  // can tell (`shares`, stand_out_shares) stand clearly out of their surroundings
  // (ExistenceParams::clear_stand_out), the likelihood ratio of that under an object and under a
  // false alarm; 0 otherwise.
  double shape_log_odds(const std::vector<double>& shares) const {
    const ExistenceParams& e = params.lifecycle.existence;
    if (!params.surface.enabled || !(e.clear_stand_out < 1.0)) return 0.0;
    if (shares.empty() || shares[(shares.size() - 1) / 2] < e.clear_stand_out) return 0.0;
    return std::log(e.clear_stand_out_if_object / e.clear_stand_out_if_clutter);
  }

  // Whether the depth shows the object standing out of the surface it rests on (in a levelled
  // map): recurring clutter boxes on a table (a detector's "scissors" on a cable, a mark) have
  // nothing above the table's band, and are not confirmed. True where there is no such evidence.
  bool rises_from_support(const MapObject& object) const {
    if (!params.surface.enabled || !params.box_fit.upright || !object.has_quadric) return true;
    std::vector<Eigen::Vector3d> points, cameras;
    surface_of(object, params.surface.max_views, &points, &cameras);
    if (static_cast<int>(points.size()) < params.surface.min_points) return true;
    const SupportEstimate support = find_support(points, object.quadric, params.surface);
    if (support.found) {
      return 2 * static_cast<int>(object_points(points, object.quadric, support, params.surface).size()) >=
             params.surface.min_points;
    }
    // No support under it: still not an object if everything inside it is one flat horizontal
    // patch (a clutter box whose ellipsoid sank into the table it lies on).
    return !flat_patch(object_points(points, object.quadric, SupportEstimate(), params.surface), params.surface);
  }

  std::optional<BoxObservation> view_of(const ObjectObservation& o) const {
    const auto it = keyframes.find(o.keyframe_id);
    if (it == keyframes.end()) return std::nullopt;
    BoxObservation v;
    v.P = it->second.P;
    v.box = o.box;
    v.width = it->second.camera.width;
    v.height = it->second.camera.height;
    return v;
  }

  std::vector<BoxObservation> views_of(const MapObject& object, int max_views) const {
    std::vector<BoxObservation> views;
    for (const ObjectObservation& o : object.observations) {
      if (auto v = view_of(o)) views.push_back(*v);
    }
    if (max_views > 0 && static_cast<int>(views.size()) > max_views) {
      views.erase(views.begin(), views.end() - max_views);
    }
    return views;
  }

  // Box-plane initialisation once the object has enough views; until it succeeds the object keeps
  // its single-view ellipsoid (or none).
  void try_box_init(MapObject* object) const {
    if (object->from_boxes) return;
    if (static_cast<int>(object->observations.size()) < params.lifecycle.min_box_views) return;
    const std::vector<BoxObservation> views = views_of(*object, params.refinement.max_views);
    if (static_cast<int>(views.size()) < params.lifecycle.min_box_views) return;
    const QuadricInitResult r = initialise_from_boxes(views, params.lifecycle.box_init);
    if (!r.ok || !r.quadric.is_valid()) return;
    // Departure from METHOD.md §1 (LifecycleParams::max_depth_disagreement): a box-plane quadric
    // that the observations' depth contradicts does not replace an ellipsoid the depth agrees with
    // better; the object keeps that one (refined by the IoU loss) and tries again with more views.
    if (params.lifecycle.max_depth_disagreement > 0.0 && object->has_quadric) {
      std::vector<DepthEvidence> evidence;
      for (const ObjectObservation& o : object->observations) evidence.push_back(evidence_of(o));
      const double boxes = depth_disagreement(r.quadric, evidence);
      if (boxes > params.lifecycle.max_depth_disagreement &&
          boxes > depth_disagreement(object->quadric, evidence)) {
        return;
      }
    }
    // Box planes from a short baseline can collapse an axis (a bottle as a disc 2 mm thick, kept
    // only by min_axis_ratio): an axis under a tenth of the longest is refused where the object's
    // own depth points (inside its current ellipsoid) spread four times wider along it. A thin
    // object (a television, a picture) keeps its thin axis: its points are flat along it too.
    const Eigen::Vector3d& axes = r.quadric.semi_axes();
    int thin = 0;
    for (int k = 1; k < 3; ++k) {
      if (axes(k) < axes(thin)) thin = k;
    }
    if (object->has_quadric && axes(thin) < 0.1 * axes.maxCoeff()) {
      std::vector<Eigen::Vector3d> points, cameras;
      surface_of(*object, params.surface.max_views, &points, &cameras);
      const std::vector<Eigen::Vector3d> own = object_points(points, object->quadric, SupportEstimate(), params.surface);
      if (static_cast<int>(own.size()) >= params.surface.min_points &&
          trimmed_spread(own, r.quadric.rotation().col(thin), params.surface.trim_quantile) >
              8.0 * axes(thin)) {
        return;
      }
    }
    object->quadric = r.quadric;
    object->has_quadric = true;
    object->from_boxes = true;
  }

  // A detection associated with (or starting) `object`: its observation, class vote and the
  // belief that it exists. A confirmed object whose class mode changes is renamed (an event).
  void add_observation(MapObject* object, KeyFrameId keyframe_id, const Detection2d& d,
                       KeyFrameAssociation* out) const {
    ObjectObservation o;
    o.keyframe_id = keyframe_id;
    o.box = d.box;
    o.class_id = d.class_id;
    o.score = d.score;
    object->observations.push_back(o);
    ++object->observation_count;
    object->class_votes[d.class_id] += std::max(0.0, static_cast<double>(d.score));
    const bool renamed = update_class(object, params.labels.rename_margin);
    const auto name = class_names.find(object->class_id);
    if (name != class_names.end()) object->class_name = name->second;
    if (renamed && object->state == ObjectState::kConfirmed) {
      ObjectEvent e;
      e.type = ObjectEvent::Type::kRenamed;
      e.id = object->id;
      e.class_id = object->class_id;
      e.class_name = object->class_name;
      out->events.push_back(e);
    }
    object->existence = after_detection(object->existence, object->class_name, d.score, params.lifecycle.existence);
    object->missed = 0;
    object->last_keyframe = keyframe_id;
  }

  // What a keyframe says of a visible object it did not detect: nothing when the object touches
  // the image border (the filter drops boxes cut by it) or hides behind something nearer;
  // otherwise a miss, weighed by what the depth shows where the object should be.
  std::optional<MissKind> miss_of(const MapObject& object, const VisibleObject& v, const ObjectKeyFrame& kf) const {
    const PinholeCamera& cam = kf.camera;
    if (v.unclipped.touches_border(cam.width, cam.height, params.filter.border_margin_px)) return std::nullopt;
    const DepthEvidenceCounts n = depth_evidence(object.quadric, v.box, cam, kf.T_wc, kf.depth);
    const MissKind kind = classify_miss(n, params.lifecycle.existence);
    if (kind == MissKind::kOccluded) return std::nullopt;
    return kind;
  }

  void remove(ObjectId id, KeyFrameAssociation* out) {
    objects.erase(id);
    first_sequence.erase(id);
    out->events.push_back({ObjectEvent::Type::kRemoved, id, 0});
  }

  KeyFrameAssociation process(const ObjectKeyFrame& kf);
  void refine_seen(const std::set<ObjectId>& seen, KeyFrameAssociation* out);
};

ObjectMapper::ObjectMapper(const ObjectMapperParams& params, ObjectId first_id)
    : impl_(std::make_unique<Impl>()) {
  impl_->params = params;
  impl_->next_id = std::max<ObjectId>(1, first_id);
}

ObjectMapper::~ObjectMapper() = default;

KeyFrameAssociation ObjectMapper::process_keyframe(const ObjectKeyFrame& keyframe, std::string* error) {
  auto reject = [&](const std::string& message) {
    if (error) *error = "keyframe " + std::to_string(keyframe.id) + ": " + message;
    KeyFrameAssociation empty;
    empty.keyframe_id = keyframe.id;
    return empty;
  };
  if (impl_->keyframes.count(keyframe.id)) return reject("repeated keyframe ID; ignored");
  const PinholeCamera& cam = keyframe.camera;
  if (!(cam.fx > 0.0) || !(cam.fy > 0.0) || !std::isfinite(cam.cx) || !std::isfinite(cam.cy) ||
      cam.width <= 0 || cam.height <= 0) {
    return reject("invalid camera (focal lengths and image size must be positive)");
  }
  if (!finite_pose(keyframe.T_wc)) return reject("pose is not finite");
  if (keyframe.depth.data != nullptr &&
      (keyframe.depth.width != cam.width || keyframe.depth.height != cam.height)) {
    return reject("depth image size " + std::to_string(keyframe.depth.width) + "x" +
                  std::to_string(keyframe.depth.height) + " differs from the camera's " +
                  std::to_string(cam.width) + "x" + std::to_string(cam.height));
  }
  if (error) error->clear();
  return impl_->process(keyframe);
}

KeyFrameAssociation ObjectMapper::Impl::process(const ObjectKeyFrame& kf) {
  const auto t0 = Clock::now();
  KeyFrameAssociation out;
  out.keyframe_id = kf.id;
  const size_t n_in = kf.detections.size();
  out.verdicts.assign(n_in, DetectionVerdict::kInvalid);
  out.object_ids.assign(n_in, 0);

  std::set<ObjectId> confirmed_before;
  for (const auto& [id, o] : objects) {
    if (o.state == ObjectState::kConfirmed) confirmed_before.insert(id);
  }

  KeyframeRecord record;
  record.camera = kf.camera;
  record.T_wc = kf.T_wc;
  const SE3 T_cw = kf.T_wc.inverse();
  record.P = kf.camera.projection_matrix(T_cw);
  record.sequence = sequence++;
  for (const Detection2d& d : kf.detections) {
    if (!d.class_name.empty()) class_names[d.class_id] = d.class_name;
  }

  // 1. Filter.
  const FilteredDetections filtered =
      filter_detections(kf.detections, kf.camera.width, kf.camera.height, params.filter);
  std::vector<Detection2d> dets;
  for (size_t i = 0; i < n_in; ++i) {
    if (filtered.rejected[i]) out.verdicts[i] = *filtered.rejected[i];
  }
  for (const int i : filtered.kept) dets.push_back(kf.detections[static_cast<size_t>(i)]);
  // The detections' single-view depth ellipsoids: the fallback's initialisation of new objects,
  // the fine step's depth quadric, and (kept with the keyframe) the depth evidence of the
  // observations for the depth check of box-plane quadrics.
  std::vector<std::optional<DualQuadric>> det_depth(dets.size());
  if (kf.depth.data != nullptr) {
    const bool ellipsoids = params.lifecycle.single_view_fallback || params.lifecycle.max_depth_disagreement > 0.0;
    for (size_t d = 0; d < dets.size(); ++d) {
      KeyframeRecord::DetectionDepth rec;
      rec.box = dets[d].box;
      if (ellipsoids) {
        const QuadricInitResult r = initialise_from_depth(dets[d].box, kf.camera, kf.T_wc, kf.depth,
                                                          params.lifecycle.depth_init);
        if (r.ok && r.quadric.is_valid()) det_depth[d] = rec.ellipsoid = r.quadric;
      }
      if (params.surface.enabled) {
        rec.points = sample_box_points(rec.box, kf.camera, kf.depth, params.surface);
        const RingSurface ring = fit_ring_surface(ring_points(rec.box, kf.camera, kf.depth, params.surface), params.surface);
        rec.stand_out = stand_out_share(rec.points, ring, params.surface);
        if (params.surface.back_plane_max_angle_deg > 0.0) rec.back_plane = find_back_plane(rec.points, ring, params.surface);
      }
      record.detections.push_back(std::move(rec));
    }
  }

  keyframes[kf.id] = record;

  // 2. Visibility of the objects with an ellipsoid; candidates without one by their last box.
  std::vector<MapObject*> with_quadric;
  std::vector<const DualQuadric*> quadrics;
  std::vector<AssociationTrack> tracks;
  std::vector<MapObject*> track_objects;
  for (auto& [id, o] : objects) {
    if (o.has_quadric) {
      with_quadric.push_back(&o);
      quadrics.push_back(&o.quadric);
    } else if (!o.observations.empty()) {
      tracks.push_back({&o, o.observations.back().box});
      track_objects.push_back(&o);
    }
  }
  const std::vector<VisibleObject> visible =
      visible_objects(quadrics, kf.camera, T_cw, params.visibility);
  for (const VisibleObject& v : visible) {
    tracks.push_back({with_quadric[static_cast<size_t>(v.index)], v.box});
    track_objects.push_back(with_quadric[static_cast<size_t>(v.index)]);
  }

  // 3–4. Coarse and fine association, one-to-one.
  AssociationFrame frame;
  frame.camera = &kf.camera;
  frame.T_wc = kf.T_wc;
  frame.P = record.P;
  frame.depth = kf.depth;
  frame.detection_depth = &det_depth;
  frame.depth_lookup = [this](const ObjectObservation& o) { return evidence_of(o); };
  const ViewLookup lookup = [this](const ObjectObservation& o) { return view_of(o); };
  const AssociationResult assoc =
      associate(tracks, dets, frame, lookup, params.association, params.lifecycle);

  std::vector<ObjectId> det_object(dets.size(), 0);
  std::set<ObjectId> seen;
  for (size_t t = 0; t < tracks.size(); ++t) {
    const int d = assoc.track_to_detection[t];
    if (d < 0) continue;
    MapObject* o = track_objects[t];
    add_observation(o, kf.id, dets[static_cast<size_t>(d)], &out);
    det_object[static_cast<size_t>(d)] = o->id;
    out.verdicts[static_cast<size_t>(filtered.kept[static_cast<size_t>(d)])] = DetectionVerdict::kAssociated;
    seen.insert(o->id);
  }
  // Misses: visible objects that took no detection.
  size_t first_visible_track = tracks.size() - visible.size();
  for (size_t k = 0; k < visible.size(); ++k) {
    const size_t t = first_visible_track + k;
    if (assoc.track_to_detection[t] >= 0) continue;
    MapObject* o = track_objects[t];
    if (auto kind = miss_of(*o, visible[k], kf)) {
      // A detection covering it (most of its projected box) that another object took explains the
      // surface the depth shows there: a duplicate, or clutter boxes on a larger object, decays.
      if (*kind == MissKind::kSupported) {
        for (size_t d = 0; d < dets.size(); ++d) {
          if (det_object[d] != 0 && det_object[d] != o->id &&
              overlap_ratio(dets[d].box, visible[k].box) >= params.merge.min_overlap) {
            kind = MissKind::kExplained;
            break;
          }
        }
      }
      ++o->missed;
      o->existence = after_miss(o->existence, *kind, o->class_name, params.lifecycle.existence);
    }
  }

  // 6. Unmatched detections start candidates.
  for (size_t d = 0; d < dets.size(); ++d) {
    if (det_object[d] != 0) continue;
    const size_t input = static_cast<size_t>(filtered.kept[d]);
    MapObject o;
    if (kf.depth.data != nullptr && params.lifecycle.single_view_fallback) {
      if (!det_depth[d]) {
        out.verdicts[input] = DetectionVerdict::kNoInit;
        continue;
      }
      o.quadric = *det_depth[d];
      o.has_quadric = true;
    }
    o.id = next_id++;
    o.state = ObjectState::kCandidate;
    o.first_keyframe = kf.id;
    o.existence = logit(params.lifecycle.existence.prior);
    add_observation(&o, kf.id, dets[d], &out);
    det_object[d] = o.id;
    out.verdicts[input] = DetectionVerdict::kNewObject;
    out.events.push_back({ObjectEvent::Type::kCreated, o.id, 0});
    first_sequence[o.id] = record.sequence;
    seen.insert(o.id);
    objects.emplace(o.id, std::move(o));
  }

  // Box-plane initialisation and confirmation of the objects seen.
  const double confirm_log_odds = logit(params.lifecycle.existence.confirm_probability);
  for (const ObjectId id : seen) {
    MapObject& o = objects.at(id);
    try_box_init(&o);
    if (o.state != ObjectState::kCandidate || !o.has_quadric) continue;
    // The depth's shape joins the belief once, when the candidate is confirmed with it.
    const std::vector<double> shares = stand_out_shares(o);
    const double shape = shape_log_odds(shares);
    if (o.existence + shape >= confirm_log_odds && agrees_with_depth(o) && stands_out(shares) && rises_from_support(o)) {
      o.existence = std::min(o.existence + shape, params.lifecycle.existence.max_log_odds);
      o.state = ObjectState::kConfirmed;
    }
  }

  // 5. Occlusion merge among the objects this keyframe sees (with their updated ellipsoids).
  if (params.merge.enabled) {
    std::vector<const MapObject*> pool;
    std::vector<const DualQuadric*> pool_quadrics;
    for (const auto& [id, o] : objects) {
      if (!o.has_quadric) continue;
      pool.push_back(&o);
      pool_quadrics.push_back(&o.quadric);
    }
    VisibilityParams merge_visibility = params.visibility;
    merge_visibility.occlusion_iou = 1.1;  // keep both of two overlapping objects: they may be one
    const std::vector<VisibleObject> in_view =
        visible_objects(pool_quadrics, kf.camera, T_cw, merge_visibility);
    const std::vector<MergePair> merges = find_merges(pool, in_view, params.merge);
    for (const MergePair& m : merges) {
      const ObjectId from = pool[static_cast<size_t>(m.from)]->id;
      const ObjectId into = pool[static_cast<size_t>(m.into)]->id;
      MapObject& target = objects.at(into);
      merge_object_into(objects.at(from), &target, params.labels.rename_margin);
      try_box_init(&target);
      objects.erase(from);
      first_sequence.erase(from);
      out.events.push_back({ObjectEvent::Type::kMerged, from, into});
      for (ObjectId& id : det_object) {
        if (id == from) id = into;
      }
      if (seen.erase(from)) seen.insert(into);
    }
  }

  // Removal: objects whose belief fell to remove_probability, and candidates not confirmed in time.
  const double remove_log_odds = logit(params.lifecycle.existence.remove_probability);
  std::vector<ObjectId> to_remove;
  for (const auto& [id, o] : objects) {
    const uint64_t age = record.sequence - first_sequence[id];
    const bool expired = o.state == ObjectState::kCandidate && !seen.count(id) &&
                         static_cast<int64_t>(age) >= params.lifecycle.existence.candidate_max_age_keyframes;
    if (o.existence <= remove_log_odds || expired) to_remove.push_back(id);
  }
  for (const ObjectId id : to_remove) remove(id, &out);

  for (size_t d = 0; d < dets.size(); ++d) {
    out.filtered.push_back(dets[d]);
    out.filtered_source.push_back(filtered.kept[d]);
    const ObjectId id = objects.count(det_object[d]) ? det_object[d] : 0;
    out.filtered_object_ids.push_back(id);
    out.object_ids[static_cast<size_t>(filtered.kept[d])] = id;
  }
  out.association_ms = ms_since(t0);
  // Confirmed here: by enough observations, or by a merge with a confirmed object.
  for (const auto& [id, o] : objects) {
    if (o.state == ObjectState::kConfirmed && !confirmed_before.count(id)) out.confirmed.push_back(id);
  }

  // 7. Refinement of the objects seen, over every keyframe that saw them, and their boxes.
  refine_seen(seen, &out);
  return out;
}

void ObjectMapper::Impl::refine_seen(const std::set<ObjectId>& seen, KeyFrameAssociation* out) {
  const auto t0 = Clock::now();
  // The object's own surface (object_surface.h): in a levelled map, the support it rests on gives
  // the refinement its priors and the box its bottom.
  struct Surface {
    std::vector<Eigen::Vector3d> points, cameras;
    std::vector<BackPlane> back_planes;
    SupportEstimate support;
  };
  std::map<ObjectId, Surface> surfaces;
  const bool levelled = params.box_fit.upright;
  for (const ObjectId id : seen) {
    const auto it = objects.find(id);
    if (!params.surface.enabled || it == objects.end() || !it->second.has_quadric) continue;
    Surface& s = surfaces[id];
    surface_of(it->second, params.surface.max_views, &s.points, &s.cameras, &s.back_planes);
    if (levelled) s.support = find_support(s.points, it->second.quadric, params.surface);
  }
  for (const ObjectId id : seen) {
    if (!params.refine) break;
    const auto it = objects.find(id);
    if (it == objects.end() || !it->second.has_quadric) continue;
    MapObject& o = it->second;
    const std::vector<BoxObservation> views = views_of(o, params.refinement.max_views);
    if (static_cast<int>(views.size()) < std::max(1, params.refinement.min_views)) continue;
    RefinementPriors priors;
    const auto s = surfaces.find(id);
    if (levelled && s != surfaces.end() && s->second.support.found) {
      priors.upright = true;
      priors.upright_weight = params.surface.upright_weight;
      priors.on_support = true;
      priors.support_z = s->second.support.z;
      priors.support_weight = params.surface.support_weight;
      priors.support_scale = params.surface.support_scale;
    }
    const RefinementResult r = refine_quadric(o.quadric, views, params.refinement, priors);
    KeyFrameAssociation::Refinement entry;
    entry.id = id;
    entry.ok = r.ok && r.quadric.is_valid();
    // Boxes alone leave an ellipsoid free to slide along the rays (farther and larger fits the
    // same boxes): a refinement that leaves most of the object's own depth points outside is
    // refused (room: a duplicate slid 3.8 m through a wall).
    if (entry.ok && s != surfaces.end()) {
      const SupportEstimate& support = s->second.support;
      const size_t before = object_points(s->second.points, o.quadric, support, params.surface).size();
      if (static_cast<int>(before) >= params.surface.min_points &&
          2 * object_points(s->second.points, r.quadric, support, params.surface).size() < before) {
        entry.ok = false;
      }
    }
    entry.views = r.views_used;
    entry.ms = r.time_ms;
    out->refinements.push_back(entry);
    if (entry.ok) {
      o.quadric = r.quadric;
      ++out->refined_objects;
    }
  }
  out->refinement_ms = ms_since(t0);
  if (!params.box_fit.enabled) return;
  const auto t1 = Clock::now();
  for (const ObjectId id : seen) {
    const auto it = objects.find(id);
    if (it == objects.end() || !it->second.has_quadric) continue;
    MapObject& o = it->second;
    const BoxFitResult b = fit_box(o.quadric, views_of(o, params.box_fit.max_views), params.box_fit);
    // Only where the box explains the detections better than the ellipsoid (box_fit.h).
    o.has_box = b.ok && b.better_than_ellipsoid;
    if (o.has_box) o.box = b.box;
    // The surface box: the points where keyframes looked, the detections' box where none did.
    const auto s = surfaces.find(id);
    if (!levelled || s == surfaces.end()) continue;
    const OrientedBox detections_box = o.has_box ? o.box : box_from_quadric(o.quadric);
    const std::vector<Eigen::Vector3d> own = object_points(s->second.points, o.quadric, s->second.support, params.surface);
    const SurfaceBoxResult sb = fit_surface_box(own, upright_box(detections_box), s->second.cameras, s->second.support,
                                                params.surface, s->second.back_planes);
    // A box much thinner than the detections' in any direction comes from an ellipsoid that cut
    // the points to a sliver: the detections' box stays. A face a plane behind the object held
    // is thin for a reason (a clock on its wall): such an axis is not compared.
    const Eigen::Vector3d sorted_box = sorted(sb.box.half_extents), sorted_det = sorted(detections_box.half_extents);
    const bool no_sliver = sb.faces_from_back_planes > 0
                               ? sb.min_extent_ratio >= params.surface.min_extent_ratio
                               : (sorted_box.array() >= params.surface.min_extent_ratio * sorted_det.array()).all();
    if (sb.ok && no_sliver) {
      o.box = sb.box;
      o.has_box = true;
    }
  }
  out->box_fit_ms = ms_since(t1);
}

int ObjectMapper::update_keyframe_poses(const std::map<KeyFrameId, SE3>& T_wc_by_id) {
  int known = 0;
  for (const auto& [id, T_wc] : T_wc_by_id) {
    const auto it = impl_->keyframes.find(id);
    if (it == impl_->keyframes.end() || !finite_pose(T_wc)) continue;
    it->second.T_wc = T_wc;
    it->second.P = it->second.camera.projection_matrix(T_wc.inverse());
    ++known;
  }
  return known;
}

std::vector<MapObject> ObjectMapper::objects(bool include_candidates) const {
  std::vector<MapObject> out;
  for (const auto& [id, o] : impl_->objects) {
    if (include_candidates || o.state == ObjectState::kConfirmed) out.push_back(o);
  }
  return out;
}

const MapObject* ObjectMapper::find(ObjectId id) const {
  const auto it = impl_->objects.find(id);
  return it == impl_->objects.end() ? nullptr : &it->second;
}

ObjectId ObjectMapper::next_id() const { return impl_->next_id; }

const std::map<int, std::string>& ObjectMapper::class_names() const { return impl_->class_names; }

const ObjectMapperParams& ObjectMapper::params() const { return impl_->params; }

bool ObjectMapper::save_state(const std::string& path, std::string* error) const {
  return write_state_file(path, impl_->objects, impl_->next_id, impl_->map_id, error);
}

bool ObjectMapper::load_state(const std::string& path, std::string* error) {
  std::map<ObjectId, MapObject> loaded;
  ObjectId next = 1;
  std::string map_id;
  if (!read_state_file(path, &loaded, &next, &map_id, error)) return false;
  impl_->map_id = map_id;
  // Never hand out an ID again that this mapper or the file has given.
  impl_->next_id = std::max(impl_->next_id, next);
  impl_->objects = std::move(loaded);
  impl_->first_sequence.clear();
  for (const auto& [id, o] : impl_->objects) impl_->first_sequence[id] = impl_->sequence;
  return true;
}

void ObjectMapper::set_map_id(const std::string& map_id) { impl_->map_id = map_id; }

const std::string& ObjectMapper::map_id() const { return impl_->map_id; }

std::vector<ObjectEvent> ObjectMapper::drop_objects() {
  std::vector<ObjectEvent> events;
  for (const auto& [id, o] : impl_->objects) events.push_back({ObjectEvent::Type::kRemoved, id, 0});
  impl_->objects.clear();
  impl_->first_sequence.clear();
  impl_->keyframes.clear();
  return events;
}

}  // namespace dqo::objects
