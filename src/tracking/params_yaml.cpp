#include "dqo_map/tracking/params_yaml.h"

#include <charconv>
#include <cmath>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>
#include <stdexcept>
#include <variant>
#include <vector>

#include <yaml-cpp/yaml.h>

namespace dqo::tracking {
namespace {

// One table describes every parameter: the loader and the writer both walk it, so that a field
// added to the table is read and written alike (and a field missing from it is neither).
using IntArray4 = int[4];
using Target = std::variant<int*, float*, double*, bool*, IntArray4*>;

struct Field {
  const char* key;
  Target target;
  double lo = -std::numeric_limits<double>::infinity();  // inclusive bounds for numbers
  double hi = std::numeric_limits<double>::infinity();
};

struct Section {
  const char* key;
  std::vector<Field> fields;
  std::vector<Section> sections;
};

constexpr double kInf = std::numeric_limits<double>::infinity();

Section schema(TrackingConfig& c) {
  TrackerParams& t = c.tracker;
  KeyframeSelectorParams& k = c.mapping_keyframes;
  return Section{
      "",
      {},
      {
          Section{"tracker",
                  {
                      {"use_features", &t.use_features},
                      {"use_dense", &t.use_dense},
                      {"min_inliers_ok", &t.min_inliers_ok, 0, 100000},
                      {"frames_to_lost", &t.frames_to_lost, 1, 100000},
                  },
                  {
                      Section{"orb",
                              {
                                  {"num_features", &t.orb.num_features, 1, 100000},
                                  {"scale_factor", &t.orb.scale_factor, 1.001, 4.0},
                                  {"num_levels", &t.orb.num_levels, 1, 32},
                                  {"fast_threshold", &t.orb.fast_threshold, 1, 255},
                                  {"min_fast_threshold", &t.orb.min_fast_threshold, 1, 255},
                                  {"grid_cell_px", &t.orb.grid_cell_px, 4, 10000},
                                  {"min_depth", &t.orb.min_depth, 0.0, kInf},
                                  {"max_depth", &t.orb.max_depth, 0.0, kInf},
                              },
                              {}},
                      Section{"dense",
                              {
                                  {"pyramid_levels", &t.dense.pyramid_levels, 1, 4},
                                  {"finest_level", &t.dense.finest_level, 0, 3},
                                  {"iterations", &t.dense.iterations, 0, 1000},
                                  {"max_depth", &t.dense.max_depth, 0.0, kInf},
                                  {"max_point_distance", &t.dense.max_point_distance, 0.0, kInf},
                                  {"max_normal_angle_deg", &t.dense.max_normal_angle_deg, 0.0, 180.0},
                                  {"colour_weight", &t.dense.colour_weight, 0.0, kInf},
                                  {"huber_delta", &t.dense.huber_delta, 0.0, kInf},
                                  {"depth_sigma_per_m2", &t.dense.depth_sigma_per_m2, 0.0, kInf},
                                  {"min_depth_sigma_m", &t.dense.min_depth_sigma_m, 0.0, kInf},
                                  {"intensity_sigma", &t.dense.intensity_sigma, 1e-9, kInf},
                                  {"huber_delta_intensity", &t.dense.huber_delta_intensity, 0.0, kInf},
                                  {"min_gradient", &t.dense.min_gradient, 0.0, kInf},
                                  {"min_inliers", &t.dense.min_inliers, 0, 100000000},
                                  {"min_inlier_ratio", &t.dense.min_inlier_ratio, 0.0, 1.0},
                                  {"max_update_m", &t.dense.max_update_m, 0.0, kInf},
                                  {"max_update_deg", &t.dense.max_update_deg, 0.0, 180.0},
                                  {"max_whitened_rms", &t.dense.max_whitened_rms, 0.0, kInf},
                                  {"convergence_px", &t.dense.convergence_px, 0.0, kInf},
                              },
                              {}},
                      Section{"pose",
                              {
                                  {"huber_reprojection_px", &t.pose.huber_reprojection_px, 0.0, kInf},
                                  {"huber_depth_m", &t.pose.huber_depth_m, 0.0, kInf},
                                  {"depth_sigma_per_m2", &t.pose.depth_sigma_per_m2, 0.0, kInf},
                                  {"rounds", &t.pose.rounds, 1, 100},
                                  {"dense_prior_weight", &t.pose.dense_prior_weight, 0.0, kInf},
                                  {"depth_sigma_min_m", &t.pose.depth_sigma_min_m, 0.0, kInf},
                                  {"iterations", &t.pose.iterations, 1, 1000},
                                  {"max_prior_chi2", &t.pose.max_prior_chi2, 0.0, kInf},
                              },
                              {}},
                      Section{"search",
                              {
                                  {"frame_radius_px", &t.search.frame_radius_px, 0.0, kInf},
                                  {"dense_radius_px", &t.search.dense_radius_px, 0.0, kInf},
                                  {"local_map_radius_px", &t.search.local_map_radius_px, 0.0, kInf},
                                  {"local_map_ratio", &t.search.local_map_ratio, 0.0, 1.0},
                                  {"local_map_keyframes", &t.search.local_map_keyframes, 1, 100000},
                                  {"min_matches", &t.search.min_matches, 0, 100000},
                              },
                              {}},
                      Section{"keyframes",
                              {
                                  {"min_frames", &t.keyframes.min_frames, 0, 100000},
                                  {"max_frames", &t.keyframes.max_frames, 1, 100000},
                                  {"min_tracked_ratio", &t.keyframes.min_tracked_ratio, 0.0, 1.0},
                                  {"min_close_points", &t.keyframes.min_close_points, 0, 100000},
                                  {"weak_translation_m", &t.keyframes.weak_translation_m, 0.0, kInf},
                                  {"weak_rotation_deg", &t.keyframes.weak_rotation_deg, 0.0, 180.0},
                                  {"max_new_points", &t.keyframes.max_new_points, 0, 1000000},
                              },
                              {}},
                      Section{"local_ba",
                              {
                                  {"enabled", &t.local_ba.enabled},
                                  {"covisible_keyframes", &t.local_ba.covisible_keyframes, 1, 1000},
                                  {"iterations", &t.local_ba.iterations, 1, 1000},
                                  {"fixed_keyframes", &t.local_ba.fixed_keyframes, 0, 1000},
                                  {"synchronous", &t.local_ba.synchronous},
                              },
                              {}},
                      Section{"reloc",
                              {
                                  {"candidate_keyframes", &t.reloc.candidate_keyframes, 1, 10000},
                                  {"min_inliers", &t.reloc.min_inliers, 3, 100000},
                                  {"max_pnp", &t.reloc.max_pnp, 1, 1000},
                              },
                              {}},
                  }},
          Section{"mapping_keyframes",
                  {
                      {"max_rotation_deg", &k.max_rotation_deg, 0.0, 360.0},
                      {"max_translation_m", &k.max_translation_m, 0.0, kInf},
                      {"max_frames", &k.max_frames, -1, 1000000},
                  },
                  {}},
      }};
}

class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Reader {
  std::string source;
  bool positions = true;

