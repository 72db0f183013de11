// Reader of the package's own dataset folder (layout in dataset_writer.h).
#include <cstdint>
#include <filesystem>
#include <limits>
#include <map>
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

constexpr long long kMaxId = std::numeric_limits<uint32_t>::max();

class OwnDatasetReader : public io_detail::BasicDatasetReader {
 public:
  OwnDatasetReader() : BasicDatasetReader("dqo") {}
  int num_frames() const override { return static_cast<int>(poses_.size()); }

  std::optional<Frame> read_frame(int i, std::string* error) const override {
    if (!check_frame_index(i, error)) return std::nullopt;
    Frame frame;
    frame.index = i;
    frame.timestamp = poses_[i].first;
    frame.T_wc = poses_[i].second;
    frame.has_pose = true;
    const std::string name = io_detail::frame_file_name(i, "png");
    if (!read_rgbd(dir_ + "/rgb/" + name, dir_ + "/depth/" + name, &frame, error)) {
      return std::nullopt;
    }
    if (!io_detail::read_instance_if_present(dir_ + "/instance/" + name, info_.camera,
                                             &frame.instance, error)) {
      return std::nullopt;
    }
    frame.detections = detections_[i];
    frame.objects = objects_[i];
    return frame;
  }

  bool open(const std::string& dir, bool load_meshes, std::string* error) {
    dir_ = dir;
    io_detail::CameraDistortion lens;
    if (!io_detail::read_camera_yaml(dir + "/camera.yaml", /*depth_scale_required=*/true,
                                     &info_.camera, &info_.depth_scale, &lens, error)) {
      return false;
    }
    info_.distortion_model = lens.model;
    info_.distortion = lens.coefficients;
    info_.rolling_shutter_s = lens.rolling_shutter_s;
    if (!io_detail::read_classes_file(dir + "/classes.txt", &info_.class_names, error)) return false;
    auto poses = read_tum_trajectory(dir + "/groundtruth.txt", error);
    if (!poses) return false;
    poses_ = std::move(*poses);
    std::error_code ec;
    if (!fs::is_directory(dir + "/rgb", ec)) return fail(error, dir + "/rgb: folder missing");
    detections_.assign(poses_.size(), {});
    objects_.assign(poses_.size(), {});
    return io_detail::read_detections_file(dir + "/detections.txt", info_.class_names, nullptr,
                                           &detections_, error) &&
           read_frame_objects(dir + "/frame_objects.txt", error) &&
           io_detail::read_gt_objects_file(dir + "/objects_gt.txt", dir, load_meshes,
                                           info_.class_names, &info_.objects, error);
  }

 private:
  bool read_frame_objects(const std::string& path, std::string* error) {
    std::vector<TextLine> lines;
    std::error_code ec;
    if (fs::exists(path, ec) && !io_detail::read_text_lines(path, &lines, error)) return false;
    const long long last = static_cast<long long>(poses_.size()) - 1;
    for (const TextLine& line : lines) {
      const LineFields f(path, line, error);
      long long frame = 0, id = 0;
      FrameObject o;
      if (!f.count(7, 7, "frame id x1 y1 x2 y2 visible_fraction") ||
          !f.integer(0, "frame", 0, last, &frame) || !f.integer(1, "id", 0, kMaxId, &id) ||
          !f.number(2, "x1", &o.box.x_min) || !f.number(3, "y1", &o.box.y_min) ||
          !f.number(4, "x2", &o.box.x_max) || !f.number(5, "y2", &o.box.y_max) ||
          !f.number(6, "visible_fraction", &o.visible_fraction)) {
        return false;
      }
      o.id = static_cast<uint32_t>(id);
      objects_[frame].push_back(o);
    }
    return true;
  }

  Trajectory poses_;  // line k of groundtruth.txt is frame k
  std::vector<std::vector<Detection2d>> detections_;
  std::vector<std::vector<FrameObject>> objects_;
};

}  // namespace

std::unique_ptr<DatasetReader> open_own_dataset(const std::string& dir, bool load_meshes,
                                                std::string* error) {
  return io_detail::open_reader<OwnDatasetReader>(dir, load_meshes, error);
}

}  // namespace dqo
