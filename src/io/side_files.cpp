#include "side_files.h"

#include <cstdint>
#include <filesystem>
#include <limits>
#include <system_error>

#include "dataset_reader_util.h"
#include "dqo_map/common/object_list.h"
#include "dqo_map/io/class_list.h"
#include "dqo_map/io/image_io.h"
#include "dqo_map/io/mesh_io.h"
#include "text_util.h"

namespace dqo {
namespace io_detail {

namespace fs = std::filesystem;

namespace {

constexpr long long kMaxId = std::numeric_limits<uint32_t>::max();
constexpr long long kMaxClass = std::numeric_limits<int>::max();

bool lines_if_present(const std::string& path, std::vector<TextLine>* lines, std::string* error) {
  std::error_code ec;
  lines->clear();
  if (!fs::exists(path, ec)) return true;
  return read_text_lines(path, lines, error);
}

std::string class_name(const std::map<int, std::string>& names, int id) {
  const auto it = names.find(id);
  return it == names.end() ? std::string() : it->second;
}

}  // namespace

bool read_classes_file(const std::string& path, std::map<int, std::string>* class_names,
                       std::string* error) {
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
    if (!class_names->emplace(static_cast<int>(id), name).second) {
      return f.error("class " + std::to_string(id) + " listed twice");
    }
  }
  return true;
}

bool read_detections_file(const std::string& path, const std::map<int, std::string>& class_names,
                          const FrameOfStamp& frame_of_stamp,
                          std::vector<std::vector<Detection2d>>* detections, std::string* error) {
  std::vector<TextLine> lines;
  if (!lines_if_present(path, &lines, error)) return false;
  const long long last = static_cast<long long>(detections->size()) - 1;
  for (const TextLine& line : lines) {
    const LineFields f(path, line, error);
    long long frame = 0, class_id = 0, gt_id = 0;
    Detection2d d;
    if (!f.count(7, 8, "frame x1 y1 x2 y2 class_id score [gt_id]")) return false;
    const std::string& first = line.tokens[0];
    const bool is_stamp = first.find_first_of(".eE") != std::string::npos;
    if (is_stamp && frame_of_stamp) {
      double stamp = 0.0;
      if (!f.number(0, "timestamp", &stamp)) return false;
      const std::optional<int> i = frame_of_stamp(stamp);
      if (!i) return f.error("no frame at timestamp " + first);
      frame = *i;
    } else if (!f.integer(0, "frame", 0, last, &frame)) {
      return false;
    }
    if (!f.number(1, "x1", &d.box.x_min) || !f.number(2, "y1", &d.box.y_min) ||
        !f.number(3, "x2", &d.box.x_max) || !f.number(4, "y2", &d.box.y_max) ||
        !f.integer(5, "class_id", -kMaxClass, kMaxClass, &class_id) ||
        !f.number(6, "score", &d.score) ||
        (line.tokens.size() == 8 && !f.integer(7, "gt_id", 0, kMaxId, &gt_id))) {
      return false;
    }
    d.class_id = static_cast<int>(class_id);
    d.class_name = class_name(class_names, d.class_id);
    d.gt_id = static_cast<uint32_t>(gt_id);
    (*detections)[frame].push_back(d);
  }
  return true;
}

bool read_gt_objects_file(const std::string& path, const std::string& dir, bool load_meshes,
                          const std::map<int, std::string>& class_names,
                          std::vector<GtObject>* objects, std::string* error) {
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
    o.class_name = class_name(class_names, o.class_id);
    o.box = to_oriented_box(e);
    const std::string mesh_path = dir + "/meshes_gt/" + std::to_string(o.id) + ".ply";
    if (load_meshes && fs::exists(mesh_path, ec)) {
      auto mesh = load_mesh(mesh_path, error);
      if (!mesh) return false;
      o.mesh = std::move(*mesh);
    }
    objects->push_back(std::move(o));
  }
  return true;
}

bool read_instance_if_present(const std::string& path, const PinholeCamera& camera,
                              InstanceImage* instance, std::string* error) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return true;
  auto image = read_png_u16(path, error);
  if (!image || !check_image_size(path, *image, camera, error)) return false;
  *instance = std::move(*image);
  return true;
}

}  // namespace io_detail
}  // namespace dqo

namespace dqo {

bool read_class_list(const std::string& path, std::map<int, std::string>* class_names, std::string* error) {
  return io_detail::read_classes_file(path, class_names, error);
}

std::string class_list_text(const std::map<int, std::string>& class_names) {
  std::string text = "# class_id class_name\n";
  for (const auto& [id, name] : class_names) text += std::to_string(id) + ' ' + name + '\n';
  return text;
}

bool write_class_list(const std::string& path, const std::map<int, std::string>& class_names, std::string* error) {
  return io_detail::write_file_atomically(path, class_list_text(class_names), error);
}

}  // namespace dqo
