// The tracking configuration: the shipped file equals the defaults, every value survives a round
// trip, and mistakes are reported with file, line and the key's full path.
#include <cstdio>
#include <map>
#include <sstream>
#include <type_traits>
#include <utility>

#include <gtest/gtest.h>

#include "../params_test_util.h"
#include "dqo_map/tracking/params_yaml.h"

namespace {

using dqo::tracking::load_tracking_config;
using dqo::tracking::parse_tracking_config;
using dqo::tracking::tracking_config_to_yaml;
using dqo::tracking::TrackingConfig;

using dqo::test::initialisers;
using dqo::test::keys_per_section;

std::string parse_error(const std::string& text) {
  std::string error;
  EXPECT_FALSE(parse_tracking_config(text, "t.yaml", &error)) << text;
  return error;
}

TEST(ParamsYaml, ShippedFileHoldsTheDefaults) {
  std::string error;
  const auto config = load_tracking_config(std::string(DQO_SOURCE_DIR) + "/config/tracking.yaml", &error);
  ASSERT_TRUE(config) << error;
  EXPECT_EQ(tracking_config_to_yaml(*config), tracking_config_to_yaml(TrackingConfig{}));
}

TEST(ParamsYaml, CoversEveryField) {
  namespace t = dqo::tracking;
  auto keys = keys_per_section(tracking_config_to_yaml(TrackingConfig{}));
  const char* fix = ": a field was added or removed; update the schema in src/tracking/params_yaml.cpp "
                    "and config/tracking.yaml";
  EXPECT_EQ(initialisers<t::OrbParams>(), keys["tracker.orb"]) << "OrbParams" << fix;
  EXPECT_EQ(initialisers<t::DenseParams>(), keys["tracker.dense"]) << "DenseParams" << fix;
  EXPECT_EQ(initialisers<t::PoseOptimiserParams>(), keys["tracker.pose"]) << "PoseOptimiserParams" << fix;
  EXPECT_EQ(initialisers<t::SearchParams>(), keys["tracker.search"]) << "SearchParams" << fix;
  EXPECT_EQ(initialisers<t::KeyframeParams>(), keys["tracker.keyframes"]) << "KeyframeParams" << fix;
  EXPECT_EQ(initialisers<t::LocalBaParams>(), keys["tracker.local_ba"]) << "LocalBaParams" << fix;
  EXPECT_EQ(initialisers<t::RelocParams>(), keys["tracker.reloc"]) << "RelocParams" << fix;
  EXPECT_EQ(initialisers<t::QualityParams>(), keys["tracker.quality"]) << "QualityParams" << fix;
  EXPECT_EQ(initialisers<t::LoopParams>(), keys["tracker.loop"]) << "LoopParams" << fix;
  EXPECT_EQ(initialisers<t::RefineParams>(), keys["tracker.refine"]) << "RefineParams" << fix;
  EXPECT_EQ(initialisers<t::ObjectLandmarkParams>(), keys["tracker.object_landmarks"])
      << "ObjectLandmarkParams" << fix;
  // TrackerParams: its scalar keys plus one per stage section.
  size_t stages = 0;
  for (const auto& [path, n] : keys) stages += path.rfind("tracker.", 0) == 0 ? 1 : 0;
  EXPECT_EQ(initialisers<t::TrackerParams>(), keys["tracker"] + stages) << "TrackerParams" << fix;
  EXPECT_EQ(initialisers<dqo::KeyframeSelectorParams>(), keys["mapping_keyframes"])
      << "KeyframeSelectorParams" << fix;
}

TEST(ParamsYaml, RoundTripsEveryValue) {
  TrackingConfig c;
  c.tracker.use_dense = false;
  c.tracker.orb.num_features = 1234;
  c.tracker.orb.scale_factor = 1.3f;
  c.tracker.orb.min_depth = 0.25;
  c.tracker.dense.iterations[2] = 17;
  c.tracker.dense.colour_weight = 0.123456789;
  c.tracker.pose.rounds = 2;
  c.tracker.keyframes.min_tracked_ratio = 0.75;
  c.tracker.local_ba.enabled = false;
  c.tracker.reloc.min_inliers = 44;
  c.tracker.loop.min_inliers = 77;
  c.tracker.loop.global_ba = false;
  c.tracker.objects.enabled = true;
  c.tracker.objects.box_sigma_px = 7.25;
  c.mapping_keyframes.max_rotation_deg = 7.5;
  c.mapping_keyframes.max_frames = 0;
  const std::string text = tracking_config_to_yaml(c);
  std::string error;
  const auto back = parse_tracking_config(text, "round trip", &error);
  ASSERT_TRUE(back) << error << "\n" << text;
  EXPECT_EQ(tracking_config_to_yaml(*back), text);
  EXPECT_FALSE(back->tracker.use_dense);
  EXPECT_EQ(back->tracker.orb.scale_factor, 1.3f);
  EXPECT_EQ(back->tracker.dense.colour_weight, 0.123456789);
  EXPECT_EQ(back->tracker.dense.iterations[2], 17);
  EXPECT_TRUE(back->tracker.objects.enabled);
  EXPECT_EQ(back->tracker.objects.box_sigma_px, 7.25);
  EXPECT_EQ(back->mapping_keyframes.max_frames, 0);
}

TEST(ParamsYaml, AbsentKeysKeepTheirDefaults) {
  std::string error;
  const auto c = parse_tracking_config("tracker:\n  orb:\n    num_features: 500\nmapping_keyframes: {max_frames: 5}\n",
                                       "t.yaml", &error);
  ASSERT_TRUE(c) << error;
  EXPECT_EQ(c->tracker.orb.num_features, 500);
  EXPECT_EQ(c->tracker.orb.num_levels, TrackingConfig{}.tracker.orb.num_levels);
  EXPECT_EQ(c->mapping_keyframes.max_frames, 5);
  EXPECT_EQ(c->mapping_keyframes.max_rotation_deg, 10.0);
  EXPECT_TRUE(parse_tracking_config("", "empty.yaml", &error)) << error;
  EXPECT_TRUE(parse_tracking_config("tracker:\n", "t.yaml", &error)) << error;
}

TEST(ParamsYaml, UnknownKeyNamesFileLineAndPath) {
  const std::string e = parse_error("tracker:\n  orb:\n    num_featurs: 500\n");
  EXPECT_NE(e.find("t.yaml:3:5:"), std::string::npos) << e;
  EXPECT_NE(e.find("'tracker.orb.num_featurs'"), std::string::npos) << e;
  EXPECT_NE(e.find("num_features"), std::string::npos) << e;  // lists the known keys
  EXPECT_NE(parse_error("trackr: {}\n").find("t.yaml:1:1: unknown key 'trackr'"), std::string::npos);
}

TEST(ParamsYaml, RefusesBadValues) {
  EXPECT_NE(parse_error("tracker: {orb: {num_features: many}}\n").find("'tracker.orb.num_features' must be a number"),
            std::string::npos);
  EXPECT_NE(parse_error("tracker: {orb: {num_features: 2.5}}\n").find("must be an integer"), std::string::npos);
  EXPECT_NE(parse_error("tracker: {orb: {num_features: -1}}\n").find("outside"), std::string::npos);
  EXPECT_NE(parse_error("tracker: {use_dense: maybe}\n").find("true or false"), std::string::npos);
  EXPECT_NE(parse_error("tracker: {dense: {iterations: [1, 2]}}\n").find("list of 4"), std::string::npos);
  EXPECT_NE(parse_error("tracker: {orb: 3}\n").find("'tracker.orb' must be a map"), std::string::npos);
  EXPECT_NE(parse_error("mapping_keyframes: {max_frames: 3}\nmapping_keyframes: {max_frames: 4}\n")
                .find("t.yaml:2:1: 'mapping_keyframes' is given twice"),
            std::string::npos);
  EXPECT_NE(parse_error("tracker: {dense: {pyramid_levels: 2, finest_level: 2}}\n").find("finest_level"),
            std::string::npos);
  EXPECT_NE(parse_error("tracker: {use_dense: false, use_features: false}\n").find("both false"),
            std::string::npos);
  EXPECT_NE(parse_error("tracker: [1, 2\n").find("t.yaml:"), std::string::npos);  // YAML syntax
  EXPECT_NE(parse_error("- 1\n- 2\n").find("the file must be a map"), std::string::npos);
}

TEST(ParamsYaml, WithoutPositionsNamesOnlyTheKey) {
  std::string error;
  EXPECT_FALSE(parse_tracking_config("tracker: {orb: {nfeatures: 3}}", "ROS parameters of /dqo_map/tracking",
                                     &error, {}, false));
  EXPECT_EQ(error.rfind("ROS parameters of /dqo_map/tracking: unknown key 'tracker.orb.nfeatures'", 0), 0u)
      << error;
}

TEST(ParamsYaml, MissingFileIsAnError) {
  std::string error;
  EXPECT_FALSE(load_tracking_config("/nonexistent/tracking.yaml", &error));
  EXPECT_NE(error.find("/nonexistent/tracking.yaml"), std::string::npos);
}

}  // namespace