  [[noreturn]] void fail(const YAML::Node& node, const std::string& message) const {
    std::string where = source;
    if (positions && node.Mark().line >= 0) {
      where += ":" + std::to_string(node.Mark().line + 1) + ":" + std::to_string(node.Mark().column + 1);
    }
    throw ConfigError(where + ": " + message);
  }

  static std::string join(const std::string& path, const std::string& key) {
    return path.empty() ? key : path + "." + key;
  }

  static std::string shown(double v) {
    char buf[32];
    const auto r = std::to_chars(buf, buf + sizeof(buf), v);
    return std::string(buf, r.ptr);
  }

  double number(const YAML::Node& node, const std::string& path, const Field& f) const {
    if (!node.IsScalar()) fail(node, "'" + path + "' must be a number");
    double v = 0.0;
    try {
      v = node.as<double>();
    } catch (const YAML::Exception&) {
      fail(node, "'" + path + "' must be a number, got '" + node.Scalar() + "'");
    }
    if (!std::isfinite(v)) fail(node, "'" + path + "' must be finite");
    if (v < f.lo || v > f.hi) {
      fail(node, "'" + path + "' = " + node.Scalar() + " is outside [" + shown(f.lo) + ", " +
                     shown(f.hi) + "]");
    }
    return v;
  }

  int integer(const YAML::Node& node, const std::string& path, const Field& f) const {
    const double v = number(node, path, f);
    if (v != std::floor(v)) fail(node, "'" + path + "' must be an integer, got '" + node.Scalar() + "'");
    return static_cast<int>(v);
  }

  void read_field(const YAML::Node& node, const std::string& path, const Field& f) const {
    std::visit(
        [&](auto* target) {
          using T = std::remove_pointer_t<decltype(target)>;
          if constexpr (std::is_same_v<T, bool>) {
            bool v = false;
            if (!node.IsScalar() || !YAML::convert<bool>::decode(node, v)) {
              fail(node, "'" + path + "' must be true or false");
            }
            *target = v;
          } else if constexpr (std::is_same_v<T, int>) {
            *target = integer(node, path, f);
          } else if constexpr (std::is_same_v<T, float>) {
            *target = static_cast<float>(number(node, path, f));
          } else if constexpr (std::is_same_v<T, double>) {
            *target = number(node, path, f);
          } else {
            constexpr size_t n = std::extent_v<T>;
            if (!node.IsSequence() || node.size() != n) {
              fail(node, "'" + path + "' must be a list of " + std::to_string(n) + " integers");
            }
            for (size_t i = 0; i < n; ++i) {
              (*target)[i] = integer(node[i], path + "[" + std::to_string(i) + "]", f);
            }
          }
        },
        f.target);
  }

