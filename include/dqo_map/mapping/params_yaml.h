#pragma once
// The mapping stage's configuration as YAML (GaussianMapperParams), read by dqo_map_offline
// --config and by the mapping nodelet; config/mapping.yaml holds the defaults and lists every field.
//
//   mapping:
//     backend: auto | cpu | cuda
//     threads, objects_timeout, max_queue, max_gaussians, mesh_views, mesh_min_alpha
//     labels: {...}   # ObjectLabelParams (the quadric ∩ box rule)
//     trainer: {...}  # GaussianTrainer::Params, with adam: {...}
//
// Strict like the other modules: an unknown key, a key given twice, a value of the wrong type or
// out of range is an error "SOURCE:LINE:COLUMN: message" naming the key's full path, and nothing is
// loaded. Absent keys keep their defaults. yaml-cpp stays in the .cpp file.
#include <optional>
#include <string>

#include "dqo_map/mapping/gaussian_mapper.h"

namespace dqo::mapping {

std::optional<GaussianMapperParams> load_mapping_params(const std::string& path, std::string* error);
std::optional<GaussianMapperParams> parse_mapping_params(const std::string& text,
                                                         const std::string& source,
                                                         std::string* error,
                                                         const GaussianMapperParams& base = {},
                                                         bool positions = true);
// Every parameter, as text that parse_mapping_params reads back to the same values (also what the
// map file's parameter hash is computed over).
std::string mapping_params_to_yaml(const GaussianMapperParams& params);

}  // namespace dqo::mapping
