#include "dqo_map/system/offline_stages.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "dqo_map/common/mask_detections.h"
#include "dqo_map/common/stopwatch.h"
#include "dqo_map/tracking/tracking_session.h"
#include "trajectory_anchor.h"

namespace dqo::system {
namespace {

mapping::MappingEvent to_mapping_event(const objects::ObjectEvent& e) {
  mapping::MappingEvent m;
  switch (e.type) {
    case objects::ObjectEvent::Type::kCreated:
      m.type = mapping::MappingEvent::Type::kCreated;
      break;
    case objects::ObjectEvent::Type::kMerged:
      m.type = mapping::MappingEvent::Type::kMerged;
      break;
    case objects::ObjectEvent::Type::kRemoved:
      m.type = mapping::MappingEvent::Type::kRemoved;
      break;
    case objects::ObjectEvent::Type::kRenamed:  // nothing for the Gaussians: callers skip it
      break;
  }
  m.id = e.id;
  m.into_id = e.into_id;
  return m;
}

}  // namespace

void add_tracking_stage(const tracking::TrackingConfig& config, const PinholeCamera& camera,
                        bool anchor, OfflineStages* stages) {
  // Offline: the same output for the same input on any machine load.
  tracking::TrackingConfig offline = config;
  offline.tracker.local_ba.deterministic = true;
  auto session = std::make_shared<tracking::TrackingSession>(offline);
  auto anchors = std::make_shared<TrajectoryAnchor>(anchor);
  stages->pose = [session, anchors, camera](const Frame& frame) {
    const auto t0 = std::chrono::steady_clock::now();
    FramePose out;
    const tracking::RgbdInput input{frame.timestamp, &frame.rgb, &frame.depth,
                                    frame.depth_timestamp};
    const tracking::SessionResult r = session->track(camera, input);
    out.ms = ms_since(t0);
    out.state = r.skipped != tracking::SessionResult::Skip::kNone ? "skipped"
                                                                  : tracking::to_string(r.track.state);
    if (session->tracker() != nullptr) out.object_costs = session->tracker()->object_costs_applied();
    if (r.skipped != tracking::SessionResult::Skip::kNone ||
        !tracking::has_pose(r.track.state)) {
      return out;
    }
    out.T_wc = anchors->apply(frame, r.track.T_wc);
    if (out.T_wc && r.keyframe_id) out.keyframe = *r.keyframe_id;
    return out;
  };
  stages->corrected_poses = [session, anchors]() {
    std::map<mapping::KeyframeId, SE3> out;
    for (const tracking::CorrectedPose& c : session->corrected_keyframes()) {
      out[c.id] = anchors->apply(c.T_wc);
    }
    return out;
  };
  stages->object_feedback = nullptr;
  if (offline.tracker.objects.enabled) {
    stages->object_feedback = [session, anchors](const ObjectStageOutput& objects) {
      // The objects were built on anchored poses: back into the tracker's world.
      const SE3 T_est_gt = anchors->T_gt_est().inverse();
      session->set_object_landmarks(object_landmarks(objects.objects, T_est_gt));
      session->add_object_sightings(objects.keyframe_objects.keyframe_id,
                                    object_sightings(objects.keyframe_objects));
    };
  }
}

std::vector<tracking::ObjectLandmark> object_landmarks(const std::vector<mapping::ObjectRecord>& objects,
                                                       const SE3& T_tracker_world) {
  std::vector<tracking::ObjectLandmark> out;
  out.reserve(objects.size());
  for (const mapping::ObjectRecord& o : objects) {
    tracking::ObjectLandmark l;
    l.id = o.id;
    l.quadric = o.quadric.transformed(T_tracker_world);
    l.confirmed = true;  // the object stage's records are its confirmed objects (to_object_records)
    l.confidence = o.confidence;
    l.observations = o.observations;
    out.push_back(l);
  }
  return out;
}

std::vector<tracking::ObjectSighting> object_sightings(const mapping::KeyframeObjects& keyframe) {
  std::vector<tracking::ObjectSighting> out;
  const size_t n = std::min(keyframe.detections.size(), keyframe.object_ids.size());
  for (size_t i = 0; i < n; ++i) {
    if (keyframe.object_ids[i] == 0) continue;
    out.push_back({keyframe.object_ids[i], keyframe.detections[i].box, keyframe.detections[i].score});
  }
  return out;
}

void add_trajectory_stage(Trajectory trajectory, const PoseLookupParams& lookup,
                          const KeyframeSelectorParams& keyframes, bool anchor,
                          OfflineStages* stages) {
  std::stable_sort(trajectory.begin(), trajectory.end(),
                   [](const TimedPose& a, const TimedPose& b) { return a.first < b.first; });
  auto sorted = std::make_shared<Trajectory>(std::move(trajectory));
  auto selector = std::make_shared<KeyframeSelector>(keyframes);
  auto anchors = std::make_shared<TrajectoryAnchor>(anchor);
  auto next_id = std::make_shared<mapping::KeyframeId>(1);
  stages->pose = [sorted, lookup, selector, anchors, next_id](const Frame& frame) {
    FramePose out;
    out.T_wc = anchors->apply(frame, pose_at(*sorted, frame.timestamp, lookup));
    if (out.T_wc && selector->consider(*out.T_wc)) out.keyframe = (*next_id)++;
    return out;
  };
  stages->corrected_poses = nullptr;
}

std::vector<mapping::ObjectRecord> to_object_records(
    const std::vector<objects::MapObject>& objects) {
  std::vector<mapping::ObjectRecord> out;
  for (const objects::MapObject& o : objects) {
    if (!o.has_quadric) continue;
    mapping::ObjectRecord r;
    r.id = o.id;
    r.class_id = o.class_id;
    r.class_name = o.class_name;
    r.quadric = o.quadric;
    r.box = o.has_box ? o.box
                      : OrientedBox{o.quadric.centre(), o.quadric.rotation(), o.quadric.semi_axes()};
    r.observations = o.observation_count;
    r.confidence = o.confidence;
    out.push_back(std::move(r));
  }
  return out;
}

std::shared_ptr<objects::ObjectMapper> add_object_stage(const objects::ObjectMapperParams& params,
                                                        DetectionSource detections,
                                                        LabelSource labels,
                                                        const DatasetInfo& info,
                                                        OfflineStages* stages,
                                                        FrameDetector detector,
                                                        ObjectStageObserver observer) {
  if (detections == DetectionSource::kDetector && !detector) {
    throw std::invalid_argument("add_object_stage: DetectionSource::kDetector needs a detector");
  }
  auto mapper = std::make_shared<objects::ObjectMapper>(params);
  // Mask labels are ground-truth object IDs: their classes come from the ground truth.
  MaskDetectionParams mask_params;
  mask_params.default_class = {0, "object"};
  for (const GtObject& o : info.objects) mask_params.classes[o.id] = {o.class_id, o.class_name};
  stages->objects = [mapper, detections, labels, mask_params, detector, observer](const mapping::MappingKeyframe& kf,
                                                   const Frame& frame) {
    const auto t0 = std::chrono::steady_clock::now();
    objects::ObjectKeyFrame okf;
    okf.id = kf.id;
    okf.stamp = kf.stamp;
    okf.camera = kf.camera;
    okf.T_wc = kf.T_wc;
    okf.depth.data = kf.depth.data.data();
    okf.depth.width = kf.depth.width;
    okf.depth.height = kf.depth.height;
    InstanceImage detector_instance;  // k+1 = input detection k (mask detections, segmenting detectors)
    if (detections == DetectionSource::kMasks) {
      MaskDetections md = detections_from_mask(mask_labels(frame.instance), mask_params);
      okf.detections = std::move(md.detections);
      detector_instance = std::move(md.instance);
    } else if (detections == DetectionSource::kDetector) {
      FrameDetections d = detector(frame);
      okf.detections = std::move(d.detections);
      detector_instance = std::move(d.instance);
    } else {
      okf.detections = frame.detections;
    }
    std::string error;
    const objects::KeyFrameAssociation r = mapper->process_keyframe(okf, &error);
    ObjectStageOutput out;
    out.keyframe_objects.keyframe_id = kf.id;
    out.keyframe_objects.detections = r.filtered;
    out.keyframe_objects.object_ids.assign(r.filtered_object_ids.begin(),
                                           r.filtered_object_ids.end());
    if (labels == LabelSource::kMasks && detections == DetectionSource::kDetector) {
      // The detector's own masks (a box-only model has none: its pixels go unlabelled).
      if (!detector_instance.empty())
        out.keyframe_objects.instance = objects::renumber_instance(detector_instance, r.filtered_source);
    } else if (labels == LabelSource::kMasks && !frame.instance.empty()) {
      out.keyframe_objects.instance =
          detector_instance.empty()
              ? instance_for_detections(frame.instance, r.filtered)
              : objects::renumber_instance(detector_instance, r.filtered_source);
    }
    for (const objects::ObjectEvent& e : r.events) {
      if (e.type != objects::ObjectEvent::Type::kRenamed) out.events.push_back(to_mapping_event(e));
    }
    out.objects = to_object_records(mapper->objects());
    out.ms = ms_since(t0);  // the stage's own time: an observer's (drawing, writing) is not counted
    if (observer) observer(ObjectStageView{kf, okf.detections, r, mapper->objects(true)});
    return out;
  };
  return mapper;
}

}  // namespace dqo::system
