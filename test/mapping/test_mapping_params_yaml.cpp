// config/mapping.yaml and the strict reader of the mapping stage's parameters.

#include <gtest/gtest.h>

#include <map>
#include <sstream>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

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

// The number of initialisers an aggregate takes: when a field is added to a params struct, this
// changes and the test below says which table to extend.
struct AnyValue {
  template <typename T>
  constexpr operator T() const noexcept;  // never defined: only used in unevaluated contexts
};
template <typename T, typename Seq, typename = void>
struct InitialisableWith : std::false_type {};
template <typename T, size_t... I>
struct InitialisableWith<T, std::index_sequence<I...>,
                         std::void_t<decltype(T{(void(I), AnyValue{})...})>> : std::true_type {};
template <typename T, size_t N = 0>
constexpr size_t initialisers() {
  if constexpr (InitialisableWith<T, std::make_index_sequence<N + 1>>::value) {
    return initialisers<T, N + 1>();
  } else {
    return N;
  }
}

// Scalar keys per section path of the written YAML.
std::map<std::string, size_t> keys_per_section(const std::string& yaml) {
  std::map<std::string, size_t> counts;
  std::vector<std::string> stack;
  std::istringstream in(yaml);
  std::string line;
  while (std::getline(in, line)) {
    const size_t indent = line.find_first_not_of(' ');
    stack.resize(indent / 2);
    const std::string key = line.substr(indent, line.find(':') - indent);
    std::string path;
    for (const auto& s : stack) path += (path.empty() ? "" : ".") + s;
    if (line.back() == ':') {
      stack.push_back(key);
      counts[path.empty() ? key : path + "." + key];
    } else {
      ++counts[path];
    }
  }
  return counts;
}

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
