#include "dqo_map/tracking/rectified_frame_source.h"

#include <algorithm>
#include <utility>

namespace dqo::tracking {

CameraCalibration calibration_of(const DatasetInfo& info) {
  CameraCalibration c;
  c.width = info.camera.width;
  c.height = info.camera.height;
  c.K = {info.camera.fx, 0.0, info.camera.cx, 0.0, info.camera.fy, info.camera.cy, 0.0, 0.0, 1.0};
  c.distortion_model = info.distortion_model;
  c.D = info.distortion;
  return c;
}

std::unique_ptr<RectifiedFrameSource> RectifiedFrameSource::create(
    std::shared_ptr<const FrameSource> source, std::string* error) {
  auto undistorter = Undistorter::create(calibration_of(source->info()), error);
  if (!undistorter) return nullptr;
  return std::unique_ptr<RectifiedFrameSource>(
      new RectifiedFrameSource(std::move(source), std::move(*undistorter)));
}

RectifiedFrameSource::RectifiedFrameSource(std::shared_ptr<const FrameSource> source,
                                           Undistorter undistorter)
    : source_(std::move(source)), undistorter_(std::move(undistorter)), info_(source_->info()) {
  info_.camera = undistorter_.camera();
  info_.distortion_model.clear();
  info_.distortion.clear();
}

std::optional<Frame> RectifiedFrameSource::read_frame(int i, std::string* error) const {
  std::optional<Frame> raw = source_->read_frame(i, error);
  if (!raw || undistorter_.is_identity()) return raw;
  Frame out = std::move(*raw);
  ImageRgb8 rgb;
  DepthImage depth;
  if (!undistorter_.rectify_rgb(out.rgb, &rgb, error) ||
      !undistorter_.rectify_depth(out.depth, &depth, error)) {
    return std::nullopt;
  }
  out.rgb = std::move(rgb);
  out.depth = std::move(depth);
  if (!out.instance.data.empty()) {
    InstanceImage labels;
    if (!undistorter_.rectify_labels(out.instance, &labels, error)) return std::nullopt;
    out.instance = std::move(labels);
  }
  for (Detection2d& d : out.detections) d.box = undistorter_.rectify_box(d.box);
  for (FrameObject& o : out.objects) o.box = undistorter_.rectify_box(o.box);
  return out;
}

std::shared_ptr<const FrameSource> rectified(std::shared_ptr<const FrameSource> source,
                                             std::string* error) {
  const DatasetInfo& info = source->info();
  const bool distorted = std::any_of(info.distortion.begin(), info.distortion.end(),
                                     [](double v) { return v != 0.0; });
  if (!distorted) return source;
  return RectifiedFrameSource::create(std::move(source), error);
}

}  // namespace dqo::tracking
