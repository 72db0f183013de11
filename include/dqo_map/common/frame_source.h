#pragma once
// Where frames come from, for everything that consumes a sequence of RGB-D frames with what ground
// truth it has: a dataset folder (io/dataset_reader.h), a synthetic scene rendered in memory
// (sim/scene_frame_source.h), or either at a reduced resolution (ScaledFrameSource). The offline
// pipeline takes this interface, so that its reduced form builds where io/ (OpenCV) does not.

#include <map>
#include <memory>
#include <vector>
#include <optional>
#include <string>

#include "dqo_map/common/dataset.h"

namespace dqo {

class FrameSource {
 public:
  virtual ~FrameSource() = default;

  // Camera, depth scale, class names and ground-truth objects (where the source has them).
  virtual const DatasetInfo& info() const = 0;
  virtual int num_frames() const = 0;
  // Frame i of [0, num_frames()): images in memory (depth in metres), pose, and what the source
  // holds of instances, ground-truth objects and detections. nullopt and *error on failure.
  // Safe to call from several threads at once.
  virtual std::optional<Frame> read_frame(int i, std::string* error = nullptr) const = 0;
};

// The intrinsics of the same camera with its image scaled by s (pixel centres at integer
// coordinates, so cx' = (cx + ½) s − ½). Width and height round to the nearest pixel (at least 1).
PinholeCamera scale_camera(const PinholeCamera& camera, double s);

// A frame resampled to `camera` (a scale_camera of the frame's own): colour by area averaging over
// the source pixels each target pixel covers, depth and instance IDs by the source pixel nearest to
// the target pixel's centre (averaging would invent depths between surfaces and IDs between
// objects); detection and per-object boxes scaled.
Frame scale_frame(const Frame& frame, const PinholeCamera& from, const PinholeCamera& to);

// Another source seen at scale s (its camera in info() scaled too).
class ScaledFrameSource : public FrameSource {
 public:
  ScaledFrameSource(std::shared_ptr<const FrameSource> source, double s);
  const DatasetInfo& info() const override { return info_; }
  int num_frames() const override { return source_->num_frames(); }
  std::optional<Frame> read_frame(int i, std::string* error = nullptr) const override;

 private:
  std::shared_ptr<const FrameSource> source_;
  DatasetInfo info_;
};

// Another source's frames `indices`, read (rendered, decoded) up front on `threads` threads and
// kept in memory, so that a timed run measures the pipeline and not the reading; other frames are
// read through. Throws std::runtime_error naming the frame that could not be read.
class PreloadedFrameSource : public FrameSource {
 public:
  PreloadedFrameSource(std::shared_ptr<const FrameSource> source, const std::vector<int>& indices, int threads);
  const DatasetInfo& info() const override { return source_->info(); }
  int num_frames() const override { return source_->num_frames(); }
  std::optional<Frame> read_frame(int i, std::string* error = nullptr) const override;
  size_t bytes() const;  // of the frames held

 private:
  std::shared_ptr<const FrameSource> source_;
  std::map<int, Frame> frames_;
};

}  // namespace dqo
