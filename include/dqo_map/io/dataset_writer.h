#pragma once
// Writer of the package's own dataset folder (read back by open_dataset / open_own_dataset).
//
// Layout (frame files numbered NNNNNN = Frame::index, six digits, from 000000 without gaps):
//   camera.yaml          width, height, fx, fy, cx, cy, depth_scale  (a flat YAML map)
//   classes.txt          `class_id class_name` per line (the name is the rest of the line)
//   rgb/NNNNNN.png       8-bit colour
//   depth/NNNNNN.png     uint16 = round(depth_m * depth_scale), 0 = no measurement (also for depth
//                        that is missing, not positive, or would not fit in 1..65535)
//   instance/NNNNNN.png  uint16 ground-truth object ID, 0 = none; only for frames that have one
//   groundtruth.txt      TUM trajectory, line k = frame k: `t tx ty tz qx qy qz qw` (T_world_camera)
//   detections.txt       `frame x1 y1 x2 y2 class_id score [gt_id]`; gt_id only when non-zero
//   frame_objects.txt    `frame id x1 y1 x2 y2 visible_fraction`: ground truth per visible object
//   objects_gt.txt       `id class_id cx cy cz qx qy qz qw hx hy hz`: oriented box, world frame,
//                        rotation as a unit quaternion (scalar last), half extents
//   meshes_gt/<id>.ply   the object's mesh in world coordinates, for objects that have one (binary
//                        PLY: vertices as doubles, exact; vertex colours, when any, as 8-bit)
// Every text file starts with a '#' comment line naming its columns; numbers are written as the
// shortest decimal text that parses back to the same value, so readers get back exactly what was
// written (depth exactly as quantise_depth() gives it; rotations up to the quaternion round trip).
// classes.txt holds the union of DatasetInfo::class_names and the class names met on objects and
// detections.
//
// All-or-nothing: files go to a hidden temporary sibling folder (`.<name>.partial-XXXXXX`) that
// finish() renames to `dir`. Any failure, abort(), or destruction before finish() removes the
// temporary folder, so `dir` either holds a complete dataset or is left as it was. (A process
// killed outright can leave the hidden temporary folder behind, never a partial `dir`.)

#include <memory>
#include <string>

#include "dqo_map/common/dataset.h"

namespace dqo {

class DatasetWriter {
 public:
  struct Params {
    // `dir` may already exist when it is empty. A non-empty `dir` is replaced at finish() only
    // with overwrite set and only when it holds a dataset of this format (a camera.yaml):
    // a mistyped path must not delete an unrelated folder.
    bool overwrite = false;
  };

  explicit DatasetWriter(const std::string& dir) : DatasetWriter(dir, Params()) {}
  DatasetWriter(const std::string& dir, const Params& params);
  ~DatasetWriter();  // abort() unless finish() succeeded
  DatasetWriter(const DatasetWriter&) = delete;
  DatasetWriter& operator=(const DatasetWriter&) = delete;

  // Once, before any frame: camera.yaml, objects_gt.txt and meshes_gt/.
  bool write_info(const DatasetInfo& info, std::string* error = nullptr);

  // Frames in order of index 0, 1, 2, ...; each needs a pose, an RGB image and a depth image of
  // the camera's size (the instance image is optional). Detections and objects are appended to
  // the text files. Not thread-safe: call from one thread.
  bool write_frame(const Frame& frame, std::string* error = nullptr);

  // Flushes the text files, writes classes.txt and moves the folder into place.
  bool finish(std::string* error = nullptr);

  // Discards everything written so far.
  void abort();

  // The first error met; every call after it fails with the same message.
  bool failed() const;
  const std::string& error() const;
  int num_frames() const;
  const std::string& dir() const;

 private:
  struct State;
  bool set_failed(const std::string& message, std::string* error);

  std::unique_ptr<State> state_;
};

}  // namespace dqo
