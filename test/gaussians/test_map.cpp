// GaussianMap: attributes stored as given, object IDs preserved through add, prune (remove_if),
// relabel and merge, the per-object index kept right after each.

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>
#include <stdexcept>
#include <vector>

#include "dqo_map/gaussians/gaussian_map.h"
#include "dqo_map/gaussians/removal_plan.h"

namespace dqo::gs {
namespace {

GaussianInit with_id(uint32_t id, float x, GaussianType type = GaussianType::kOpaque) {
  GaussianInit g;
  g.position = Eigen::Vector3f(x, 2 * x, 3 * x);
  g.object_id = id;
  g.type = type;
  g.birth_keyframe = static_cast<uint32_t>(x);
  return g;
}

// Every Gaussian's ID agrees with the one its position was made with (x encodes the ID here), and
// indices_of lists exactly the Gaussians of each ID in index order.
void expect_consistent(const GaussianMap& map) {
  const auto& ids = map.object_ids_per_gaussian();
  for (uint32_t id : map.object_ids()) {
    std::vector<uint32_t> expected;
    for (size_t i = 0; i < map.size(); ++i)
      if (ids[i] == id) expected.push_back(static_cast<uint32_t>(i));
    EXPECT_EQ(map.indices_of(id), expected) << "object " << id;
  }
  size_t total = 0;
  for (uint32_t id : map.object_ids()) total += map.indices_of(id).size();
  EXPECT_EQ(total, map.size());
}

TEST(GaussianMap, AddStoresAttributesAndTypeOpacity) {
  GaussianMap map;
  GaussianInit g = with_id(4, 1.f);
  g.rotation = Eigen::Vector4f(0.5f, 0.5f, -0.5f, 0.5f);
  g.colour = Eigen::Vector3f(0.1f, 0.2f, 0.3f);
  g.log_scale = Eigen::Vector3f(-3.f, -4.f, -5.f);
  EXPECT_EQ(map.add(g), 0u);
  EXPECT_EQ(map.add(with_id(4, 2.f, GaussianType::kTransparent)), 1u);
  GaussianInit explicit_opacity = with_id(5, 3.f);
  explicit_opacity.opacity = 0.42f;
  EXPECT_EQ(map.add(explicit_opacity), 2u);
  ASSERT_EQ(map.size(), 3u);
  EXPECT_EQ(map.positions()[0], 1.f);
  EXPECT_EQ(map.positions()[5], 6.f);
  EXPECT_EQ(map.rotations()[2], -0.5f);
  EXPECT_EQ(map.colours()[2], 0.3f);
  EXPECT_EQ(map.log_scales()[1], -4.f);
  EXPECT_EQ(map.opacities()[0], kOpaqueOpacity);
  EXPECT_EQ(map.opacities()[1], kTransparentOpacity);
  EXPECT_EQ(map.opacities()[2], 0.42f);
  EXPECT_EQ(map.types()[1], static_cast<uint8_t>(GaussianType::kTransparent));
  EXPECT_EQ(map.birth_keyframes()[2], 3u);
  EXPECT_EQ(map.confidences()[0], 0.f);
  EXPECT_EQ(map.stable()[0], 0);
  EXPECT_EQ(map.object_ids(), (std::vector<uint32_t>{4, 5}));
  EXPECT_EQ(map.indices_of(4), (std::vector<uint32_t>{0, 1}));
  EXPECT_TRUE(map.indices_of(99).empty());
}

TEST(GaussianMap, IdsSurviveAddPruneRelabelAndMerge) {
  GaussianMap map;
  // x = 10 * id + k so that each Gaussian's ID can be checked from its position after any change.
  const uint32_t ids[] = {0, 1, 2, 1, 3, 0, 2, 2, 1, 3, 3, 0};
  for (size_t k = 0; k < std::size(ids); ++k) map.add(with_id(ids[k], 10.f * ids[k] + 0.01f * k));
  auto check_ids_match_positions = [&](const std::vector<uint32_t>& relabelled_from,
                                       uint32_t relabelled_to) {
    for (size_t i = 0; i < map.size(); ++i) {
      uint32_t original = static_cast<uint32_t>(map.positions()[3 * i] / 10.f);
      if (std::find(relabelled_from.begin(), relabelled_from.end(), original) !=
          relabelled_from.end())
        original = relabelled_to;
      EXPECT_EQ(map.object_ids_per_gaussian()[i], original) << "gaussian " << i;
    }
  };
  expect_consistent(map);  // builds the index; the next add must keep it right
  map.add(with_id(2, 20.5f));
  expect_consistent(map);
  EXPECT_EQ(map.indices_of(2).size(), 4u);

  // Prune: every other Gaussian.
  std::vector<uint8_t> remove(map.size(), 0);
  for (size_t i = 0; i < remove.size(); i += 2) remove[i] = 1;
  const size_t before = map.size();
  EXPECT_EQ(map.remove_if(remove), (before + 1) / 2);
  EXPECT_EQ(map.size(), before / 2);
  check_ids_match_positions({}, 0);
  expect_consistent(map);
  // Attribute arrays stay aligned with each other.
  for (size_t i = 0; i < map.size(); ++i) {
    EXPECT_EQ(map.positions()[3 * i + 1], 2 * map.positions()[3 * i]);
    EXPECT_EQ(map.birth_keyframes()[i], static_cast<uint32_t>(map.positions()[3 * i]));
  }
  EXPECT_THROW(map.remove_if(std::vector<uint8_t>(map.size() + 1, 0)), std::invalid_argument);

  // Merge object 3 into object 1.
  const size_t n1 = map.indices_of(1).size(), n3 = map.indices_of(3).size();
  ASSERT_GT(n3, 0u);
  EXPECT_EQ(map.relabel(3, 1), n3);
  check_ids_match_positions({3}, 1);
  expect_consistent(map);
  EXPECT_EQ(map.indices_of(1).size(), n1 + n3);
  EXPECT_TRUE(map.indices_of(3).empty());
  const std::vector<uint32_t> present = map.object_ids();
  EXPECT_EQ(std::count(present.begin(), present.end(), 3u), 0);

  // Return object 2 to the background.
  const size_t n0 = map.indices_of(0).size(), n2 = map.indices_of(2).size();
  EXPECT_EQ(map.relabel(2, 0), n2);
  expect_consistent(map);
  EXPECT_EQ(map.indices_of(0).size(), n0 + n2);
  EXPECT_EQ(map.relabel(42, 1), 0u);
  EXPECT_EQ(map.relabel(1, 1), 0u);
  EXPECT_EQ(map.object_ids(), (std::vector<uint32_t>{0, 1}));

  // Add after relabel, then prune one object completely.
  map.add(with_id(9, 90.f));
  expect_consistent(map);
  std::vector<uint8_t> drop(map.size(), 0);
  for (uint32_t i : map.indices_of(1)) drop[i] = 1;
  map.remove_if(drop);
  expect_consistent(map);
  EXPECT_TRUE(map.indices_of(1).empty());
  EXPECT_EQ(map.indices_of(9).size(), 1u);
}

// The per-object counts (taken by runs over threads) against a plain count, on a map of runs that
// relabelling in place has split, large enough for several chunks.
TEST(GaussianMap, CountsByObjectMatchAPlainCount) {
  std::mt19937 rng(8);
  GaussianMap map;
  while (map.size() < 300000) {
    const uint32_t id = rng() % 7;
    const size_t run = 1 + rng() % 5000;
    for (size_t k = 0; k < run; ++k) map.add(with_id(id, 1.f));
  }
  std::vector<std::pair<uint32_t, uint32_t>> changes;
  for (size_t i = 0; i < map.size(); ++i) {
    if (rng() % 50 == 0) changes.emplace_back(static_cast<uint32_t>(i), 10 + rng() % 3);
  }
  map.relabel_each(changes);
  std::map<uint32_t, size_t> expected;
  for (uint32_t id : map.object_ids_per_gaussian()) ++expected[id];
  EXPECT_EQ(map.counts_by_object(), expected);
  std::vector<uint32_t> ids;
  for (const auto& [id, count] : expected) ids.push_back(id);
  EXPECT_EQ(map.object_ids(), ids);
  EXPECT_TRUE(GaussianMap().counts_by_object().empty());
}

// A removal keeps exactly the unremoved entries, moves none that sit below the new size, and
// moves as many as it removed there; checked against a plain set difference on random masks.
TEST(RemovalPlan, KeepsTheSurvivorsAndMovesOnlyIntoHoles) {
  std::mt19937 rng(3);
  for (int trial = 0; trial < 200; ++trial) {
    const size_t n = std::uniform_int_distribution<size_t>(0, 60)(rng);
    const double p = std::uniform_real_distribution<double>(0.0, 1.0)(rng);
    std::vector<uint8_t> remove(n);
    std::vector<int> values(2 * n), survivors;
    for (size_t i = 0; i < n; ++i) {
      remove[i] = std::bernoulli_distribution(p)(rng) ? 1 : 0;
      values[2 * i] = static_cast<int>(i), values[2 * i + 1] = -static_cast<int>(i);  // width 2
      if (!remove[i]) survivors.push_back(static_cast<int>(i));
    }
    const RemovalPlan plan = plan_removal(remove);
    ASSERT_EQ(plan.kept, survivors.size());
    ASSERT_EQ(plan.holes.size(), plan.sources.size());
    apply_removal(&values, 2, plan);
    ASSERT_EQ(values.size(), 2 * plan.kept);
    std::vector<int> got;
    for (size_t j = 0; j < plan.kept; ++j) {
      EXPECT_EQ(values[2 * j + 1], -values[2 * j]) << "an entry's values split";
      if (!remove[j]) {
        EXPECT_EQ(values[2 * j], static_cast<int>(j)) << "a survivor below the new size moved";
      }
      got.push_back(values[2 * j]);
    }
    std::sort(got.begin(), got.end());
    EXPECT_EQ(got, survivors) << "trial " << trial;
  }
}

// The plan made from the list of removed indices (the pruning's, without a pass over a mask) is
// the mask's, entry for entry; a list out of order or out of range is refused.
TEST(RemovalPlan, FromTheRemovedIndicesIsTheMasks) {
  std::mt19937 rng(4);
  for (int trial = 0; trial < 300; ++trial) {
    const size_t n = std::uniform_int_distribution<size_t>(0, 80)(rng);
    const double p = std::uniform_real_distribution<double>(0.0, 1.0)(rng);
    std::vector<uint8_t> remove(n);
    std::vector<uint32_t> removed;
    for (size_t i = 0; i < n; ++i) {
      remove[i] = std::bernoulli_distribution(p)(rng) ? 1 : 0;
      if (remove[i]) removed.push_back(static_cast<uint32_t>(i));
    }
    const RemovalPlan from_mask = plan_removal(remove), from_list = plan_removal(removed, n);
    EXPECT_EQ(from_list.size, n);
    EXPECT_EQ(from_list.kept, from_mask.kept) << "trial " << trial;
    EXPECT_EQ(from_list.removed(), removed.size());
    EXPECT_EQ(from_list.holes, from_mask.holes) << "trial " << trial;
    EXPECT_EQ(from_list.sources, from_mask.sources) << "trial " << trial;
  }
  EXPECT_THROW(plan_removal(std::vector<uint32_t>{3, 1}, 5), std::invalid_argument);
  EXPECT_THROW(plan_removal(std::vector<uint32_t>{1, 1}, 5), std::invalid_argument);
  EXPECT_THROW(plan_removal(std::vector<uint32_t>{5}, 5), std::invalid_argument);
}

TEST(GaussianMap, BytesUsed) {
  GaussianMap map;
  EXPECT_EQ(map.bytes_used(), 0u);
  map.reserve(1000);
  for (int i = 0; i < 1000; ++i) map.add(with_id(1, float(i)));
  // 3 + 3 + 4 + 3 + 1 + 1 floats, two uint32 and two bytes per Gaussian: 70 bytes.
  EXPECT_EQ(map.bytes_used(), 1000u * 70u);
}

// The revision stamp that tells a device copy whether it still shows this map: new on every add,
// removal and relabelling that changes something, different for every copy, unchanged by reads
// and by no-op edits.
TEST(GaussianMap, RevisionChangesWithEveryStructuralEdit) {
  GaussianMap map;
  const uint64_t empty = map.revision();
  GaussianInit g;
  g.object_id = 2;
  map.add(g);
  map.add(g);
  const uint64_t two = map.revision();
  EXPECT_NE(two, empty);
  EXPECT_EQ(map.size(), 2u);
  EXPECT_EQ(map.revision(), two) << "reads change nothing";
  EXPECT_EQ(map.relabel(5, 6), 0u);
  EXPECT_EQ(map.remove_if({0, 0}), 0u);
  EXPECT_EQ(map.revision(), two) << "edits that change nothing keep it";
  EXPECT_EQ(map.relabel(2, 3), 2u);
  const uint64_t relabelled = map.revision();
  EXPECT_NE(relabelled, two);
  EXPECT_EQ(map.relabel_each({{0, 3}, {1, 3}}), 0u) << "already 3";
  EXPECT_EQ(map.revision(), relabelled);
  EXPECT_EQ(map.relabel_each({{1, 4}}), 1u);
  EXPECT_NE(map.revision(), relabelled);
  EXPECT_EQ(map.object_ids_per_gaussian(), (std::vector<uint32_t>{3, 4})) << "only the listed one";
  EXPECT_THROW(map.relabel_each({{0, 5}, {2, 1}}), std::invalid_argument);
  EXPECT_EQ(map.object_ids_per_gaussian(), (std::vector<uint32_t>{3, 4})) << "nothing changed before the throw";
  const uint64_t each = map.revision();
  EXPECT_EQ(map.remove_if({1, 0}), 1u);
  EXPECT_NE(map.revision(), each);
  EXPECT_EQ(map.object_ids_per_gaussian(), (std::vector<uint32_t>{4}));
  // Copies and assignments are other maps, even with the same contents.
  GaussianMap copy = map;
  EXPECT_NE(copy.revision(), map.revision());
  GaussianMap moved = std::move(copy);
  EXPECT_NE(moved.revision(), map.revision());
  const uint64_t before = map.revision();
  map = moved;
  EXPECT_NE(map.revision(), before);
  EXPECT_NE(map.revision(), moved.revision());
}

// The flags' stamp (a device copy sends the stable flags and object IDs whole only when it moved):
// new on a relabelling that changes something and on any use of the non-const stable(); kept by
// appends, removals, reads through a const map and no-op relabellings.
TEST(GaussianMap, FlagsRevisionChangesWhenFlagsMayHave) {
  GaussianMap map;
  GaussianInit g;
  g.object_id = 2;
  map.add(g);
  map.add(g);
  map.add(g);
  const uint64_t start = map.flags_revision();
  map.add(g);
  EXPECT_EQ(map.remove_if({0, 1, 0, 0}), 1u);
  EXPECT_EQ(map.flags_revision(), start) << "appends and removals: the device follows them itself";
  const GaussianMap& view = map;
  EXPECT_EQ(view.stable().size(), 3u);
  EXPECT_EQ(map.relabel(7, 8), 0u);
  EXPECT_EQ(map.relabel_each({{0, 2}}), 0u);
  EXPECT_EQ(map.flags_revision(), start) << "reads and relabellings that change nothing";
  EXPECT_EQ(map.relabel_each({{0, 5}}), 1u);
  const uint64_t relabelled = map.flags_revision();
  EXPECT_NE(relabelled, start);
  EXPECT_EQ(map.relabel(2, 3), 2u);
  EXPECT_NE(map.flags_revision(), relabelled);
  const uint64_t before_stable = map.flags_revision();
  map.stable()[1] = 1;
  EXPECT_NE(map.flags_revision(), before_stable) << "the non-const stable() may write";
  const GaussianMap copy = map;
  EXPECT_NE(copy.flags_revision(), map.flags_revision()) << "another map";
}

}  // namespace
}  // namespace dqo::gs
