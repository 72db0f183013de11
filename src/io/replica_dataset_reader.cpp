// Reader of the Replica layout used by NICE-SLAM (rules in dataset_reader.h).
#include <cstdio>
#include <filesystem>
#include <system_error>

#include "camera_yaml.h"
#include "dataset_reader_util.h"
#include "side_files.h"
#include "dqo_map/io/dataset_reader.h"
#include "text_util.h"

namespace dqo {

namespace fs = std::filesystem;
using io_detail::fail;
using io_detail::LineFields;
using io_detail::TextLine;

namespace {

constexpr double kReplicaDepthScale = 6553.5;

std::string numbered(const char* prefix, int i, const char* extension) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%s%06d.%s", prefix, i, extension);
  return buffer;
}

class ReplicaDatasetReader : public io_detail::BasicDatasetReader {
 public:
  ReplicaDatasetReader() : BasicDatasetReader("replica") {}
  int num_frames() const override { return static_cast<int>(poses_.size()); }

  std::optional<Frame> read_frame(int i, std::string* error) const override {
    if (!check_frame_index(i, error)) return std::nullopt;
    Frame frame;
    frame.index = i;
    frame.timestamp = i * frame_period_;
    frame.T_wc = poses_[i];
    frame.has_pose = true;
    const std::string rgb_path = dir_ + "/results/" + numbered("frame", i, "jpg");
    const std::string depth_path = dir_ + "/results/" + numbered("depth", i, "png");
    if (!read_rgbd(rgb_path, depth_path, &frame, error)) return std::nullopt;
    frame.detections = detections_[i];
    return frame;
  }

  bool open(const std::string& dir, const ReplicaReaderParams& params, std::string* error) {
    dir_ = dir;
    frame_period_ = params.frame_period;
    std::error_code ec;
    // NICE-SLAM keeps one cam_params.json for all scenes, in the folder above them.
    std::string cam_path = dir + "/cam_params.json";
    if (!fs::exists(cam_path, ec)) {
      const fs::path parent = fs::absolute(dir, ec).lexically_normal().parent_path();
      const std::string above = (parent / "cam_params.json").string();
      if (!fs::exists(above, ec)) {
        return fail(error, cam_path + ": missing (looked here and at " + above + ")");
      }
      cam_path = above;
    }
    info_.depth_scale = kReplicaDepthScale;
    if (!io_detail::read_replica_cam_params(cam_path, &info_.camera, &info_.depth_scale,
                                            error)) {
      return false;
    }
    if (!fs::is_directory(dir + "/results", ec)) {
      return fail(error, dir + "/results: folder missing");
    }
    if (!read_trajectory(dir + "/traj.txt", error)) return false;
    // The own format's side files, when a detector (dqo_detect) or a user put them here: the
    // detections by frame index and their class names.
    detections_.resize(poses_.size());
    return io_detail::read_classes_file(dir + "/classes.txt", &info_.class_names, error) &&
           io_detail::read_detections_file(dir + "/detections.txt", info_.class_names, nullptr, &detections_, error);
  }

 private:
  bool read_trajectory(const std::string& path, std::string* error) {
    std::vector<TextLine> lines;
    if (!io_detail::read_text_lines(path, &lines, error)) return false;
    for (const TextLine& line : lines) {
      const LineFields f(path, line, error);
      if (!f.count(16, 16, "a 4x4 camera-to-world matrix, row-major")) return false;
      Eigen::Matrix4d T;
      for (int k = 0; k < 16; ++k) {
        const std::string name = "m" + std::to_string(k / 4) + std::to_string(k % 4);
        if (!f.number(k, name.c_str(), &T(k / 4, k % 4))) return false;
      }
      if ((T.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-6) {
        return f.error("bottom row is not 0 0 0 1");
      }
      const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
      if ((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-4 ||
          R.determinant() < 0.0) {
        return f.error("top-left 3x3 block is not a rotation");
      }
      poses_.push_back(SE3::from_matrix(T));
    }
    return true;
  }

  std::vector<SE3> poses_;  // line i of traj.txt is frame i
  std::vector<std::vector<Detection2d>> detections_;  // [frame]
  double frame_period_ = 1.0 / 30.0;
};

}  // namespace

std::unique_ptr<DatasetReader> open_replica_dataset(const std::string& dir,
                                                    const ReplicaReaderParams& params,
                                                    std::string* error) {
  return io_detail::open_reader<ReplicaDatasetReader>(dir, params, error);
}

}  // namespace dqo
