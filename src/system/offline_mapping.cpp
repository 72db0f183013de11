#include "dqo_map/system/offline_mapping.h"

#include <algorithm>
#include <chrono>
#include <future>
#include <limits>

namespace dqo::system {
namespace {

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

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
  std::map<uint32_t, const GtObject*> gt;
  for (const GtObject& o : info.objects) {
    gt[o.id] = &o;
    out.objects.push_back(object_record_from_box(o.id, o.class_id, o.class_name, o.box));
  }
  const InstanceImage& ins = frame.instance;
  if (ins.empty()) {
    out.ms = ms_since(t0);
    return out;
  }
  // Boxes of each ID's pixels (continuous coordinates: pixel u covers [u − ½, u + ½]).
  struct Extent {
    int u0 = std::numeric_limits<int>::max(), v0 = std::numeric_limits<int>::max(), u1 = -1, v1 = -1;
  };
  std::map<uint16_t, Extent> extents;
  for (int v = 0; v < ins.height; ++v) {
    for (int u = 0; u < ins.width; ++u) {
      const uint16_t id = ins.at(u, v);
      if (id == 0) continue;
      Extent& e = extents[id];
      e.u0 = std::min(e.u0, u);
      e.v0 = std::min(e.v0, v);
      e.u1 = std::max(e.u1, u);
      e.v1 = std::max(e.v1, v);
    }
  }
  std::map<uint16_t, uint16_t> index;  // object ID -> detection index + 1
  for (const auto& [id, e] : extents) {
    Detection2d d;
    const auto it = gt.find(id);
    if (it != gt.end()) {
      d.class_id = it->second->class_id;
      d.class_name = it->second->class_name;
    }
    d.score = 1.f;
    d.box.x_min = e.u0 - 0.5;
    d.box.y_min = e.v0 - 0.5;
    d.box.x_max = e.u1 + 0.5;
    d.box.y_max = e.v1 + 0.5;
    d.gt_id = id;
    out.keyframe_objects.detections.push_back(d);
    out.keyframe_objects.object_ids.push_back(id);
    index[id] = static_cast<uint16_t>(out.keyframe_objects.detections.size());
  }
  InstanceImage renumbered(ins.width, ins.height, 1, 0);
  for (size_t p = 0; p < ins.data.size(); ++p) {
    if (ins.data[p] != 0) renumbered.data[p] = index[ins.data[p]];
  }
  out.keyframe_objects.instance = std::move(renumbered);
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
    if (!pose.T_wc) {
      ++result.frames_without_pose;
      if (progress) progress(n + 1, total);
      continue;
    }
    result.trajectory.emplace_back(frame->timestamp, *pose.T_wc);

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
      result.timings.objects_ms.push_back(objects.ms);
      std::string error;
      if (!mapper->add_keyframe(std::move(kf), &error)) {
        ++result.rejected_keyframes;
        result.warnings.push_back(error);
      } else {
        ++result.keyframes;
        for (const mapping::MappingEvent& e : objects.events) mapper->apply_event(e);
        mapper->set_objects(std::move(objects.objects));
        if (!mapper->add_keyframe_objects(std::move(objects.keyframe_objects), &error)) {
          result.warnings.push_back(error);
        }
      }
    }
    if (stages.corrected_poses) {
      const auto corrected = stages.corrected_poses();
      if (!corrected.empty()) mapper->set_keyframe_poses(corrected);
    }
    while (auto report = mapper->process_next()) {
      result.timings.mapping_ms.push_back(report->total_ms);
      result.reports.push_back(std::move(*report));
    }
    if (progress) progress(n + 1, total);
  }
  mapper->flush();
  while (auto report = mapper->process_next()) {
    result.timings.mapping_ms.push_back(report->total_ms);
    result.reports.push_back(std::move(*report));
  }
  result.ok = result.error.empty();
  result.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return result;
}

}  // namespace dqo::system
