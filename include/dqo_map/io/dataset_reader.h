#pragma once
// Reading RGB-D datasets: one interface over the package's own folder format, TUM RGB-D and the
// Replica layout of NICE-SLAM, chosen by what the folder holds (tested in this order):
//
//   "tum"        rgb.txt and depth.txt          (+ groundtruth.txt, + camera.yaml beside them)
//   own ("dqo")  camera.yaml and rgb/           (layout in dataset_writer.h)
//   "replica"    results/ and traj.txt          (+ cam_params.json here or in the parent folder)
//
// TUM RGB-D: rgb.txt and depth.txt list `timestamp path` per line ('#' comments). Colour and depth
// images are paired one-to-one by nearest timestamp within max_time_difference (greedily by
// increasing difference, as TUM's associate.py); colour images without a partner are dropped.
// A frame's timestamp is its colour image's. Its pose comes from groundtruth.txt (TUM trajectory
// format) interpolated at that timestamp (see PoseLookupParams); where none can be had, or without
// groundtruth.txt, has_pose is false. Depth scale 5000 unless camera.yaml gives depth_scale;
// camera.yaml has the keys of the own format (depth_scale optional, distortion optional) and is
// required. The own format's side files are read when present beside rgb.txt: classes.txt,
// detections.txt (its frame column a frame index, or a timestamp matched to the nearest frame
// within max_time_difference), objects_gt.txt (+ meshes_gt/) and instance/ (a PNG named as the
// colour image, e.g. instance/1305031102.175304.png, or by frame index, instance/000042.png).
//
// Replica (NICE-SLAM): results/frameNNNNNN.jpg (colour), results/depthNNNNNN.png (uint16, scale
// 6553.5 unless cam_params.json says otherwise), traj.txt with one camera-to-world 4x4 matrix per
// line (16 numbers, row-major) for frame NNNNNN = line index. The frame count is the number of
// poses. Replica has no timestamps: frame i gets i * frame_period. classes.txt and detections.txt
// (frame column: the frame index; e.g. from dqo_detect) are read when present.
//
// Readers are immutable after opening: read_frame may be called from several threads at once.
// Text files are parsed, and malformed lines reported, when the dataset is opened; images are
// read by read_frame.

#include <memory>
#include <optional>
#include <string>

#include "dqo_map/common/dataset.h"
#include "dqo_map/common/frame_source.h"
#include "dqo_map/io/trajectory_io.h"

namespace dqo {

// info(): camera, depth scale, class names and ground-truth objects (own format only);
// read_frame(i): what the format holds of poses, instances, ground-truth objects and detections.
class DatasetReader : public FrameSource {
 public:
  // "dqo", "tum" or "replica".
  virtual std::string format() const = 0;
  // The folder it reads.
  virtual const std::string& dir() const = 0;
};

struct TumReaderParams {
  double max_time_difference = 0.02;  // seconds between paired colour and depth images, and
                                      // between a detection's timestamp and its frame's
  // Read in place of the folder's camera.yaml when not empty (a calibration kept apart from the
  // data, e.g. config/cameras/tum_fr1.yaml with the lens distortion).
  std::string camera_file;
  bool load_meshes = true;  // objects_gt.txt's meshes_gt/<id>.ply (open_dataset: its own flag)
  PoseLookupParams pose;              // ground truth at the colour timestamp
  double default_depth_scale = 5000.0;
};

struct ReplicaReaderParams {
  double frame_period = 1.0 / 30.0;  // seconds; Replica has no timestamps
};

struct DatasetReaderParams {
  bool load_meshes = true;  // own format and TUM: read meshes_gt/<id>.ply into info().objects[].mesh
  TumReaderParams tum;
  ReplicaReaderParams replica;
};

// "dqo", "tum", "replica", or "" when the folder holds none of the three (or does not exist).
std::string detect_dataset_format(const std::string& dir);

// Opens whichever format the folder holds. nullptr and *error (naming the file, and the line for
// malformed text) when the folder is missing, holds no known format, or a file is malformed.
std::unique_ptr<DatasetReader> open_dataset(const std::string& dir, std::string* error);
std::unique_ptr<DatasetReader> open_dataset(const std::string& dir,
                                            const DatasetReaderParams& params,
                                            std::string* error);

std::unique_ptr<DatasetReader> open_own_dataset(const std::string& dir, bool load_meshes,
                                                std::string* error);
std::unique_ptr<DatasetReader> open_tum_dataset(const std::string& dir,
                                                const TumReaderParams& params, std::string* error);
std::unique_ptr<DatasetReader> open_replica_dataset(const std::string& dir,
                                                    const ReplicaReaderParams& params,
                                                    std::string* error);

}  // namespace dqo
