#include "dqo_map/mapping/params_yaml.h"

#include "dqo_map/config/yaml_schema.h"

namespace dqo::mapping {
namespace {

using config::Field;
using config::kInf;
using config::make_choice;
using config::Section;

// One table for the reader and the writer (config/yaml_schema.h).
Section schema(GaussianMapperParams& p) {
  gs::GaussianTrainer::Params& t = p.trainer;
  gs::GaussianAdam::Params& a = t.adam;
  gs::ObjectLabelParams& l = p.labels;
  return Section{
      "",
      {},
      {Section{
          "mapping",
          {
              {"backend", make_choice(&p.backend, parse_backend, to_string, "auto, cpu, cuda")},
              {"threads", &p.threads, -1, 1024},
              {"objects_timeout", &p.objects_timeout, 0.0, kInf},
              {"max_queue", &p.max_queue, 0, 1000000},
              {"max_gaussians", &p.max_gaussians, 0, 2000000000},
              {"mesh_views", &p.mesh_views, 1, 10000},
              {"mesh_min_alpha", &p.mesh_min_alpha, 0.0, 1.0},
          },
          {
              Section{"labels",
                      {
                          {"ellipsoid_scale", &l.ellipsoid_scale, 0.1, 10.0},
                          {"min_depth", &l.min_depth, 0.0, kInf},
                          {"max_depth", &l.max_depth, 0.0, kInf},
                      },
                      {}},
              Section{
                  "trainer",
                  {
                      {"missing_transmittance", &t.missing_transmittance, 0.0, 1.0},
                      {"depth_error", &t.depth_error, 0.0, kInf},
                      {"colour_error", &t.colour_error, 0.0, kInf},
                      {"ins_threshold", &t.ins_threshold, 0.0, 1.0},
                      {"missing_stride", &t.missing_stride, 1, 64},
                      {"error_sample_rate", &t.error_sample_rate, 0.0, 1.0},
                      {"min_depth", &t.min_depth, 0.0, kInf},
                      {"max_depth", &t.max_depth, 0.0, kInf},
                      {"scale_factor", &t.scale_factor, 1e-6, kInf},
                      {"flatness", &t.flatness, 1e-6, 1.0},
                      {"max_stretch", &t.max_stretch, 1.0, kInf},
                      {"normal_radius_px", &t.normal_radius_px, 1, 64},
                      {"transparent_for_colour_error", &t.transparent_for_colour_error},
                      {"iterations", &t.iterations, 0, 100000},
                      {"window", &t.window, 1, 100000},
                      {"newest_share", &t.newest_share, -1.0, 1.0},
                      {"lambda_depth", &t.lambda_depth, 0.0, kInf},
                      {"lambda_ins", &t.lambda_ins, 0.0, kInf},
                      {"lambda_ssim", &t.lambda_ssim, 0.0, 1.0},
                      {"normalise_depth", &t.normalise_depth},
                      {"surface_depth", &t.surface_depth},
                      {"surface_gap", &t.surface_gap, 0.0, kInf},
                      {"surface_gap_relative", &t.surface_gap_relative, 0.0, kInf},
                      {"train_per_label", &t.train_per_label},
                      {"stable_confidence", &t.stable_confidence, 0.0, kInf},
                      {"max_unstable_age", &t.max_unstable_age, 0, 1000000},
                      {"max_scale", &t.max_scale, 1e-6, kInf},
                      {"max_invisible_keyframes", &t.max_invisible_keyframes, 0, 1000000},
                      {"min_contribution", &t.min_contribution, 0.0, kInf},
                      {"relabel_fraction", &t.relabel_fraction, 0.0, 1.0},
                      {"relabel_keyframes", &t.relabel_keyframes, 1, 255},
                      {"budget_decay", &t.budget_decay, 0.0, 1.0},
                      {"budget_object_weight", &t.budget_object_weight, 0.0, kInf},
                  },
                  {Section{"adam",
                           {
                               {"lr_position", &a.lr_position, 0.0, kInf},
                               {"lr_log_scale", &a.lr_log_scale, 0.0, kInf},
                               {"lr_rotation", &a.lr_rotation, 0.0, kInf},
                               {"lr_colour", &a.lr_colour, 0.0, kInf},
                               {"lr_opacity", &a.lr_opacity, 0.0, kInf},
                           },
                           {}}}},
          }}}};
}

}  // namespace

std::optional<GaussianMapperParams> parse_mapping_params(const std::string& text,
                                                         const std::string& source,
                                                         std::string* error,
                                                         const GaussianMapperParams& base,
                                                         bool positions) {
  GaussianMapperParams params = base;
  if (!config::read_yaml(text, source, positions, schema(params), error)) return std::nullopt;
  auto cross = [&](bool bad, const std::string& message) {
    if (bad && error) *error = source + ": " + message;
    return bad;
  };
  if (cross(params.trainer.min_depth >= params.trainer.max_depth,
            "mapping.trainer.min_depth must be below max_depth") ||
      cross(params.labels.min_depth >= params.labels.max_depth,
            "mapping.labels.min_depth must be below max_depth")) {
    return std::nullopt;
  }
  return params;
}

std::optional<GaussianMapperParams> load_mapping_params(const std::string& path,
                                                        std::string* error) {
  std::string text;
  if (!config::read_text_file(path, &text, error)) return std::nullopt;
  return parse_mapping_params(text, path, error);
}

std::string mapping_params_to_yaml(const GaussianMapperParams& params) {
  GaussianMapperParams copy = params;
  return config::write_yaml(schema(copy));
}

}  // namespace dqo::mapping
