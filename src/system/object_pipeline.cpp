#include "dqo_map/system/object_pipeline.h"

#include <algorithm>
#include <chrono>
#include <future>
#include <utility>

#include "trajectory_anchor.h"

namespace dqo::system {

ObjectPipelineResult run_object_pipeline(const FrameSource& reader, const ObjectPipelineParams& params,
                                         const Trajectory* trajectory, const ProgressCallback& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  ObjectPipelineResult result;
  result.camera = reader.info().camera;
  const int total = params.max_frames >= 0 ? std::min(params.max_frames, reader.num_frames())
                                           : reader.num_frames();
  Trajectory sorted;
  if (trajectory) {
    sorted = *trajectory;
    std::stable_sort(sorted.begin(), sorted.end(),
                     [](const TimedPose& a, const TimedPose& b) { return a.first < b.first; });
  }
  objects::ObjectMapper mapper(params.mapper);
  KeyframeSelector selector(params.keyframes);
  // Reading (PNG decoding) of frame i + 1 overlaps the mapping of frame i.
  auto read = [&reader](int i) {
    return std::async(std::launch::async, [&reader, i] {
      std::string e;
      auto frame = reader.read_frame(i, &e);
      return std::make_pair(std::move(frame), e);
    });
  };
  TrajectoryAnchor anchor(params.anchor_to_ground_truth);
  std::future<std::pair<std::optional<Frame>, std::string>> next;
  if (total > 0) next = read(0);
  for (int i = 0; i < total; ++i) {
    auto [frame, read_error] = next.get();
    if (i + 1 < total) next = read(i + 1);
    if (!frame) {
      result.error = "frame " + std::to_string(i) + ": " + read_error;
      break;
    }
    ++result.frames;
    std::optional<SE3> T_wc;
    if (trajectory) {
      T_wc = anchor.apply(*frame, pose_at(sorted, frame->timestamp, params.pose_lookup));
      result.anchored = anchor.anchored();
    } else if (frame->has_pose) {
      T_wc = frame->T_wc;
    }
    if (!T_wc) {
      ++result.frames_without_pose;
    } else if (selector.consider(*T_wc)) {
      objects::ObjectKeyFrame kf;
      kf.id = static_cast<objects::KeyFrameId>(i + 1);
      kf.stamp = frame->timestamp;
      kf.camera = result.camera;
      kf.T_wc = *T_wc;
      if (params.use_depth && frame->depth.same_size(result.camera.width, result.camera.height)) {
        kf.depth.data = frame->depth.data.data();
        kf.depth.width = frame->depth.width;
        kf.depth.height = frame->depth.height;
      }
      kf.detections = frame->detections;
      std::string error;
      const objects::KeyFrameAssociation r = mapper.process_keyframe(kf, &error);
      if (!error.empty()) {
        result.error = error;
        break;
      }
      if (params.on_keyframe) params.on_keyframe(kf, r, mapper);
      ++result.keyframes;
      result.keyframe_T_wc.push_back(*T_wc);
      result.association_ms.push_back(r.association_ms);
      for (const auto& refinement : r.refinements) result.refinement_ms.push_back(refinement.ms);
      result.events.insert(result.events.end(), r.events.begin(), r.events.end());
      result.detections += static_cast<int>(kf.detections.size());
      for (const objects::ObjectId id : r.object_ids) {
        if (id == 0) ++result.rejected_detections;
      }
    }
    if (progress) progress(i + 1, total);
  }
  result.objects = mapper.objects();
  result.class_names = mapper.class_names();
  result.ok = result.error.empty();
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

}  // namespace dqo::system