  void read_section(const YAML::Node& node, const std::string& path, const Section& s) const {
    if (node.IsNull()) return;  // `tracker:` with nothing under it
    if (!node.IsMap()) fail(node, (path.empty() ? std::string("the file") : "'" + path + "'") + " must be a map");
    std::set<std::string> seen;
    for (const auto& kv : node) {
      const YAML::Node& key_node = kv.first;
      if (!key_node.IsScalar()) fail(key_node, "keys must be names");
      const std::string key = key_node.Scalar();
      const std::string full = join(path, key);
      if (!seen.insert(key).second) fail(key_node, "'" + full + "' is given twice");
      bool known = false;
      for (const Field& f : s.fields) {
        if (key == f.key) {
          read_field(kv.second, full, f);
          known = true;
        }
      }
      for (const Section& sub : s.sections) {
        if (key == sub.key) {
          read_section(kv.second, full, sub);
          known = true;
        }
      }
      if (!known) {
        std::string names;
        for (const Field& f : s.fields) names += std::string(names.empty() ? "" : ", ") + f.key;
        for (const Section& sub : s.sections) names += std::string(names.empty() ? "" : ", ") + sub.key;
        fail(key_node, "unknown key '" + full + "' (known" + (path.empty() ? "" : " in " + path) +
                           ": " + names + ")");
      }
    }
  }
};

void write_section(std::ostream& out, const Section& s, int indent) {
  const std::string pad(static_cast<size_t>(indent), ' ');
  for (const Field& f : s.fields) {
    out << pad << f.key << ": ";
    std::visit(
        [&](auto* target) {
          using T = std::remove_pointer_t<decltype(target)>;
          if constexpr (std::is_same_v<T, bool>) {
            out << (*target ? "true" : "false");
          } else if constexpr (std::is_same_v<T, int>) {
            out << *target;
          } else if constexpr (std::is_same_v<T, float> || std::is_same_v<T, double>) {
            char buf[40];
            auto r = std::to_chars(buf, buf + sizeof(buf), *target);
            std::string text(buf, r.ptr);
            // Keep a decimal point so that the value reads back as a real number everywhere.
            if (text.find_first_of(".en") == std::string::npos) text += ".0";
            out << text;
          } else {
            out << "[";
            for (size_t i = 0; i < std::extent_v<T>; ++i) out << (i ? ", " : "") << (*target)[i];
            out << "]";
          }
        },
        f.target);
    out << "\n";
  }
  for (const Section& sub : s.sections) {
    out << pad << sub.key << ":\n";
    write_section(out, sub, indent + 2);
  }
}

}  // namespace

std::optional<TrackingConfig> parse_tracking_config(const std::string& text, const std::string& source,
                                                    std::string* error, const TrackingConfig& base,
                                                    bool positions) {
  TrackingConfig config = base;
  const Reader reader{source, positions};
  try {
    const YAML::Node root = YAML::Load(text);
    if (root.IsDefined() && !root.IsNull()) reader.read_section(root, "", schema(config));
  } catch (const ConfigError& e) {
    if (error) *error = e.what();
    return std::nullopt;
  } catch (const YAML::Exception& e) {
    if (error) {
      *error = source;
      if (positions && e.mark.line >= 0) {
        *error += ":" + std::to_string(e.mark.line + 1) + ":" + std::to_string(e.mark.column + 1);
      }
      *error += ": " + e.msg;
    }
    return std::nullopt;
  }
  if (config.tracker.dense.finest_level >= config.tracker.dense.pyramid_levels) {
    if (error) {
      *error = source + ": tracker.dense.finest_level (" + std::to_string(config.tracker.dense.finest_level) +
               ") must be below tracker.dense.pyramid_levels (" +
               std::to_string(config.tracker.dense.pyramid_levels) + ")";
    }
    return std::nullopt;
  }
  if (config.tracker.orb.min_depth >= config.tracker.orb.max_depth) {
    if (error) *error = source + ": tracker.orb.min_depth must be below tracker.orb.max_depth";
    return std::nullopt;
  }
  if (!config.tracker.use_features && !config.tracker.use_dense) {
    if (error) *error = source + ": tracker.use_features and tracker.use_dense are both false";
    return std::nullopt;
  }
  return config;
}

std::optional<TrackingConfig> load_tracking_config(const std::string& path, std::string* error) {
  std::ifstream in(path);
  if (!in) {
    if (error) *error = path + ": cannot open the file";
    return std::nullopt;
  }
  std::stringstream text;
  text << in.rdbuf();
  return parse_tracking_config(text.str(), path, error);
}

std::string tracking_config_to_yaml(const TrackingConfig& config) {
  TrackingConfig copy = config;  // the schema points into a mutable config
  std::ostringstream out;
  write_section(out, schema(copy), 0);
  return out.str();
}

}  // namespace dqo::tracking
