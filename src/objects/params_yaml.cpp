#include "dqo_map/objects/params_yaml.h"

#include <cmath>
#include <string>

#include "dqo_map/config/yaml_schema.h"

namespace dqo::objects {
namespace {

using config::Field;
using config::kInf;
using config::make_choice;
using config::Section;

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

double logit_of(double p) { return std::log(p / (1.0 - p)); }

// recall_by_class as one string, "class: recall, class: recall" (a YAML string; the schema has
// no maps).
config::Choice recall_by_class_choice(std::map<std::string, double>* target) {
  return config::Choice{[target](const std::string& text) { return parse_recall_by_class(text, target); },
                        // Quoted: the list holds ': ', which YAML would read as a mapping.
                        [target]() { return "\"" + recall_by_class_to_string(*target) + "\""; },
                        "'class name: recall, ...' with recalls in (0, 1)"};
}

// One table describes every parameter: the shared reader and writer (config/yaml_schema.h) both
// walk it, so that a field added to the table is read and written alike.
Section schema(ObjectMapperParams& p) {
  DetectionFilterParams& f = p.filter;
  VisibilityParams& v = p.visibility;
  AssociationParams& a = p.association;
  MergeParams& m = p.merge;
  LifecycleParams& l = p.lifecycle;
  ExistenceParams& e = l.existence;
  LabelParams& lb = p.labels;
  SurfaceParams& sf = p.surface;
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
                          {"strategy", make_choice(&a.strategy, parse_association_strategy, to_string, "iou, qd, iou+qd")},
                          {"min_iou", &a.min_iou, 0.0, 1.0},
                          {"min_similarity", &a.min_similarity, 0.0, 1.0},
                          {"accept_iou", &a.accept_iou, 0.0, 1.01},
                          {"max_init_views", &a.max_init_views, 3, 1000},
                          {"fine_quadric", make_choice(&a.fine_quadric, parse_fine_quadric, to_string, "boxes, depth")},
                          {"require_same_class", &a.require_same_class},
                      },
                      {Section{"distance",
                               {
                                   {"kind", make_choice(&a.distance.kind, parse_distance_kind, distance_kind_name, "qd, w2")},
                                   {"tau", &a.distance.tau, 1e-9, kInf},
                                   {"wasserstein_c", &a.distance.wasserstein_c, 1e-9, kInf},
                               },
                               {}}}},
              Section{"merge",
                      {
                          {"enabled", &m.enabled},
                          {"min_overlap", &m.min_overlap, 0.0, 1.0},
                          {"max_distance", &m.max_distance, 0.0, kInf},
                          {"min_iou_3d_any_class", &m.min_iou_3d_any_class, 0.0, 1.01},
                          {"max_seen_apart_iou", &m.max_seen_apart_iou, 0.0, 1.0},
                      },
                      {}},
              Section{"surface",
                      {
                          {"enabled", &sf.enabled},
                          {"samples_per_box", &sf.samples_per_box, 0, 1000000},
                          {"min_depth", &sf.min_depth, 0.0, kInf},
                          {"max_depth", &sf.max_depth, 0.0, kInf},
                          {"max_views", &sf.max_views, 1, 100000},
                          {"max_points", &sf.max_points, 1, 100000000},
                          {"ellipsoid_margin", &sf.ellipsoid_margin, 1.0, 10.0},
                          {"min_points", &sf.min_points, 1, 100000000},
                          {"min_extent_ratio", &sf.min_extent_ratio, 0.0, 1.0},
                          {"trim_quantile", &sf.trim_quantile, 0.0, 0.49},
                          {"round_footprint", &sf.round_footprint, 0.0, 1.01},
                          {"support_reach", &sf.support_reach, 0.0, kInf},
                          {"support_band", &sf.support_band, 0.0, kInf},
                          {"support_max_gap", &sf.support_max_gap, 0.0, kInf},
                          {"min_support_points", &sf.min_support_points, 1, 100000000},
                          {"back_plane_max_angle_deg", &sf.back_plane_max_angle_deg, 0.0, 90.0},
                          {"stand_out_distance", &sf.stand_out_distance, 0.0, kInf},
                          {"plane_tolerance", &sf.plane_tolerance, 0.0, kInf},
                          {"ring_explained", &sf.ring_explained, 0.0, 1.0},
                          {"min_stand_out", &sf.min_stand_out, 0.0, 1.0},
                          {"upright_weight", &sf.upright_weight, 0.0, kInf},
                          {"support_weight", &sf.support_weight, 0.0, kInf},
                          {"support_scale", &sf.support_scale, 1e-6, kInf},
                      },
                      {}},
              Section{"labels",
                      {
                          {"rename_margin", &lb.rename_margin, 1.0, kInf},
                          {"top_classes", &lb.top_classes, 1, 1000},
                      },
                      {}},
              Section{"lifecycle",
                      {
                          {"min_box_views", &l.min_box_views, 3, 1000},
                          {"max_depth_disagreement", &l.max_depth_disagreement, 0.0, kInf},
                          {"single_view_fallback", &l.single_view_fallback},
                      },
                      {
                          Section{"existence",
                                  {
                                      {"prior", &e.prior, 1e-6, 1.0 - 1e-6},
                                      {"recall", &e.recall, 1e-3, 1.0 - 1e-3},
                                      {"recall_by_class", recall_by_class_choice(&e.recall_by_class)},
                                      {"false_alarm_rate", &e.false_alarm_rate, 1e-3, 1.0 - 1e-3},
                                      {"supported_miss_weight", &e.supported_miss_weight, 0.0, 1.0},
                                      {"free_space", &e.free_space, -kInf, 0.0},
                                      {"min_surface_fraction", &e.min_surface_fraction, 0.0, 1.0},
                                      {"clear_stand_out", &e.clear_stand_out, 0.0, 1.0},
                                      {"clear_stand_out_if_object", &e.clear_stand_out_if_object, 1e-3, 1.0 - 1e-3},
                                      {"clear_stand_out_if_clutter", &e.clear_stand_out_if_clutter, 1e-3, 1.0 - 1e-3},
                                      {"confirm_probability", &e.confirm_probability, 1e-6, 1.0 - 1e-6},
                                      {"remove_probability", &e.remove_probability, 1e-6, 1.0 - 1e-6},
                                      {"max_log_odds", &e.max_log_odds, 1e-3, 100.0},
                                      {"candidate_max_age_keyframes", &e.candidate_max_age_keyframes, 1, 100000000},
                                  },
                                  {}},
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
                                      {"front_window", &l.depth_init.front_window, 1e-3, 1.0},
                                      {"front_tolerance", &l.depth_init.front_tolerance, 0.0, kInf},
                                      {"max_depth_reach", &l.depth_init.max_depth_reach, 0.0, kInf},
                                      {"min_depth_axis_ratio", &l.depth_init.min_depth_axis_ratio, 0.0, kInf},
                                      {"max_depth_axis_ratio", &l.depth_init.max_depth_axis_ratio, 0.0, kInf},
                                      {"window_samples", &l.depth_init.window_samples, 4, 100000000},
                                      {"box_samples", &l.depth_init.box_samples, 4, 100000000},
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

}  // namespace

std::optional<ObjectMapperParams> parse_object_params(const std::string& text,
                                                      const std::string& source, std::string* error,
                                                      const ObjectMapperParams& base,
                                                      bool positions) {
  ObjectMapperParams params = base;
  if (!config::read_yaml(text, source, positions, schema(params), error)) return std::nullopt;
  auto cross = [&](bool bad, const std::string& message) {
    if (bad && error) *error = source + ": " + message;
    return bad;
  };
  const LifecycleParams& l = params.lifecycle;
  const ExistenceParams& e = l.existence;
  if (cross(l.depth_init.min_depth >= l.depth_init.max_depth,
            "objects.lifecycle.depth_init.min_depth must be below max_depth") ||
      cross(l.depth_init.low_quantile >= l.depth_init.high_quantile,
            "objects.lifecycle.depth_init.low_quantile must be below high_quantile") ||
      cross(params.refinement.min_semi_axis >= params.refinement.max_semi_axis,
            "objects.refinement.min_semi_axis must be below max_semi_axis") ||
      cross(e.remove_probability >= e.confirm_probability,
            "objects.lifecycle.existence.remove_probability must be below confirm_probability") ||
      cross(logit_of(e.prior) + e.log_odds_detected("") <= logit_of(e.remove_probability),
            "objects.lifecycle.existence: a new candidate (prior and one detection) must start above "
            "remove_probability, or every object is removed at once") ||
      cross(params.refinement.min_views > params.refinement.max_views,
            "objects.refinement.min_views must not exceed max_views")) {
    return std::nullopt;
  }
  return params;
}

std::optional<ObjectMapperParams> load_object_params(const std::string& path, std::string* error) {
  std::string text;
  if (!config::read_text_file(path, &text, error)) return std::nullopt;
  return parse_object_params(text, path, error);
}

std::string object_params_to_yaml(const ObjectMapperParams& params) {
  ObjectMapperParams copy = params;  // the schema points into a mutable struct
  return config::write_yaml(schema(copy));
}

}  // namespace dqo::objects
