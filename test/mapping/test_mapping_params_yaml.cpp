// config/mapping.yaml and the strict reader of the mapping stage's parameters.

#include <gtest/gtest.h>

#include <map>
#include <sstream>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "../params_test_util.h"
#include "dqo_map/mapping/params_yaml.h"

namespace dqo::mapping {
namespace {

std::string parse_error(const std::string& text) {
  std::string error;
  EXPECT_FALSE(parse_mapping_params(text, "m.yaml", &error)) << text;
  return error;
}

TEST(MappingParamsYaml, ShippedFileHoldsTheDefaults) {
  std::string error;
  const auto p = load_mapping_params(std::string(DQO_SOURCE_DIR) + "/config/mapping.yaml", &error);
  ASSERT_TRUE(p) << error;
  EXPECT_EQ(mapping_params_to_yaml(*p), mapping_params_to_yaml(GaussianMapperParams{}));
}

TEST(MappingParamsYaml, WrittenTextReadsBackToTheSameValues) {
  GaussianMapperParams p;
  p.backend = Backend::kCpu;
  p.max_gaussians = 12345;
  p.objects_timeout = 0.25;
  p.trainer.iterations = 7;
  p.trainer.adam.lr_colour = 0.0125f;
  p.labels.ellipsoid_scale = 1.5;
  std::string error;
  const auto back = parse_mapping_params(mapping_params_to_yaml(p), "x", &error);
  ASSERT_TRUE(back) << error;
  EXPECT_EQ(back->backend, Backend::kCpu);
  EXPECT_EQ(back->max_gaussians, 12345);
  EXPECT_DOUBLE_EQ(back->objects_timeout, 0.25);
  EXPECT_EQ(back->trainer.iterations, 7);
  EXPECT_FLOAT_EQ(back->trainer.adam.lr_colour, 0.0125f);
  EXPECT_DOUBLE_EQ(back->labels.ellipsoid_scale, 1.5);
  EXPECT_EQ(mapping_params_to_yaml(*back), mapping_params_to_yaml(p));
}

TEST(MappingParamsYaml, PartialFilesKeepTheOtherDefaults) {
  std::string error;
  const auto p = parse_mapping_params("mapping:\n  trainer:\n    window: 5\n", "m.yaml", &error);
  ASSERT_TRUE(p) << error;
  EXPECT_EQ(p->trainer.window, 5);
  EXPECT_EQ(p->trainer.iterations, GaussianMapperParams{}.trainer.iterations);
}

TEST(MappingParamsYaml, StrictErrorsNameTheKey) {
  EXPECT_NE(parse_error("mapping:\n  trainer:\n    itrations: 5\n").find("mapping.trainer.itrations"),
            std::string::npos);
  EXPECT_NE(parse_error("mapping:\n  backend: gpu\n").find("auto, cpu, cuda"), std::string::npos);
  EXPECT_NE(parse_error("mapping:\n  max_queue: -1\n").find("mapping.max_queue"), std::string::npos);
  EXPECT_NE(parse_error("mapping:\n  trainer:\n    min_depth: 6.0\n").find("below max_depth"),
            std::string::npos);
  EXPECT_NE(parse_error("mapping:\n  threads: two\n").find("m.yaml:2"), std::string::npos);
}

using test::initialisers;
using test::keys_per_section;

TEST(MappingParamsYaml, CoversEveryField) {
  auto keys = keys_per_section(mapping_params_to_yaml(GaussianMapperParams{}));
  const char* fix = ": a field was added or removed; update the schema in src/mapping/params_yaml.cpp "
                    "and config/mapping.yaml";
  // GaussianMapperParams: its scalars plus the trainer and labels sections.
  EXPECT_EQ(initialisers<GaussianMapperParams>(), keys["mapping"] + 2) << "GaussianMapperParams" << fix;
  EXPECT_EQ(initialisers<gs::ObjectLabelParams>(), keys["mapping.labels"]) << "ObjectLabelParams" << fix;
  // Trainer: its scalars, the adam section, max_gaussians (mapping.max_gaussians sets it) and the
  // seed, which stays out of the file on purpose (a run is reproducible with the default seed).
  EXPECT_EQ(initialisers<gs::GaussianTrainer::Params>(), keys["mapping.trainer"] + 1 + 2)
      << "GaussianTrainer::Params" << fix;
  // Adam: the learning rates; its β, ε and the two projection switches are the 3DGS constants.
  EXPECT_EQ(initialisers<gs::GaussianAdam::Params>(), keys["mapping.trainer.adam"] + 5)
      << "GaussianAdam::Params" << fix;
}

}  // namespace
}  // namespace dqo::mapping
