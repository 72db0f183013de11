// The training engine's resident map (cuda/train/resident_map.h) against the host's own
// bookkeeping (skipped without a GPU): a map and an optimiser state with random contents go
// through rounds of what the trainer does between batches — removals (GaussianMap::remove_if and
// GaussianAdam::remove_if on the host, remove_if on the device with the same mask), appends,
// new stable flags and object IDs — and after each sync_up() every device array equals the
// host's, bit for bit, having sent the flags whole only where the host changed them.

#include <gtest/gtest.h>

#include <cstring>
#include <random>

#include "../../cuda/train/resident_map.h"
#include "../gaussians/raster_test_util.h"
#include "dqo_map/cuda/device_info.h"
#include "dqo_map/gaussians/removal_plan.h"

namespace dqo::cuda {
namespace {

using gs::testing::uniform;

gs::GaussianInit random_gaussian(std::mt19937_64& rng) {
  gs::GaussianInit g;
  g.position = Eigen::Vector3f(uniform(rng, -3, 3), uniform(rng, -3, 3), uniform(rng, 0, 5));
  g.log_scale = Eigen::Vector3f(uniform(rng, -5, -2), uniform(rng, -5, -2), uniform(rng, -5, -2));
  g.rotation = Eigen::Vector4f(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
  g.colour = Eigen::Vector3f(uniform(rng, 0, 1), uniform(rng, 0, 1), uniform(rng, 0, 1));
  g.object_id = static_cast<uint32_t>(rng() % 4);
  g.type = rng() % 5 == 0 ? gs::GaussianType::kTransparent : gs::GaussianType::kOpaque;
  return g;
}

// Random optimiser state for Gaussians [from, n) (the host's appends start at zero; random values
// show that the device takes the host's, whatever they are).
void randomise_state(gs::GaussianMap* map, gs::GaussianAdam* adam, size_t from, std::mt19937_64& rng) {
  adam->resize_for(*map);
  gs::GaussianAdam::State& st = adam->mutable_state();
  for (gs::GaussianAdam::Moments* m : {&st.position, &st.log_scale, &st.rotation, &st.colour}) {
    const size_t width = m->m.size() / map->size();
    for (size_t k = from * width; k < m->m.size(); ++k) {
      m->m[k] = static_cast<float>(uniform(rng, -1, 1));
      m->v[k] = static_cast<float>(uniform(rng, 0, 1));
    }
  }
  for (size_t i = from; i < map->size(); ++i) {
    st.steps[i] = static_cast<uint32_t>(rng() % 1000);
    map->confidences()[i] = static_cast<float>(st.steps[i]);
  }
}

template <typename T>
bool bits_equal(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

void expect_same(const detail::ResidentMap& resident, const gs::GaussianMap& map, const gs::GaussianAdam& adam,
                 cudaStream_t stream, const std::string& where) {
  ASSERT_TRUE(resident.valid()) << where;
  ASSERT_EQ(resident.count(), map.size()) << where;
  const detail::ResidentMap::HostCopy d = resident.download_all(stream);
  EXPECT_TRUE(bits_equal(d.position, map.positions())) << where;
  EXPECT_TRUE(bits_equal(d.log_scale, map.log_scales())) << where;
  EXPECT_TRUE(bits_equal(d.rotation, map.rotations())) << where;
  EXPECT_TRUE(bits_equal(d.colour, map.colours())) << where;
  EXPECT_TRUE(bits_equal(d.confidence, map.confidences())) << where;
  EXPECT_TRUE(bits_equal(d.opacity, map.opacities())) << where;
  EXPECT_TRUE(bits_equal(d.object_id, map.object_ids_per_gaussian())) << where;
  EXPECT_TRUE(bits_equal(d.stable, map.stable())) << where;
  EXPECT_TRUE(bits_equal(d.type, map.types())) << where;
  const gs::GaussianAdam::State& st = adam.state();
  const gs::GaussianAdam::Moments* m[4] = {&st.position, &st.log_scale, &st.rotation, &st.colour};
  for (int a = 0; a < 4; ++a) {
    EXPECT_TRUE(bits_equal(d.m[a], m[a]->m)) << where << ", first moments of attribute " << a;
    EXPECT_TRUE(bits_equal(d.v[a], m[a]->v)) << where << ", second moments of attribute " << a;
  }
  EXPECT_TRUE(bits_equal(d.steps, st.steps)) << where;
}

TEST(ResidentMap, FollowsTheHostsRemovalsAppendsAndFlags) {
  if (!gpu_available()) GTEST_SKIP() << "no GPU";
  cudaStream_t stream = nullptr;
  ASSERT_EQ(cudaStreamCreate(&stream), cudaSuccess);
  for (uint64_t seed : {1u, 2u, 3u}) {
    std::mt19937_64 rng(seed);
    gs::GaussianMap map;
    gs::GaussianAdam adam;
    for (int i = 0; i < 5000; ++i) map.add(random_gaussian(rng));
    randomise_state(&map, &adam, 0, rng);
    detail::ResidentMap resident;
    resident.sync_up(map, adam, stream);
    expect_same(resident, map, adam, stream, "seed " + std::to_string(seed) + ", first upload");
    for (int round = 0; round < 6; ++round) {
      const std::string where = "seed " + std::to_string(seed) + ", round " + std::to_string(round);
      // Round 2 appends before it removes (the relabelling moves Gaussians so): the mask then
      // also covers Gaussians the device has not seen.
      const bool append_first = round == 2;
      const size_t before = map.size();  // all on the device
      if (append_first)
        for (int i = 0; i < 300; ++i) map.add(random_gaussian(rng));
      std::vector<uint8_t> remove(map.size(), 0);
      const double rate = round == 4 ? 0.0 : 0.05 + 0.1 * round;  // round 4 removes nothing
      for (uint8_t& r : remove) r = uniform(rng, 0, 1) < rate;
      adam.resize_for(map);
      map.remove_if(remove);
      adam.remove_if(remove);
      resident.remove(gs::plan_removal(remove), stream);
      if (!append_first)
        for (int i = 0; i < 200 + 100 * round; ++i) map.add(random_gaussian(rng));
      // The device holds the survivors of its `before` Gaussians; the rest are the host's new ones.
      size_t held = 0;
      for (size_t i = 0; i < before; ++i) held += remove[i] ? 0 : 1;
      randomise_state(&map, &adam, held, rng);
      // Odd rounds leave the flags as they were: only the appended Gaussians' go up (the device
      // compacted its own by the removal's plan).
      const bool new_flags = round % 2 == 0;
      if (new_flags) {
        for (size_t i = 0; i < map.size(); ++i) map.stable()[i] = rng() % 3 == 0;
        map.relabel(1, 3);  // an object merged into another
      }
      // What the device still holds after its removal: all it held but the removed, or (round 2,
      // whose mask covers Gaussians it has not seen) the prefix it could keep in the host's order.
      const size_t on_device = resident.count();
      EXPECT_LE(on_device, held) << where;
      resident.sync_up(map, adam, stream);
      expect_same(resident, map, adam, stream, where);
      EXPECT_NE(map.size(), before) << where;
      const size_t appended = map.size() - on_device;
      EXPECT_EQ(resident.bytes_sent_last(),
                appended * detail::ResidentMap::kBytesPerAppended + (new_flags ? map.size() : appended) * 5)
          << where;
      // Nothing changed since: nothing goes up.
      resident.sync_up(map, adam, stream);
      EXPECT_EQ(resident.bytes_sent_last(), 0u) << where;
      // A review's few relabels, applied on the device as on the host: the flags stay current,
      // nothing goes up, the IDs agree. Told with a stale revision, it sends them whole instead.
      std::vector<std::pair<uint32_t, uint32_t>> changes;
      for (size_t i = round; i < map.size(); i += 97) changes.emplace_back(static_cast<uint32_t>(i), 7u + round);
      const bool stale = round == 5;
      const uint64_t flags_before = map.flags_revision();
      ASSERT_GT(map.relabel_each(changes), 0u) << where;
      resident.relabel(map, changes, stale ? flags_before + 12345 : flags_before, stream);
      resident.sync_up(map, adam, stream);
      EXPECT_EQ(resident.bytes_sent_last(), stale ? map.size() * 5 : 0u) << where << ", relabelled";
      expect_same(resident, map, adam, stream, where + ", relabelled");
    }
    // A map changed behind its back (smaller than what it holds): everything goes up again.
    gs::GaussianMap smaller = map.subset({0, 5, 7, 11});
    gs::GaussianAdam fresh;
    randomise_state(&smaller, &fresh, 0, rng);
    resident.sync_up(smaller, fresh, stream);
    expect_same(resident, smaller, fresh, stream, "seed " + std::to_string(seed) + ", smaller map");
    // After invalidate(), a map of the same size is sent whole.
    gs::GaussianMap other;
    for (size_t i = 0; i < smaller.size(); ++i) other.add(random_gaussian(rng));
    randomise_state(&other, &fresh, 0, rng);
    resident.invalidate();
    resident.sync_up(other, fresh, stream);
    expect_same(resident, other, fresh, stream, "seed " + std::to_string(seed) + ", replaced map");
  }
  cudaStreamDestroy(stream);
}

// Moments the host does not keep (the trainer's setting with an engine): the device keeps its
// own through appends and removals, starts the new Gaussians' at zero, and hands a copy back.
TEST(ResidentMap, KeepsTheMomentsTheHostLeavesToIt) {
  if (!gpu_available()) GTEST_SKIP() << "no GPU";
  cudaStream_t stream = nullptr;
  ASSERT_EQ(cudaStreamCreate(&stream), cudaSuccess);
  for (uint64_t seed : {4u, 5u}) {
    const std::string where = "seed " + std::to_string(seed);
    std::mt19937_64 rng(seed);
    gs::GaussianMap map;
    gs::GaussianAdam adam;
    for (int i = 0; i < 3000; ++i) map.add(random_gaussian(rng));
    randomise_state(&map, &adam, 0, rng);
    detail::ResidentMap resident;
    resident.sync_up(map, adam, stream);
    gs::GaussianAdam::State expected = adam.state();  // what the device holds now

    adam.keep_moments_on_host(false);
    EXPECT_TRUE(adam.state().colour.m.empty()) << where;
    // Appended Gaussians: zero moments on the device; the host keeps steps only.
    for (int i = 0; i < 100; ++i) map.add(random_gaussian(rng));
    adam.resize_for(map);
    EXPECT_EQ(adam.state().steps.size(), map.size()) << where;
    EXPECT_TRUE(adam.state().position.m.empty()) << where;
    resident.sync_up(map, adam, stream);
    for (gs::GaussianAdam::Moments* m :
         {&expected.position, &expected.log_scale, &expected.rotation, &expected.colour}) {
      const size_t width = m->m.size() / 3000;
      m->m.resize(map.size() * width, 0.f);
      m->v.resize(map.size() * width, 0.f);
    }
    expected.steps.resize(map.size(), 0u);
    // Removals: the device compacts its moments, the host its steps.
    std::vector<uint8_t> remove(map.size(), 0);
    for (uint8_t& r : remove) r = uniform(rng, 0, 1) < 0.2;
    map.remove_if(remove);
    adam.remove_if(remove);
    resident.remove(gs::plan_removal(remove), stream);
    resident.sync_up(map, adam, stream);
    // The host's removal of the same mask (removal_plan.h, tested on its own in test_map.cpp).
    const gs::RemovalPlan plan = gs::plan_removal(remove);
    const auto keep = [&](std::vector<float>* v, size_t width) { gs::apply_removal(v, width, plan); };
    const size_t width[4] = {3, 3, 4, 3};
    gs::GaussianAdam::Moments* em[4] = {&expected.position, &expected.log_scale, &expected.rotation, &expected.colour};
    for (int a = 0; a < 4; ++a) keep(&em[a]->m, width[a]), keep(&em[a]->v, width[a]);
    // A copy comes back on request, sized for the map, equal to the device's, bit for bit.
    resident.download_optimiser(&adam, stream);
    ASSERT_EQ(cudaStreamSynchronize(stream), cudaSuccess);
    const gs::GaussianAdam::State& st = adam.state();
    const gs::GaussianAdam::Moments* got[4] = {&st.position, &st.log_scale, &st.rotation, &st.colour};
    size_t nonzero = 0;
    for (int a = 0; a < 4; ++a) {
      EXPECT_TRUE(bits_equal(got[a]->m, em[a]->m)) << where << ", first moments of attribute " << a;
      EXPECT_TRUE(bits_equal(got[a]->v, em[a]->v)) << where << ", second moments of attribute " << a;
      for (float x : got[a]->v) nonzero += x != 0.f;
    }
    EXPECT_GT(nonzero, map.size()) << where << ": the random moments survived";
    // The copy is dropped once the map changes again.
    map.add(random_gaussian(rng));
    adam.resize_for(map);
    EXPECT_TRUE(adam.state().rotation.v.empty()) << where;
    gs::MapGradients grad;
    EXPECT_THROW(adam.step(grad, std::vector<uint8_t>(map.size(), 1), &map), std::logic_error) << where;
  }
  cudaStreamDestroy(stream);
}

}  // namespace
}  // namespace dqo::cuda
