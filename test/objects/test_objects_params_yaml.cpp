// The object stage's YAML configuration: strict parsing, and config/objects.yaml lists every field.
#include <fstream>
#include <set>
#include <sstream>
#include <gtest/gtest.h>
#include "dqo_map/objects/params_yaml.h"

namespace dqo::objects {
namespace {

const std::string kConfig = std::string(DQO_SOURCE_DIR) + "/config/objects.yaml";

// The key paths of a block-style YAML text (comments stripped): "objects.filter.min_score", ...
std::set<std::string> key_paths(const std::string& text) {
  std::set<std::string> paths;
  std::vector<std::pair<int, std::string>> stack;  // (indent, key)
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    const size_t hash = line.find('#');
    if (hash != std::string::npos) line = line.substr(0, hash);
    const size_t first = line.find_first_not_of(' ');
    const size_t colon = line.find(':');
    if (first == std::string::npos || colon == std::string::npos) continue;
    const int indent = static_cast<int>(first);
    while (!stack.empty() && stack.back().first >= indent) stack.pop_back();
    stack.emplace_back(indent, line.substr(first, colon - first));
    std::string path;
    for (const auto& [i, key] : stack) path += (path.empty() ? "" : ".") + key;
    const bool leaf = line.find_first_not_of(' ', colon + 1) != std::string::npos;
    if (leaf) paths.insert(path);
  }
  return paths;
}

TEST(ObjectParamsYaml, ShippedConfigListsEveryFieldWithTheDefaults) {
  std::string error;
  const auto loaded = load_object_params(kConfig, &error);
  ASSERT_TRUE(loaded) << error;
  EXPECT_EQ(object_params_to_yaml(*loaded), object_params_to_yaml(ObjectMapperParams()));
  std::ifstream in(kConfig);
  std::stringstream text;
  text << in.rdbuf();
  const std::set<std::string> in_file = key_paths(text.str());
  const std::set<std::string> all = key_paths(object_params_to_yaml(ObjectMapperParams()));
  EXPECT_GT(all.size(), 40u);
  for (const std::string& path : all) EXPECT_TRUE(in_file.count(path)) << path << " missing from " << kConfig;
  for (const std::string& path : in_file) EXPECT_TRUE(all.count(path)) << path << " is not a parameter";
}

TEST(ObjectParamsYaml, RoundTripOfChangedValues) {
  ObjectMapperParams p;
  p.filter.min_score = 0.37;
  p.filter.max_detections = 17;
  p.visibility.occlusion_iou = 0.71;
  p.association.strategy = AssociationStrategy::kQd;
  p.association.distance.kind = QuadricDistanceKind::kWasserstein;
  p.association.distance.tau = 2.5;
  p.association.require_same_class = true;
  p.merge.enabled = false;
  p.merge.max_distance = 0.123456789;
  p.lifecycle.existence.candidate_max_age_keyframes = 5;
  p.lifecycle.existence.recall = 0.35;
  p.lifecycle.existence.recall_by_class = {{"refrigerator", 0.3}, {"dining table", 0.25}};
  p.labels.rename_margin = 1.5;
  p.lifecycle.box_init.min_baseline_ratio = 0.07;
  p.lifecycle.depth_init.high_quantile = 0.95;
  p.refinement.max_iterations = 7;
  p.refinement.huber_delta = 0.3;
  p.refine = false;
  const std::string text = object_params_to_yaml(p);
  std::string error;
  const auto back = parse_object_params(text, "generated", &error);
  ASSERT_TRUE(back) << error;
  EXPECT_EQ(object_params_to_yaml(*back), text);
  EXPECT_EQ(back->filter.min_score, 0.37);
  EXPECT_EQ(back->filter.max_detections, 17);
  EXPECT_EQ(back->association.strategy, AssociationStrategy::kQd);
  EXPECT_EQ(back->association.distance.kind, QuadricDistanceKind::kWasserstein);
  EXPECT_TRUE(back->association.require_same_class);
  EXPECT_FALSE(back->merge.enabled);
  EXPECT_EQ(back->merge.max_distance, 0.123456789);
  EXPECT_EQ(back->lifecycle.box_init.min_baseline_ratio, 0.07);
  EXPECT_EQ(back->refinement.max_iterations, 7);
  EXPECT_EQ(back->lifecycle.existence.candidate_max_age_keyframes, 5);
  EXPECT_EQ(back->lifecycle.existence.recall, 0.35);
  EXPECT_EQ(back->lifecycle.existence.recall_by_class, p.lifecycle.existence.recall_by_class);
  EXPECT_EQ(back->labels.rename_margin, 1.5);
  EXPECT_FALSE(back->refine);
}

TEST(ObjectParamsYaml, StrictErrorsNameTheKeyAndPosition) {
  std::string error;
  EXPECT_FALSE(parse_object_params("objects:\n  filter:\n    min_scor: 0.3\n", "f.yaml", &error));
  EXPECT_NE(error.find("f.yaml:3:5"), std::string::npos) << error;
  EXPECT_NE(error.find("objects.filter.min_scor"), std::string::npos) << error;
  EXPECT_FALSE(parse_object_params("objects:\n  filter:\n    min_score: 1.5\n", "f.yaml", &error));
  EXPECT_NE(error.find("objects.filter.min_score"), std::string::npos) << error;
  EXPECT_FALSE(parse_object_params("objects:\n  association:\n    strategy: hungarian\n", "f.yaml", &error));
  EXPECT_NE(error.find("one of iou, qd, iou+qd, got 'hungarian'"), std::string::npos) << error;
  EXPECT_FALSE(parse_object_params("objects:\n  refine: maybe\n", "f.yaml", &error));
  EXPECT_NE(error.find("objects.refine"), std::string::npos) << error;
  EXPECT_FALSE(parse_object_params("objects:\n  merge: {enabled: true, enabled: false}\n", "f.yaml", &error));
  EXPECT_NE(error.find("twice"), std::string::npos) << error;
  EXPECT_FALSE(parse_object_params("objects:\n  lifecycle:\n    existence: {candidate_max_age_keyframes: 2.5}\n",
                                   "f.yaml", &error));
  EXPECT_NE(error.find("integer"), std::string::npos) << error;
  EXPECT_FALSE(parse_object_params("tracker:\n  use_dense: true\n", "f.yaml", &error));
  EXPECT_NE(error.find("unknown key 'tracker'"), std::string::npos) << error;
  EXPECT_FALSE(parse_object_params("objects: [1, 2\n", "f.yaml", &error));
  EXPECT_FALSE(load_object_params("/nonexistent/objects.yaml", &error));
  EXPECT_NE(error.find("/nonexistent/objects.yaml"), std::string::npos);
  EXPECT_FALSE(parse_object_params("objects:\n  lifecycle:\n    existence: {recall_by_class: 'tv 0.3'}\n",
                                   "f.yaml", &error));
  EXPECT_NE(error.find("objects.lifecycle.existence.recall_by_class"), std::string::npos) << error;
  // Cross-field checks.
  EXPECT_FALSE(parse_object_params("objects:\n  lifecycle:\n    existence: {confirm_probability: 0.05}\n",
                                   "f.yaml", &error));
  EXPECT_NE(error.find("remove_probability must be below confirm_probability"), std::string::npos) << error;
  EXPECT_FALSE(parse_object_params("objects:\n  lifecycle:\n    depth_init: {min_depth: 5, max_depth: 1}\n",
                                   "f.yaml", &error));
  // A partial file keeps the other defaults; the `base` it is read over counts.
  ObjectMapperParams base;
  base.filter.min_area_px = 123.0;
  const auto partial = parse_object_params("objects:\n  filter:\n    min_score: 0.4\n", "f.yaml", &error, base);
  ASSERT_TRUE(partial) << error;
  EXPECT_EQ(partial->filter.min_score, 0.4);
  EXPECT_EQ(partial->filter.min_area_px, 123.0);
  const auto strategy = parse_object_params("objects: {association: {strategy: iou}}", "f", &error);
  ASSERT_TRUE(strategy) << error;
  EXPECT_EQ(strategy->association.strategy, AssociationStrategy::kIou);
}

TEST(ObjectParamsYaml, StrategyNames) {
  for (const auto s : {AssociationStrategy::kIou, AssociationStrategy::kQd, AssociationStrategy::kIouQd}) {
    AssociationStrategy back = AssociationStrategy::kIou;
    EXPECT_TRUE(parse_association_strategy(to_string(s), &back));
    EXPECT_EQ(back, s);
  }
  EXPECT_FALSE(parse_association_strategy("IoU", nullptr));
}

}  // namespace
}  // namespace dqo::objects
