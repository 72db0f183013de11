#include "dqo_map/system/offline_mapping.h"

#include <algorithm>
#include <chrono>
#include <future>
#include <vector>

#include "dqo_map/common/mask_detections.h"
#include "dqo_map/common/stopwatch.h"
#include "mapping_thread.h"

namespace dqo::system {
mapping::ObjectRecord object_record_from_box(uint64_t id, int class_id,
                                             const std::string& class_name,
                                             const OrientedBox& box) {
  mapping::ObjectRecord r;
  r.id = id;
  r.class_id = class_id;
  r.class_name = class_name;
  r.quadric = DualQuadric::from_params(box.centre, box.rotation, box.half_extents);
  r.box = box;
  r.observations = 1;
  r.confidence = 1.0;
  return r;
}

ObjectStageOutput ground_truth_objects(const Frame& frame, const DatasetInfo& info) {
  ObjectStageOutput out;
  const auto t0 = std::chrono::steady_clock::now();
  MaskDetectionParams mask;
  mask.min_pixels = 1;           // ground truth: every visible pixel counts
  mask.default_class = {0, ""};  // an ID without a ground-truth object
  for (const GtObject& o : info.objects) {
    out.objects.push_back(object_record_from_box(o.id, o.class_id, o.class_name, o.box));
    mask.classes[o.id] = {o.class_id, o.class_name};
  }
  if (!frame.instance.empty()) {
    MaskDetections md = detections_from_mask(mask_labels(frame.instance), mask);
    for (size_t k = 0; k < md.detections.size(); ++k) md.detections[k].gt_id = md.labels[k];
    out.keyframe_objects.detections = std::move(md.detections);
    out.keyframe_objects.object_ids.assign(md.labels.begin(), md.labels.end());
    out.keyframe_objects.instance = std::move(md.instance);
  }
  out.ms = ms_since(t0);
  return out;
}

OfflineResult run_offline_mapping(const FrameSource& source, const OfflineStages& stages,
                                  const OfflineMappingParams& params,
                                  mapping::GaussianMapper* mapper,
                                  const OfflineProgress& progress) {
  const auto t_start = std::chrono::steady_clock::now();
  OfflineResult result;
  const int every = std::max(1, params.every);
  std::vector<int> frames;
  for (int i = 0; i < source.num_frames(); i += every) {
    if (params.max_frames >= 0 && static_cast<int>(frames.size()) >= params.max_frames) break;
    frames.push_back(i);
  }
  const int total = static_cast<int>(frames.size());
  KeyframeSelector selector(params.keyframes);
  mapping::KeyframeId next_keyframe = 1;

  // Reading (PNG decoding, or rendering) of the next frame overlaps the work on this one.
  auto read = [&source](int i) {
    return std::async(std::launch::async, [&source, i] {
      const auto t0 = std::chrono::steady_clock::now();
      std::string e;
      auto frame = source.read_frame(i, &e);
      return std::make_tuple(std::move(frame), e, ms_since(t0));
    });
  };
  MappingThread mapping_thread(mapper, params.mapping_thread);
  decltype(read(0)) next;
  if (total > 0) next = read(frames[0]);
  for (int n = 0; n < total; ++n) {
    auto [frame, read_error, read_ms] = next.get();
    if (n + 1 < total) next = read(frames[n + 1]);
    if (!frame) {
      result.error = "frame " + std::to_string(frames[n]) + ": " + read_error;
      break;
    }
    ++result.frames;
    result.timings.read_ms.push_back(read_ms);
    if (frame->has_pose) result.ground_truth.emplace_back(frame->timestamp, frame->T_wc);

    FramePose pose;
    if (stages.pose) {
      pose = stages.pose(*frame);
    } else if (frame->has_pose) {
      pose.T_wc = frame->T_wc;
      if (selector.consider(frame->T_wc)) pose.keyframe = next_keyframe++;
    }
    result.timings.pose_ms.push_back(pose.ms);
    if (!pose.state.empty()) result.states.emplace_back(frame->timestamp, pose.state);
    result.object_costs = std::max(result.object_costs, pose.object_costs);
    if (!pose.T_wc) {
      ++result.frames_without_pose;
      if (progress) progress(n + 1, total);
      continue;
    }
    result.trajectory.emplace_back(frame->timestamp, *pose.T_wc);

    MappingThread::Work keyframe_work;
    if (pose.keyframe) {
      mapping::MappingKeyframe kf;
      kf.id = *pose.keyframe;
      kf.stamp = frame->timestamp;
      kf.camera = source.info().camera;
      kf.T_wc = *pose.T_wc;
      kf.rgb = frame->rgb;
      kf.depth = frame->depth;
      ObjectStageOutput objects = stages.objects ? stages.objects(kf, *frame)
                                                 : ground_truth_objects(*frame, source.info());
      objects.keyframe_objects.keyframe_id = kf.id;
      if (stages.objects && stages.object_feedback) stages.object_feedback(objects);
      result.timings.objects_ms.push_back(objects.ms);
      // In the order the ROS nodes publish: the keyframe, its events, the objects, its objects.
      keyframe_work = [kf = std::move(kf), objects = std::move(objects)](
                          mapping::GaussianMapper& m, std::vector<std::string>* warnings) mutable {
        std::string error;
        if (!m.add_keyframe(std::move(kf), &error)) {
          warnings->push_back(error);
          return false;
        }
        for (const mapping::MappingEvent& e : objects.events) m.apply_event(e);
        m.set_objects(std::move(objects.objects));
        if (!m.add_keyframe_objects(std::move(objects.keyframe_objects), &error)) warnings->push_back(error);
        return true;
      };
    }
    std::map<mapping::KeyframeId, SE3> corrected;
    if (stages.corrected_poses) corrected = stages.corrected_poses();
    // The frame's keyframe and corrections as one piece of work: the mapper maps what became
    // ready after both, as the single-threaded loop did.
    if (keyframe_work || !corrected.empty()) {
      const bool is_keyframe = static_cast<bool>(keyframe_work);
      mapping_thread.post(
          [work = std::move(keyframe_work), corrected = std::move(corrected)](
              mapping::GaussianMapper& m, std::vector<std::string>* warnings) mutable {
            const bool accepted = !work || work(m, warnings);
            if (!corrected.empty()) m.set_keyframe_poses(corrected);
            return accepted;
          },
          is_keyframe);
    }
    if (progress) progress(n + 1, total);
  }
  MappingThread::Outcome mapped = mapping_thread.finish();
  result.keyframes = mapped.keyframes;
  result.rejected_keyframes = mapped.rejected_keyframes;
  for (std::string& w : mapped.warnings) result.warnings.push_back(std::move(w));
  for (mapping::MappingReport& report : mapped.reports) {
    result.timings.mapping_ms.push_back(report.total_ms);
    result.reports.push_back(std::move(report));
  }
  result.ok = result.error.empty();
  result.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return result;
}

}  // namespace dqo::system
