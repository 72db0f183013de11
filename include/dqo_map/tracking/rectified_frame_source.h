#pragma once
// A frame source whose images have lens distortion (DatasetInfo::distortion_model, e.g. a TUM fr1
// or Azure Kinect recording with its camera.yaml) seen through the tracker's undistortion, so that
// the offline tools treat it as tracking_node treats a CameraInfo with D: colour, depth and
// instance labels rectified once per frame, detection and per-object boxes mapped through the
// undistortion (as the association node maps raw detections), and a pinhole camera (the raw K,
// D = 0) in info(). OpenCV stays in the .cpp (through Undistorter).

#include <memory>
#include <optional>
#include <string>

#include "dqo_map/common/frame_source.h"
#include "dqo_map/tracking/undistortion.h"

namespace dqo::tracking {

// The calibration of a source's camera as a CameraInfo would hold it (P zero: the raw K).
CameraCalibration calibration_of(const DatasetInfo& info);

class RectifiedFrameSource : public FrameSource {
 public:
  // nullptr and *error when the distortion is unusable (Undistorter::create's checks).
  static std::unique_ptr<RectifiedFrameSource> create(std::shared_ptr<const FrameSource> source,
                                                      std::string* error);
  const DatasetInfo& info() const override { return info_; }
  int num_frames() const override { return source_->num_frames(); }
  std::optional<Frame> read_frame(int i, std::string* error = nullptr) const override;

 private:
  RectifiedFrameSource(std::shared_ptr<const FrameSource> source, Undistorter undistorter);
  std::shared_ptr<const FrameSource> source_;
  Undistorter undistorter_;
  DatasetInfo info_;
};

// `source` itself when its images have no distortion, else a RectifiedFrameSource over it;
// nullptr and *error when the distortion is unusable.
std::shared_ptr<const FrameSource> rectified(std::shared_ptr<const FrameSource> source,
                                             std::string* error);

}  // namespace dqo::tracking
