#include "camera_yaml.h"

#include <cmath>
#include <map>
#include <set>

#include <yaml-cpp/yaml.h>

#include "text_util.h"

namespace dqo {
namespace io_detail {

namespace {

// yaml-cpp marks are 0-based; -1 when unknown.
std::string at_mark(const std::string& path, const YAML::Mark& mark, const std::string& message) {
  return mark.line >= 0 ? located(path, mark.line + 1, message) : path + ": " + message;
}

bool load_yaml(const std::string& path, YAML::Node* root, std::string* error) {
  try {
    *root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    return fail(error, path + ": cannot open for reading");
  } catch (const YAML::Exception& e) {
    return fail(error, at_mark(path, e.mark, "cannot parse: " + e.msg));
  }
  if (!root->IsMap()) return fail(error, path + ": expected a map of keys to values");
  return true;
}

bool number_of(const std::string& path, const YAML::Node& key, const YAML::Node& value,
               double* out, std::string* error) {
  const std::string name = key.as<std::string>();
  if (!value.IsScalar() || !parse_double(value.Scalar(), out)) {
    return fail(error, at_mark(path, value.Mark(), "'" + name + "' must be a finite number"));
  }
  return true;
}

bool integer_of(const std::string& path, const YAML::Node& key, const YAML::Node& value, int* out,
                std::string* error) {
  double v = 0.0;
  if (!number_of(path, key, value, &v, error)) return false;
  if (v != std::floor(v) || v < 0 || v > 1e6) {
    return fail(error, at_mark(path, value.Mark(),
                               "'" + key.as<std::string>() + "' must be a whole number of pixels"));
  }
  *out = static_cast<int>(v);
  return true;
}

}  // namespace

bool check_camera(const std::string& path, const PinholeCamera& camera, double depth_scale,
                  std::string* error) {
  if (camera.width <= 0 || camera.height <= 0) {
    return fail(error, path + ": width and height must be positive");
  }
  if (!(camera.fx > 0.0) || !(camera.fy > 0.0) || !std::isfinite(camera.fx) ||
      !std::isfinite(camera.fy)) {
    return fail(error, path + ": fx and fy must be positive");
  }
  if (!std::isfinite(camera.cx) || !std::isfinite(camera.cy)) {
    return fail(error, path + ": cx and cy must be finite");
  }
  if (!(depth_scale > 0.0) || !std::isfinite(depth_scale)) {
    return fail(error, path + ": depth_scale must be positive");
  }
  return true;
}

bool read_camera_yaml(const std::string& path, bool depth_scale_required, PinholeCamera* camera,
                      double* depth_scale, CameraDistortion* distortion, std::string* error) {
  YAML::Node root;
  if (!load_yaml(path, &root, error)) return false;
  std::set<std::string> seen;
  PinholeCamera cam;
  double scale = *depth_scale;
  CameraDistortion lens;
  YAML::Mark lens_mark;
  const char* expected = distortion != nullptr
                             ? "width, height, fx, fy, cx, cy, depth_scale, distortion_model, distortion, "
                               "rolling_shutter_s"
                             : "width, height, fx, fy, cx, cy, depth_scale";
  try {
    for (auto it = root.begin(); it != root.end(); ++it) {
      const YAML::Node key = it->first;
      const YAML::Node value = it->second;
      const std::string name = key.as<std::string>();
      bool ok = true;
      if (name == "width") {
        ok = integer_of(path, key, value, &cam.width, error);
      } else if (name == "height") {
        ok = integer_of(path, key, value, &cam.height, error);
      } else if (name == "fx") {
        ok = number_of(path, key, value, &cam.fx, error);
      } else if (name == "fy") {
        ok = number_of(path, key, value, &cam.fy, error);
      } else if (name == "cx") {
        ok = number_of(path, key, value, &cam.cx, error);
      } else if (name == "cy") {
        ok = number_of(path, key, value, &cam.cy, error);
      } else if (name == "depth_scale") {
        ok = number_of(path, key, value, &scale, error);
      } else if (distortion != nullptr && name == "distortion_model") {
        if (!value.IsScalar()) {
          return fail(error, at_mark(path, value.Mark(), "'distortion_model' must be a name"));
        }
        lens.model = value.Scalar();
        lens_mark = value.Mark();
      } else if (distortion != nullptr && name == "distortion") {
        if (!value.IsSequence()) {
          return fail(error, at_mark(path, value.Mark(),
                                     "'distortion' must be a list of numbers [k1, k2, p1, p2, k3, ...]"));
        }
        for (const YAML::Node& v : value) {
          double c = 0.0;
          if (!number_of(path, key, v, &c, error)) return false;
          lens.coefficients.push_back(c);
        }
        if (!seen.count("distortion_model")) lens_mark = value.Mark();
      } else if (distortion != nullptr && name == "rolling_shutter_s") {
        ok = number_of(path, key, value, &lens.rolling_shutter_s, error);
        if (ok && !(lens.rolling_shutter_s >= 0.0 && lens.rolling_shutter_s <= 1.0)) {
          return fail(error, at_mark(path, value.Mark(),
                                     "'rolling_shutter_s' must lie in [0, 1] seconds"));
        }
      } else {
        return fail(error, at_mark(path, key.Mark(),
                                   "unknown key '" + name + "' (expected " + expected + ")"));
      }
      if (!ok) return false;
      seen.insert(name);
    }
  } catch (const YAML::Exception& e) {
    return fail(error, at_mark(path, e.mark, e.msg));
  }
  for (const char* required : {"width", "height", "fx", "fy", "cx", "cy"}) {
    if (!seen.count(required)) return fail(error, path + ": missing key '" + required + "'");
  }
  if (depth_scale_required && !seen.count("depth_scale")) {
    return fail(error, path + ": missing key 'depth_scale'");
  }
  if (!check_camera(path, cam, scale, error)) return false;
  if (distortion != nullptr && (seen.count("distortion_model") || seen.count("distortion"))) {
    size_t most = 0;
    if (lens.model == "plumb_bob") most = 5;
    if (lens.model == "rational_polynomial") most = 8;
    if (!seen.count("distortion_model") || !seen.count("distortion")) {
      return fail(error, at_mark(path, lens_mark,
                                 "'distortion_model' and 'distortion' go together"));
    }
    if (most == 0) {
      return fail(error, at_mark(path, lens_mark,
                                 "unknown distortion_model '" + lens.model +
                                     "' (expected plumb_bob or rational_polynomial)"));
    }
    if (lens.coefficients.size() > most) {
      return fail(error, at_mark(path, lens_mark,
                                 lens.model + " takes at most " + std::to_string(most) +
                                     " coefficients, 'distortion' has " +
                                     std::to_string(lens.coefficients.size())));
    }
    lens.coefficients.resize(most, 0.0);
  }
  *camera = cam;
  *depth_scale = scale;
  if (distortion != nullptr) *distortion = lens;
  return true;
}

std::string camera_yaml_text(const PinholeCamera& camera, double depth_scale) {
  std::string text;
  text += "# Pinhole intrinsics of the rectified images (pixels); depth PNG value = metres x "
          "depth_scale\n";
  text += "width: " + std::to_string(camera.width) + "\n";
  text += "height: " + std::to_string(camera.height) + "\n";
  text += "fx: " + format_double(camera.fx) + "\n";
  text += "fy: " + format_double(camera.fy) + "\n";
  text += "cx: " + format_double(camera.cx) + "\n";
  text += "cy: " + format_double(camera.cy) + "\n";
  text += "depth_scale: " + format_double(depth_scale) + "\n";
  return text;
}

bool read_replica_cam_params(const std::string& path, PinholeCamera* camera, double* depth_scale,
                             std::string* error) {
  YAML::Node root;
  if (!load_yaml(path, &root, error)) return false;
  PinholeCamera cam;
  double scale = *depth_scale;
  try {
    const YAML::Node node = root["camera"];
    if (!node || !node.IsMap()) return fail(error, path + ": expected a \"camera\" object");
    std::map<std::string, YAML::Node> keys;
    for (auto it = node.begin(); it != node.end(); ++it) {
      keys[it->first.as<std::string>()] = it->first;
    }
    for (const char* required : {"w", "h", "fx", "fy", "cx", "cy"}) {
      if (!keys.count(required)) {
        return fail(error, at_mark(path, node.Mark(),
                                   std::string("\"camera\" lacks \"") + required + "\""));
      }
    }
    if (!integer_of(path, keys["w"], node["w"], &cam.width, error) ||
        !integer_of(path, keys["h"], node["h"], &cam.height, error) ||
        !number_of(path, keys["fx"], node["fx"], &cam.fx, error) ||
        !number_of(path, keys["fy"], node["fy"], &cam.fy, error) ||
        !number_of(path, keys["cx"], node["cx"], &cam.cx, error) ||
        !number_of(path, keys["cy"], node["cy"], &cam.cy, error)) {
      return false;
    }
    if (keys.count("scale") && !number_of(path, keys["scale"], node["scale"], &scale, error)) {
      return false;
    }
  } catch (const YAML::Exception& e) {
    return fail(error, at_mark(path, e.mark, e.msg));
  }
  if (!check_camera(path, cam, scale, error)) return false;
  *camera = cam;
  *depth_scale = scale;
  return true;
}

}  // namespace io_detail
}  // namespace dqo
