#include "dqo_map/objects/params_yaml.h"

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

namespace dqo::objects {
namespace {

// One table describes every parameter: the loader and the writer both walk it, so that a field
// added to the table is read and written alike (the same scheme as tracking/params_yaml.cpp).
using Target =
    std::variant<int*, float*, double*, bool*, AssociationStrategy*, QuadricDistanceKind*, FineQuadric*>;

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

bool parse_distance_kind(const std::string& text, QuadricDistanceKind* kind) {
  if (text == "qd") {
    *kind = QuadricDistanceKind::kQD;
  } else if (text == "w2") {
    *kind = QuadricDistanceKind::kWasserstein;
  } else {
    return false;
  }
  return true;
}

const char* distance_kind_name(QuadricDistanceKind kind) {
  return kind == QuadricDistanceKind::kQD ? "qd" : "w2";
}

Section schema(ObjectMapperParams& p) {
  DetectionFilterParams& f = p.filter;
  VisibilityParams& v = p.visibility;
  AssociationParams& a = p.association;
  MergeParams& m = p.merge;
  LifecycleParams& l = p.lifecycle;
  RefinementParams& r = p.refinement;
  BoxFitParams& b = p.box_fit;
  return Section{
      "",
      {},
      {Section{
          "objects",
          {{"refine", &p.refine}},
          {
              Section{"filter",
                      {
                          {"min_score", &f.min_score, 0.0, 1.0},
                          {"min_area_px", &f.min_area_px, 0.0, kInf},
                          {"max_area_fraction", &f.max_area_fraction, 0.0, 1.0},
                          {"border_margin_px", &f.border_margin_px, 0.0, kInf},
                          {"duplicate_iou_same_class", &f.duplicate_iou_same_class, 0.0, 1.0},
                          {"duplicate_iou_other_class", &f.duplicate_iou_other_class, 0.0, 1.0},
                          {"max_detections", &f.max_detections, 0, 100000},
                      },
                      {}},
              Section{"visibility",
                      {
                          {"min_fraction_in_image", &v.min_fraction_in_image, 0.0, 1.0},
                          {"occlusion_iou", &v.occlusion_iou, 0.0, 1.1},
                          {"near", &v.near, 0.0, kInf},
                      },
                      {}},
              Section{"association",
                      {
                          {"strategy", &a.strategy},
                          {"min_iou", &a.min_iou, 0.0, 1.0},
                          {"min_similarity", &a.min_similarity, 0.0, 1.0},
                          {"max_init_views", &a.max_init_views, 3, 1000},
                          {"fine_quadric", &a.fine_quadric},
                          {"require_same_class", &a.require_same_class},
                      },
                      {Section{"distance",
                               {
                                   {"kind", &a.distance.kind},
                                   {"tau", &a.distance.tau, 1e-9, kInf},
                                   {"wasserstein_c", &a.distance.wasserstein_c, 1e-9, kInf},
                               },
                               {}}}},
              Section{"merge",
                      {
                          {"enabled", &m.enabled},
                          {"min_overlap", &m.min_overlap, 0.0, 1.0},
                          {"max_distance", &m.max_distance, 0.0, kInf},
                      },
                      {}},
              Section{"lifecycle",
                      {
                          {"confirm_observations", &l.confirm_observations, 1, 100000},
                          {"candidate_max_missed", &l.candidate_max_missed, 1, 100000},
                          {"candidate_max_age_keyframes", &l.candidate_max_age_keyframes, 1, 100000000},
                          {"remove_after_missed", &l.remove_after_missed, 0, 100000000},
                          {"min_box_views", &l.min_box_views, 3, 1000},
                          {"single_view_fallback", &l.single_view_fallback},
                      },
                      {
                          Section{"box_init",
                                  {
                                      {"border_margin_px", &l.box_init.border_margin_px, 0.0, kInf},
                                      {"min_baseline_ratio", &l.box_init.min_baseline_ratio, 0.0, kInf},
                                      {"min_axis_ratio", &l.box_init.min_axis_ratio, 0.0, 1.0},
                                      {"max_mean_edge_error_px", &l.box_init.max_mean_edge_error_px, 0.0, kInf},
                                  },
                                  {}},
                          Section{"depth_init",
                                  {
                                      {"min_depth", &l.depth_init.min_depth, 0.0, kInf},
                                      {"max_depth", &l.depth_init.max_depth, 0.0, kInf},
                                      {"low_quantile", &l.depth_init.low_quantile, 0.0, 1.0},
                                      {"high_quantile", &l.depth_init.high_quantile, 0.0, 1.0},
                                      {"min_semi_axis", &l.depth_init.min_semi_axis, 1e-6, kInf},
                                  },
                                  {}},
                      }},
              Section{"refinement",
                      {
                          {"max_iterations", &r.max_iterations, 0, 10000},
                          {"min_views", &r.min_views, 1, 100000},
                          {"max_views", &r.max_views, 1, 100000},
                          {"border_margin_px", &r.border_margin_px, 0.0, kInf},
                          {"min_semi_axis", &r.min_semi_axis, 1e-9, kInf},
                          {"max_semi_axis", &r.max_semi_axis, 1e-9, kInf},
                          {"huber_delta", &r.huber_delta, 1e-9, kInf},
                      },
                      {}},
              Section{"box_fit",
                      {
                          {"enabled", &b.enabled},
                          {"max_iterations", &b.max_iterations, 0, 10000},
                          {"min_views", &b.min_views, 1, 100000},
                          {"max_views", &b.max_views, 1, 100000},
                          {"initial_scale", &b.initial_scale, 1e-3, 10.0},
                          {"huber_delta", &b.huber_delta, 1e-9, kInf},
                          {"upright", &b.upright},
                      },
                      {}},
          }}}};
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
          } else if constexpr (std::is_same_v<T, AssociationStrategy>) {
            if (!node.IsScalar() || !parse_association_strategy(node.Scalar(), target)) {
              fail(node, "'" + path + "' must be iou, qd or iou+qd");
            }
          } else if constexpr (std::is_same_v<T, FineQuadric>) {
            if (!node.IsScalar() || !parse_fine_quadric(node.Scalar(), target)) {
              fail(node, "'" + path + "' must be boxes or depth");
            }
          } else {
            if (!node.IsScalar() || !parse_distance_kind(node.Scalar(), target)) {
              fail(node, "'" + path + "' must be qd or w2");
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
          } else if constexpr (std::is_same_v<T, AssociationStrategy> || std::is_same_v<T, FineQuadric>) {
            out << to_string(*target);
          } else {
            out << distance_kind_name(*target);
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

std::optional<ObjectMapperParams> parse_object_params(const std::string& text,
                                                      const std::string& source, std::string* error,
                                                      const ObjectMapperParams& base,
                                                      bool positions) {
  ObjectMapperParams params = base;
  const Reader reader{source, positions};
  try {
    const YAML::Node root = YAML::Load(text);
    if (root.IsDefined() && !root.IsNull()) reader.read_section(root, "", schema(params));
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
  auto cross = [&](bool bad, const std::string& message) {
    if (bad && error) *error = source + ": " + message;
    return bad;
  };
  const LifecycleParams& l = params.lifecycle;
  if (cross(l.depth_init.min_depth >= l.depth_init.max_depth,
            "objects.lifecycle.depth_init.min_depth must be below max_depth") ||
      cross(l.depth_init.low_quantile >= l.depth_init.high_quantile,
            "objects.lifecycle.depth_init.low_quantile must be below high_quantile") ||
      cross(params.refinement.min_semi_axis >= params.refinement.max_semi_axis,
            "objects.refinement.min_semi_axis must be below max_semi_axis") ||
      cross(params.refinement.min_views > params.refinement.max_views,
            "objects.refinement.min_views must not exceed max_views")) {
    return std::nullopt;
  }
  return params;
}

std::optional<ObjectMapperParams> load_object_params(const std::string& path, std::string* error) {
  std::ifstream in(path);
  if (!in) {
    if (error) *error = path + ": cannot open the file";
    return std::nullopt;
  }
  std::stringstream text;
  text << in.rdbuf();
  return parse_object_params(text.str(), path, error);
}

std::string object_params_to_yaml(const ObjectMapperParams& params) {
  ObjectMapperParams copy = params;  // the schema points into a mutable struct
  std::ostringstream out;
  write_section(out, schema(copy), 0);
  return out.str();
}

}  // namespace dqo::objects
