// Reader of the package's own dataset folder (layout in dataset_writer.h).
#include <cstdint>
#include <filesystem>
#include <limits>
#include <map>
#include <system_error>

#include "camera_yaml.h"
#include "dataset_reader_util.h"
#include "dqo_map/common/object_list.h"
#include "dqo_map/io/dataset_reader.h"
#include "dqo_map/io/image_io.h"
#include "dqo_map/io/mesh_io.h"
#include "text_util.h"

namespace dqo {

namespace fs = std::filesystem;
using io_detail::fail;
using io_detail::LineFields;
using io_detail::TextLine;

namespace {

constexpr long long kMaxId = std::numeric_limits<uint32_t>::max();
constexpr long long kMaxClass = std::numeric_limits<int>::max();

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
    const std::string instance_path = dir_ + "/instance/" + name;
    std::error_code ec;
    if (fs::exists(instance_path, ec)) {
      auto instance = read_png_u16(instance_path, error);
      if (!instance ||
          !io_detail::check_image_size(instance_path, *instance, info_.camera, error)) {
        return std::nullopt;
      }
      frame.instance = std::move(*instance);
    }
    frame.detections = detections_[i];
    frame.objects = objects_[i];
    return frame;
  }

  bool open(const std::string& dir, bool load_meshes, std::string* error) {
    dir_ = dir;
    if (!io_detail::read_camera_yaml(dir + "/camera.yaml", /*depth_scale_required=*/true,
                                     &info_.camera, &info_.depth_scale, error)) {
      return false;
    }
    if (!read_classes(dir + "/classes.txt", error)) return false;
    auto poses = read_tum_trajectory(dir + "/groundtruth.txt", error);
    if (!poses) return false;
    poses_ = std::move(*poses);
    std::error_code ec;
    if (!fs::is_directory(dir + "/rgb", ec)) return fail(error, dir + "/rgb: folder missing");
    detections_.assign(poses_.size(), {});
    objects_.assign(poses_.size(), {});
    return read_detections(dir + "/detections.txt", error) &&
           read_frame_objects(dir + "/frame_objects.txt", error) &&
           read_objects(dir + "/objects_gt.txt", load_meshes, error);
  }

 private:
  // Optional files: absent means "none".
  static bool lines_if_present(const std::string& path, std::vector<TextLine>* lines,
                               std::string* error) {
    std::error_code ec;
    lines->clear();
    if (!fs::exists(path, ec)) return true;
    return io_detail::read_text_lines(path, lines, error);
  }

  bool read_classes(const std::string& path, std::string* error) {
    std::vector<TextLine> lines;
    if (!lines_if_present(path, &lines, error)) return false;
    for (const TextLine& line : lines) {
      const LineFields f(path, line, error);
      long long id = 0;
      if (line.tokens.size() < 2) return f.error("expected 'class_id class_name'");
      if (!f.integer(0, "class_id", -kMaxClass, kMaxClass, &id)) return false;
      // The name is the rest of the line: it may contain blanks ("dining table").
      const size_t id_start = line.text.find_first_not_of(" \t");
      const size_t id_end = line.text.find_first_of(" \t", id_start);
      const size_t name_start = line.text.find_first_not_of(" \t", id_end);
      const size_t name_end = line.text.find_last_not_of(" \t");
      const std::string name = line.text.substr(name_start, name_end - name_start + 1);
      if (!info_.class_names.emplace(static_cast<int>(id), name).second) {
        return f.error("class " + std::to_string(id) + " listed twice");
      }
    }
    return true;
  }

  std::string class_name(int id) const {
    const auto it = info_.class_names.find(id);
    return it == info_.class_names.end() ? std::string() : it->second;
  }

  bool read_detections(const std::string& path, std::string* error) {
    std::vector<TextLine> lines;
    if (!lines_if_present(path, &lines, error)) return false;
    const long long last = static_cast<long long>(poses_.size()) - 1;
    for (const TextLine& line : lines) {
      const LineFields f(path, line, error);
      long long frame = 0, class_id = 0, gt_id = 0;
      Detection2d d;
      if (!f.count(7, 8, "frame x1 y1 x2 y2 class_id score [gt_id]") ||
          !f.integer(0, "frame", 0, last, &frame) || !f.number(1, "x1", &d.box.x_min) ||
          !f.number(2, "y1", &d.box.y_min) || !f.number(3, "x2", &d.box.x_max) ||
          !f.number(4, "y2", &d.box.y_max) ||
          !f.integer(5, "class_id", -kMaxClass, kMaxClass, &class_id) ||
          !f.number(6, "score", &d.score) ||
          (line.tokens.size() == 8 && !f.integer(7, "gt_id", 0, kMaxId, &gt_id))) {
        return false;
      }
      d.class_id = static_cast<int>(class_id);
      d.class_name = class_name(d.class_id);
      d.gt_id = static_cast<uint32_t>(gt_id);
      detections_[frame].push_back(d);
    }
    return true;
  }

  bool read_frame_objects(const std::string& path, std::string* error) {
    std::vector<TextLine> lines;
    if (!lines_if_present(path, &lines, error)) return false;
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

  // objects_gt.txt is an object list file (common/object_list.h) with box half extents in place of
  // semi-axes; one parser for both.
  bool read_objects(const std::string& path, bool load_meshes, std::string* error) {
    std::error_code ec;
    if (!fs::exists(path, ec)) return true;
    const auto entries = read_object_list(path, error);
    if (!entries) return false;
    for (const ObjectListEntry& e : *entries) {
      if (e.id > static_cast<uint64_t>(kMaxId)) {
        return fail(error, path + ": object ID " + std::to_string(e.id) +
                               " out of range (ground-truth IDs are 32-bit)");
      }
      GtObject o;
      o.id = static_cast<uint32_t>(e.id);
      o.class_id = e.class_id;
      o.class_name = class_name(o.class_id);
      o.box = to_oriented_box(e);
      const std::string mesh_path = dir_ + "/meshes_gt/" + std::to_string(o.id) + ".ply";
      if (load_meshes && fs::exists(mesh_path, ec)) {
        auto mesh = load_mesh(mesh_path, error);
        if (!mesh) return false;
        o.mesh = std::move(*mesh);
      }
      info_.objects.push_back(std::move(o));
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
