#include "dqo_map/system/keyframe_overlays.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <utility>

#include "dqo_map/common/frame_source.h"
#include "dqo_map/io/image_io.h"
#include "dqo_map/objects/object_overlay.h"

namespace dqo::system {

namespace {

// `image` enlarged `factor` times, bilinear (pixel centres at integer coordinates).
ImageRgb8 enlarged(const ImageRgb8& image, int factor) {
  if (factor <= 1 || image.empty()) return image;
  ImageRgb8 out;
  out.width = image.width * factor;
  out.height = image.height * factor;
  out.channels = image.channels;
  out.data.resize(static_cast<size_t>(out.width) * out.height * out.channels);
  const int c = image.channels;
  for (int y = 0; y < out.height; ++y) {
    const double sy = std::clamp((y + 0.5) / factor - 0.5, 0.0, image.height - 1.0);
    const int y0 = static_cast<int>(sy), y1 = std::min(y0 + 1, image.height - 1);
    const double fy = sy - y0;
    for (int x = 0; x < out.width; ++x) {
      const double sx = std::clamp((x + 0.5) / factor - 0.5, 0.0, image.width - 1.0);
      const int x0 = static_cast<int>(sx), x1 = std::min(x0 + 1, image.width - 1);
      const double fx = sx - x0;
      for (int k = 0; k < c; ++k) {
        auto at = [&](int xx, int yy) {
          return static_cast<double>(image.data[(static_cast<size_t>(yy) * image.width + xx) * c + k]);
        };
        const double v = (1 - fy) * ((1 - fx) * at(x0, y0) + fx * at(x1, y0)) +
                         fy * ((1 - fx) * at(x0, y1) + fx * at(x1, y1));
        out.data[(static_cast<size_t>(y) * out.width + x) * c + k] = static_cast<uint8_t>(std::lround(v));
      }
    }
  }
  return out;
}

}  // namespace

ImageRgb8 keyframe_overlay(const ObjectStageView& view, int min_width) {
  const mapping::MappingKeyframe& kf = view.keyframe;
  const int factor = kf.camera.width > 0 && kf.camera.width < min_width
                         ? (min_width + kf.camera.width - 1) / kf.camera.width
                         : 1;
  const objects::KeyFrameAssociation& a = view.association;
  std::vector<objects::OverlayDetection> detections;
  detections.reserve(a.filtered.size());
  for (size_t k = 0; k < a.filtered.size(); ++k) {
    objects::OverlayDetection d;
    const Box2d& b = a.filtered[k].box;  // image coordinates [0, w] x [0, h]: they scale as they are
    d.box = {b.x_min * factor, b.y_min * factor, b.x_max * factor, b.y_max * factor};
    d.class_name = a.filtered[k].class_name;
    d.score = a.filtered[k].score;
    d.object_id = k < a.filtered_object_ids.size() ? a.filtered_object_ids[k] : 0;
    detections.push_back(std::move(d));
  }
  return objects::draw_object_overlay(enlarged(kf.rgb, factor), scale_camera(kf.camera, factor),
                                      kf.T_wc, detections, view.objects);
}

std::string keyframe_overlay_name(mapping::KeyframeId id) {
  char name[48];
  std::snprintf(name, sizeof(name), "keyframe_%06llu.png", static_cast<unsigned long long>(id));
  return name;
}

ObjectStageObserver overlay_writer(const std::string& folder, std::shared_ptr<OverlayLog> log,
                                   std::string* error, int min_width) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(folder, ec);
  if (ec || !fs::is_directory(folder)) {
    *error = "cannot create the overlay folder " + folder + (ec ? ": " + ec.message() : "");
    return {};
  }
  // A second run into the same folder with fewer keyframes must not leave the first's behind.
  for (const fs::directory_entry& e : fs::directory_iterator(folder, ec)) {
    const std::string name = e.path().filename().string();
    if (e.is_regular_file() && name.rfind("keyframe_", 0) == 0 && e.path().extension() == ".png") {
      fs::remove(e.path(), ec);
    }
  }
  return [folder, log, min_width](const ObjectStageView& view) {
    if (!log->error.empty()) return;
    const std::string path = (fs::path(folder) / keyframe_overlay_name(view.keyframe.id)).string();
    std::string e;
    if (write_png(path, keyframe_overlay(view, min_width), &e)) {
      ++log->written;
    } else {
      log->error = e.empty() ? path + ": cannot write" : e;
    }
  };
}

ObjectStageObserver class_name_collector(std::shared_ptr<std::map<int, std::string>> names) {
  return [names](const ObjectStageView& view) {
    for (const Detection2d& d : view.detections) {
      if (!d.class_name.empty()) names->emplace(d.class_id, d.class_name);
    }
  };
}

std::string object_table(const std::vector<objects::MapObject>& objects,
                         const std::map<int, std::string>& class_names, int top) {
  std::string out;
  char line[512];
  std::snprintf(line, sizeof(line), "%4s  %-14s %-40s %-24s %-17s %5s %6s\n", "id", "class",
                "top classes (share of the vote)", "centre x y z (m)", "box size (m)", "obs", "P(ex)");
  out += line;
  for (const objects::MapObject& o : objects) {
    std::string shares;
    for (const objects::ClassShare& c : objects::top_classes(o, top, class_names)) {
      const std::string name = c.class_name.empty() ? "class " + std::to_string(c.class_id) : c.class_name;
      char share[96];
      std::snprintf(share, sizeof(share), "%s%s %.2f", shares.empty() ? "" : ", ", name.c_str(), c.share);
      shares += share;
    }
    if (shares.empty()) shares = "-";
    const OrientedBox box = o.has_box ? o.box
                                      : OrientedBox{o.quadric.centre(), o.quadric.rotation(), o.quadric.semi_axes()};
    char centre[64], size[64];
    std::snprintf(centre, sizeof(centre), "%.3f %.3f %.3f", box.centre.x(), box.centre.y(), box.centre.z());
    std::snprintf(size, sizeof(size), "%.2f %.2f %.2f", 2 * box.half_extents.x(),
                  2 * box.half_extents.y(), 2 * box.half_extents.z());
    std::snprintf(line, sizeof(line), "%4llu  %-14s %-40s %-24s %-17s %5d %6.3f\n",
                  static_cast<unsigned long long>(o.id), o.class_name.c_str(), shares.c_str(), centre,
                  size, o.observation_count, objects::existence_probability(o));
    out += line;
  }
  return out;
}

}  // namespace dqo::system
