// Reader of TUM RGB-D sequences (rules in dataset_reader.h).
#include <algorithm>
#include <cmath>
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

struct ListEntry {
  double timestamp = 0.0;
  std::string path;  // as written in the list, relative to the sequence folder
};

bool read_list(const std::string& path, std::vector<ListEntry>* entries, std::string* error) {
  std::vector<TextLine> lines;
  if (!io_detail::read_text_lines(path, &lines, error)) return false;
  for (const TextLine& line : lines) {
    const LineFields f(path, line, error);
    ListEntry entry;
    if (!f.count(2, 2, "timestamp filename") || !f.number(0, "timestamp", &entry.timestamp)) {
      return false;
    }
    entry.path = line.tokens[1];
    entries->push_back(std::move(entry));
  }
  return true;
}

class TumDatasetReader : public io_detail::BasicDatasetReader {
 public:
  TumDatasetReader() : BasicDatasetReader("tum") {}
  int num_frames() const override { return static_cast<int>(frames_.size()); }

  std::optional<Frame> read_frame(int i, std::string* error) const override {
    if (!check_frame_index(i, error)) return std::nullopt;
    const Entry& e = frames_[i];
    Frame frame;
    frame.index = i;
    frame.timestamp = e.timestamp;
    frame.depth_timestamp = e.depth_timestamp;
    frame.has_pose = e.has_pose;
    frame.T_wc = e.T_wc;
    if (!read_rgbd(dir_ + "/" + e.rgb, dir_ + "/" + e.depth, &frame, error)) return std::nullopt;
    if (has_instance_) {
      // Named as the colour image, else by frame index.
      const std::string by_name = dir_ + "/instance/" + fs::path(e.rgb).filename().string();
      std::error_code ec;
      const std::string path = fs::exists(by_name, ec)
                                   ? by_name
                                   : dir_ + "/instance/" + io_detail::frame_file_name(i, "png");
      if (!io_detail::read_instance_if_present(path, info_.camera, &frame.instance, error))
        return std::nullopt;
    }
    frame.detections = detections_[i];
    return frame;
  }

  bool open(const std::string& dir, const TumReaderParams& params, std::string* error) {
    dir_ = dir;
    load_meshes_ = params.load_meshes;
    info_.depth_scale = params.default_depth_scale;
    const std::string camera_path =
        params.camera_file.empty() ? dir + "/camera.yaml" : params.camera_file;
    std::error_code ec;
    if (!fs::exists(camera_path, ec)) {
      return fail(error, camera_path +
                             ": missing (TUM sequences need the intrinsics in a camera.yaml "
                             "beside rgb.txt: width, height, fx, fy, cx, cy, [depth_scale])");
    }
    io_detail::CameraDistortion lens;
    if (!io_detail::read_camera_yaml(camera_path, /*depth_scale_required=*/false, &info_.camera,
                                     &info_.depth_scale, &lens, error)) {
      return false;
    }
    info_.distortion_model = lens.model;
    info_.distortion = lens.coefficients;
    info_.rolling_shutter_s = lens.rolling_shutter_s;
    std::vector<ListEntry> rgb, depth;
    if (!read_list(dir + "/rgb.txt", &rgb, error) ||
        !read_list(dir + "/depth.txt", &depth, error)) {
      return false;
    }
    Trajectory groundtruth;
    const std::string gt_path = dir + "/groundtruth.txt";
    if (fs::exists(gt_path, ec)) {
      auto poses = read_tum_trajectory(gt_path, error);
      if (!poses) return false;
      groundtruth = std::move(*poses);
      std::stable_sort(groundtruth.begin(), groundtruth.end(),
                       [](const TimedPose& a, const TimedPose& b) { return a.first < b.first; });
    }

    std::vector<double> rgb_times, depth_times;
    for (const ListEntry& e : rgb) rgb_times.push_back(e.timestamp);
    for (const ListEntry& e : depth) depth_times.push_back(e.timestamp);
    for (const auto& [i, j] :
         associate_timestamps(rgb_times, depth_times, params.max_time_difference)) {
      Entry e;
      e.timestamp = rgb[i].timestamp;
      e.rgb = rgb[i].path;
      e.depth = depth[j].path;
      e.depth_timestamp = depth[j].timestamp;
      if (auto pose = pose_at(groundtruth, e.timestamp, params.pose)) {
        e.T_wc = *pose;
        e.has_pose = true;
      }
      frames_.push_back(std::move(e));
    }
    // rgb.txt is in time order in every TUM sequence; sort anyway so frame order is time order.
    std::stable_sort(frames_.begin(), frames_.end(),
                     [](const Entry& a, const Entry& b) { return a.timestamp < b.timestamp; });
    return read_side_files(params, error);
  }

 private:
  bool read_side_files(const TumReaderParams& params, std::string* error) {
    std::error_code ec;
    has_instance_ = fs::is_directory(dir_ + "/instance", ec);
    detections_.assign(frames_.size(), {});
    const double tolerance = params.max_time_difference;
    auto frame_of_stamp = [this, tolerance](double t) -> std::optional<int> {
      // frames_ is sorted by time: the nearest of the two around t.
      const auto it = std::lower_bound(frames_.begin(), frames_.end(), t,
                                       [](const Entry& e, double v) { return e.timestamp < v; });
      std::optional<int> best;
      double best_dt = tolerance;
      for (auto c : {it, it == frames_.begin() ? it : it - 1}) {
        if (c == frames_.end()) continue;
        const double dt = std::abs(c->timestamp - t);
        if (dt <= best_dt) {
          best_dt = dt;
          best = static_cast<int>(c - frames_.begin());
        }
      }
      return best;
    };
    return io_detail::read_classes_file(dir_ + "/classes.txt", &info_.class_names, error) &&
           io_detail::read_detections_file(dir_ + "/detections.txt", info_.class_names,
                                           frame_of_stamp, &detections_, error) &&
           io_detail::read_gt_objects_file(dir_ + "/objects_gt.txt", dir_, load_meshes_,
                                           info_.class_names, &info_.objects, error);
  }

  struct Entry {
    double timestamp = 0.0;
    std::string rgb;
    std::string depth;
    double depth_timestamp = 0.0;
    SE3 T_wc;
    bool has_pose = false;
  };

  std::vector<Entry> frames_;
  std::vector<std::vector<Detection2d>> detections_;  // per frame
  bool has_instance_ = false;
  bool load_meshes_ = false;
};

}  // namespace

std::unique_ptr<DatasetReader> open_tum_dataset(const std::string& dir,
                                                const TumReaderParams& params,
                                                std::string* error) {
  return io_detail::open_reader<TumDatasetReader>(dir, params, error);
}

}  // namespace dqo
