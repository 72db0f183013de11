#include "dqo_map/io/dataset_writer.h"

#include "dqo_map/io/class_list.h"

#include <stdlib.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <system_error>

#include <Eigen/Geometry>

#include "camera_yaml.h"
#include "dqo_map/io/image_io.h"
#include "dqo_map/io/mesh_io.h"
#include "text_util.h"

namespace dqo {

namespace fs = std::filesystem;
using io_detail::format_double;
using io_detail::format_float;

struct DatasetWriter::State {
  Params params;
  fs::path dir;
  std::string dir_text;
  fs::path staging;  // empty when there is none (not created, removed, or renamed into place)
  std::string error;
  bool failed = false;
  bool finished = false;
  bool have_info = false;
  int num_frames = 0;
  PinholeCamera camera;
  double depth_scale = 0.0;
  std::map<int, std::string> class_names;
  std::ofstream groundtruth;
  std::ofstream detections;
  std::ofstream frame_objects;

  void remove_staging() {
    groundtruth.close();
    detections.close();
    frame_objects.close();
    if (!staging.empty()) {
      std::error_code ec;
      fs::remove_all(staging, ec);
      staging.clear();
    }
  }
};

namespace {

// The class-name table must stay a function: one ID, one name.
bool add_class_name(std::map<int, std::string>* names, int id, const std::string& name,
                    std::string* message) {
  if (name.empty()) return true;
  if (name.find_first_of("\r\n") != std::string::npos || name.front() == ' ' ||
      name.back() == ' ' || name.front() == '\t' || name.back() == '\t') {
    *message = "class name '" + name + "' has a line break or leading/trailing blanks";
    return false;
  }
  auto [it, inserted] = names->emplace(id, name);
  if (!inserted && it->second != name) {
    *message = "class " + std::to_string(id) + " is named both '" + it->second + "' and '" +
               name + "'";
    return false;
  }
  return true;
}

std::string box_text(const Box2d& b) {
  return format_double(b.x_min) + ' ' + format_double(b.y_min) + ' ' + format_double(b.x_max) +
         ' ' + format_double(b.y_max);
}

bool finite_box(const Box2d& b) {
  return std::isfinite(b.x_min) && std::isfinite(b.y_min) && std::isfinite(b.x_max) &&
         std::isfinite(b.y_max);
}

bool directory_is_empty(const fs::path& dir) {
  std::error_code ec;
  return fs::is_empty(dir, ec) && !ec;
}

}  // namespace

DatasetWriter::DatasetWriter(const std::string& dir, const Params& params)
    : state_(std::make_unique<State>()) {
  state_->params = params;
  fs::path target = fs::path(dir).lexically_normal();
  if (target.has_filename() == false) target = target.parent_path();  // "out/" -> "out"
  state_->dir = target;
  state_->dir_text = target.string();
  if (target.empty() || target.filename() == "." || target.filename() == "..") {
    set_failed(dir + ": not a usable dataset folder name", nullptr);
    return;
  }
  std::error_code ec;
  if (fs::exists(target, ec)) {
    if (!fs::is_directory(target, ec)) {
      set_failed(dir + ": exists and is not a folder", nullptr);
      return;
    }
    if (!directory_is_empty(target)) {
      if (!params.overwrite) {
        set_failed(dir + ": folder exists and is not empty (set overwrite to replace a dataset)",
                   nullptr);
        return;
      }
      if (!fs::exists(target / "camera.yaml", ec)) {
        set_failed(dir + ": refusing to replace a folder that is not a dataset (no camera.yaml)",
                   nullptr);
        return;
      }
    }
  }
  const fs::path parent = target.has_parent_path() ? target.parent_path() : fs::path(".");
  fs::create_directories(parent, ec);
  if (ec) {
    set_failed(parent.string() + ": cannot create folder: " + ec.message(), nullptr);
    return;
  }
  std::string pattern = (parent / ("." + target.filename().string() + ".partial-XXXXXX")).string();
  if (!::mkdtemp(pattern.data())) {
    set_failed(parent.string() + ": cannot create a temporary folder for " + dir, nullptr);
    return;
  }
  state_->staging = pattern;
  for (const char* sub : {"rgb", "depth", "instance", "meshes_gt"}) {
    fs::create_directory(state_->staging / sub, ec);
    if (ec) {
      set_failed((state_->staging / sub).string() + ": cannot create folder: " + ec.message(),
                 nullptr);
      return;
    }
  }
}

DatasetWriter::~DatasetWriter() {
  if (!state_->finished) abort();
}

bool DatasetWriter::set_failed(const std::string& message, std::string* error) {
  if (!state_->failed) {
    state_->failed = true;
    state_->error = message;
  }
  state_->remove_staging();
  if (error) *error = state_->error;
  return false;
}

bool DatasetWriter::failed() const { return state_->failed; }
const std::string& DatasetWriter::error() const { return state_->error; }
int DatasetWriter::num_frames() const { return state_->num_frames; }
const std::string& DatasetWriter::dir() const { return state_->dir_text; }

void DatasetWriter::abort() {
  state_->remove_staging();
  if (!state_->finished && !state_->failed) {
    state_->failed = true;
    state_->error = state_->dir.string() + ": writing was aborted";
  }
}

bool DatasetWriter::write_info(const DatasetInfo& info, std::string* error) {
  State& s = *state_;
  if (s.failed) return set_failed(s.error, error);
  if (s.finished) return set_failed(s.dir.string() + ": write_info after finish()", error);
  if (s.have_info) return set_failed(s.dir.string() + ": write_info called twice", error);
  std::string message;
  if (!io_detail::check_camera(s.dir.string() + ": DatasetInfo", info.camera, info.depth_scale,
                               &message)) {
    return set_failed(message, error);
  }
  s.camera = info.camera;
  s.depth_scale = info.depth_scale;
  for (const auto& [id, name] : info.class_names) {
    if (!add_class_name(&s.class_names, id, name, &message)) {
      return set_failed(s.dir.string() + ": " + message, error);
    }
  }

  if (!io_detail::write_file_atomically((s.staging / "camera.yaml").string(),
                                        io_detail::camera_yaml_text(info.camera, info.depth_scale),
                                        &message)) {
    return set_failed(message, error);
  }

  std::string objects = "# id class_id cx cy cz qx qy qz qw hx hy hz\n";
  std::map<uint32_t, bool> ids;
  for (const GtObject& o : info.objects) {
    if (o.id == 0) return set_failed(s.dir.string() + ": ground-truth object with ID 0", error);
    if (!ids.emplace(o.id, true).second) {
      return set_failed(s.dir.string() + ": two ground-truth objects with ID " +
                            std::to_string(o.id),
                        error);
    }
    if (!add_class_name(&s.class_names, o.class_id, o.class_name, &message)) {
      return set_failed(s.dir.string() + ": " + message, error);
    }
    if (!o.box.centre.allFinite() || !o.box.rotation.allFinite() ||
        !o.box.half_extents.allFinite()) {
      return set_failed(s.dir.string() + ": object " + std::to_string(o.id) +
                            " has a box that is not finite",
                        error);
    }
    const Eigen::Quaterniond q(o.box.rotation);
    const Eigen::Vector3d& c = o.box.centre;
    const Eigen::Vector3d& h = o.box.half_extents;
    objects += std::to_string(o.id) + ' ' + std::to_string(o.class_id) + ' ' +
               format_double(c.x()) + ' ' + format_double(c.y()) + ' ' + format_double(c.z()) +
               ' ' + format_double(q.x()) + ' ' + format_double(q.y()) + ' ' +
               format_double(q.z()) + ' ' + format_double(q.w()) + ' ' + format_double(h.x()) +
               ' ' + format_double(h.y()) + ' ' + format_double(h.z()) + '\n';
    if (!o.mesh.empty()) {
      const fs::path mesh_path = s.staging / "meshes_gt" / (std::to_string(o.id) + ".ply");
      if (!save_mesh_ply(mesh_path.string(), o.mesh, &message)) {
        return set_failed(message, error);
      }
    }
  }
  if (!io_detail::write_file_atomically((s.staging / "objects_gt.txt").string(), objects,
                                        &message)) {
    return set_failed(message, error);
  }

  s.groundtruth.open(s.staging / "groundtruth.txt");
  s.detections.open(s.staging / "detections.txt");
  s.frame_objects.open(s.staging / "frame_objects.txt");
  if (!s.groundtruth || !s.detections || !s.frame_objects) {
    return set_failed(s.staging.string() + ": cannot create the text files", error);
  }
  s.groundtruth << "# timestamp tx ty tz qx qy qz qw\n";
  s.detections << "# frame x1 y1 x2 y2 class_id score [gt_id]\n";
  s.frame_objects << "# frame id x1 y1 x2 y2 visible_fraction\n";
  s.have_info = true;
  return true;
}

bool DatasetWriter::write_frame(const Frame& frame, std::string* error) {
  State& s = *state_;
  if (s.failed) return set_failed(s.error, error);
  if (s.finished) return set_failed(s.dir.string() + ": write_frame after finish()", error);
  const std::string where = s.dir.string() + ": frame " + std::to_string(frame.index) + ": ";
  if (!s.have_info) return set_failed(where + "write_info must come first", error);
  if (frame.index != s.num_frames) {
    return set_failed(where + "expected frame index " + std::to_string(s.num_frames) +
                          " (frames are written in order, from 0, without gaps)",
                      error);
  }
  if (!frame.has_pose) return set_failed(where + "has no pose (the format needs one)", error);
  if (!std::isfinite(frame.timestamp) || !frame.T_wc.translation().allFinite() ||
      !frame.T_wc.quaternion().coeffs().allFinite()) {
    return set_failed(where + "timestamp or pose is not finite", error);
  }
  const int w = s.camera.width;
  const int h = s.camera.height;
  auto check_image = [&](const auto& image, int channels, const char* name) {
    if (!image.same_size(w, h) || image.channels != channels ||
        image.data.size() != static_cast<size_t>(w) * h * channels) {
      set_failed(where + name + " image is " + std::to_string(image.width) + "x" +
                     std::to_string(image.height) + "x" + std::to_string(image.channels) +
                     ", expected " + std::to_string(w) + "x" + std::to_string(h) + "x" +
                     std::to_string(channels),
                 error);
      return false;
    }
    return true;
  };
  if (!check_image(frame.rgb, 3, "rgb") || !check_image(frame.depth, 1, "depth")) return false;
  if (!frame.instance.empty() && !check_image(frame.instance, 1, "instance")) return false;

  std::string message;
  std::string detections;
  for (const Detection2d& d : frame.detections) {
    if (!finite_box(d.box) || !std::isfinite(d.score)) {
      return set_failed(where + "detection box or score is not finite", error);
    }
    if (!add_class_name(&s.class_names, d.class_id, d.class_name, &message)) {
      return set_failed(where + message, error);
    }
    detections += std::to_string(frame.index) + ' ' + box_text(d.box) + ' ' +
                  std::to_string(d.class_id) + ' ' + format_float(d.score);
    if (d.gt_id != 0) detections += ' ' + std::to_string(d.gt_id);
    detections += '\n';
  }
  std::string objects;
  for (const FrameObject& o : frame.objects) {
    if (!finite_box(o.box) || !std::isfinite(o.visible_fraction)) {
      return set_failed(where + "object box or visible fraction is not finite", error);
    }
    objects += std::to_string(frame.index) + ' ' + std::to_string(o.id) + ' ' + box_text(o.box) +
               ' ' + format_double(o.visible_fraction) + '\n';
  }

  const std::string name = io_detail::frame_file_name(frame.index, "png");
  if (!write_png((s.staging / "rgb" / name).string(), frame.rgb, &message) ||
      !write_png((s.staging / "depth" / name).string(), depth_to_u16(frame.depth, s.depth_scale),
                 &message) ||
      (!frame.instance.empty() &&
       !write_png((s.staging / "instance" / name).string(), frame.instance, &message))) {
    return set_failed(message, error);
  }

  const Eigen::Vector3d& p = frame.T_wc.translation();
  const Eigen::Quaterniond& q = frame.T_wc.quaternion();
  s.groundtruth << format_double(frame.timestamp) << ' ' << format_double(p.x()) << ' '
                << format_double(p.y()) << ' ' << format_double(p.z()) << ' '
                << format_double(q.x()) << ' ' << format_double(q.y()) << ' '
                << format_double(q.z()) << ' ' << format_double(q.w()) << '\n';
  s.detections << detections;
  s.frame_objects << objects;
  if (!s.groundtruth || !s.detections || !s.frame_objects) {
    return set_failed(where + "cannot append to the text files", error);
  }
  ++s.num_frames;
  return true;
}

bool DatasetWriter::finish(std::string* error) {
  State& s = *state_;
  if (s.failed) return set_failed(s.error, error);
  if (s.finished) return true;
  if (!s.have_info) return set_failed(s.dir.string() + ": finish() before write_info", error);
  s.groundtruth.close();
  s.detections.close();
  s.frame_objects.close();
  if (s.groundtruth.fail() || s.detections.fail() || s.frame_objects.fail()) {
    return set_failed(s.staging.string() + ": cannot flush the text files", error);
  }
  std::string message;
  if (!write_class_list((s.staging / "classes.txt").string(), s.class_names, &message)) {
    return set_failed(message, error);
  }

  std::error_code ec;
  fs::path old;  // a dataset being replaced, moved aside until the new one is in place
  if (fs::exists(s.dir, ec) && !directory_is_empty(s.dir)) {
    if (!s.params.overwrite) {
      return set_failed(s.dir.string() + ": folder appeared while writing and is not empty",
                        error);
    }
    const fs::path parent = s.staging.parent_path();
    std::string pattern = (parent / ("." + s.dir.filename().string() + ".old-XXXXXX")).string();
    if (!::mkdtemp(pattern.data())) {
      return set_failed(parent.string() + ": cannot create a temporary folder", error);
    }
    old = pattern;
    fs::rename(s.dir, old, ec);  // onto the empty folder mkdtemp made
    if (ec) {
      fs::remove(old);
      return set_failed(s.dir.string() + ": cannot move the old dataset aside: " + ec.message(),
                        error);
    }
  }
  // rename(2) replaces an empty folder, so an empty `dir` needs no special case.
  fs::rename(s.staging, s.dir, ec);
  if (ec) {
    std::error_code ignored;
    if (!old.empty()) fs::rename(old, s.dir, ignored);
    return set_failed(s.dir.string() + ": cannot move the dataset into place: " + ec.message(),
                      error);
  }
  s.staging.clear();
  s.finished = true;
  fs::permissions(s.dir,
                  fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec |
                      fs::perms::others_read | fs::perms::others_exec,
                  ec);  // mkdtemp made it 0700
  if (!old.empty()) fs::remove_all(old, ec);
  return true;
}

}  // namespace dqo
