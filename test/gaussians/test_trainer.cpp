// The incremental trainer on the `tiny` scene (160x120, no noise) with ground-truth poses and
// instance labels: image quality and object IDs after a few keyframes; stabilisation, pruning
// (stale, oversized, invisible) and state kept in step through relabel and removal.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>

#include "dqo_map/gaussians/math/prune.h"
#include "dqo_map/gaussians/removal_plan.h"
#include "dqo_map/gaussians/render_metrics.h"
#include "dqo_map/gaussians/trainer.h"
#include "dqo_map/sim/renderer.h"
#include "dqo_map/sim/scene_loader.h"

namespace dqo::gs {
namespace {

const sim::Scene& tiny() {
  static const sim::Scene scene = [] {
    std::string error;
    auto s = sim::load_scene(std::string(DQO_SOURCE_DIR) + "/config/scenes/tiny.yaml", {}, &error);
    EXPECT_TRUE(s.has_value()) << error;
    return s ? *s : sim::Scene();
  }();
  return scene;
}

const Frame& tiny_frame(int index) {
  static const sim::Renderer renderer(tiny(), 2);
  static std::vector<Frame> frames(tiny().num_frames());
  static std::vector<bool> done(tiny().num_frames(), false);
  if (!done[index]) {
    frames[index] = renderer.render(index, false);
    done[index] = true;
  }
  return frames[index];
}

TrainingKeyframe keyframe_of(int index) {
  const Frame& f = tiny_frame(index);
  TrainingKeyframe kf;
  kf.id = static_cast<uint32_t>(100 + index);
  kf.camera = tiny().camera;
  kf.T_wc = f.T_wc;
  kf.rgb = f.rgb;
  kf.depth = f.depth;
  kf.labels = labels_from_instance(f.instance);
  return kf;
}

TEST(Trainer, TinyKeyframesReachQualityAndIds) {
  GaussianTrainer::Params params;
  params.iterations = 60;
  GaussianTrainer trainer(params, make_cpu_rasteriser(2));
  const std::vector<int> frames = {0, 1, 2, 3};
  for (const int f : frames) {
    const KeyframeReport r = trainer.add_keyframe(keyframe_of(f));
    // Each iteration trains on a keyframe drawn at random, so single losses jump between views
    // (the newest, still rough, and older, settled ones): the first ten against the last ten.
    ASSERT_EQ(r.losses.size(), static_cast<size_t>(params.iterations));
    double first = 0, last = 0;
    for (int k = 0; k < 10; ++k) first += r.losses[k], last += r.losses[r.losses.size() - 1 - k];
    EXPECT_LT(last, first) << "keyframe " << f;
    EXPECT_EQ(r.num_gaussians, trainer.map().size());
  }
  EXPECT_EQ(trainer.keyframes_seen(), frames.size());
  EXPECT_EQ(trainer.keyframes_stored(), std::min<size_t>(params.window, frames.size()));
  for (const int f : frames) {
    RenderOutput out;
    trainer.render(tiny().camera, tiny_frame(f).T_wc, &out);
    const double p = psnr(out, tiny_frame(f).rgb);
    const double ids = id_agreement(out, tiny_frame(f).instance);
    const double dl1 = depth_l1(out, tiny_frame(f).depth);
    EXPECT_GT(p, 27.0) << "frame " << f;  // ~30 dB measured
    EXPECT_GE(ids, 0.9) << "frame " << f;
    EXPECT_LT(dl1, 0.02) << "frame " << f;  // ~0.8 cm measured
  }
  // Every object of the scene has Gaussians, with its ID.
  for (uint32_t id = 1; id <= 5; ++id) EXPECT_GT(trainer.map().indices_of(id).size(), 20u) << id;
}

// The map a trainer makes does not depend on its rasteriser's thread count, bit for bit: the
// same keyframes on one thread and on three (which split the tiles differently) give the same
// Gaussians, losses and IDs, so a map trained on a robot's cores is the one a test reproduces.
TEST(Trainer, SameMapOnAnyThreadCount) {
  GaussianTrainer::Params params;
  params.iterations = 15;
  GaussianTrainer one(params, make_cpu_rasteriser(1));
  GaussianTrainer three(params, make_cpu_rasteriser(3));
  for (const int f : {0, 2, 4}) {
    const KeyframeReport a = one.add_keyframe(keyframe_of(f));
    const KeyframeReport b = three.add_keyframe(keyframe_of(f));
    ASSERT_EQ(a.losses.size(), b.losses.size());
    EXPECT_EQ(a.losses, b.losses) << "keyframe " << f;
    EXPECT_EQ(a.num_gaussians, b.num_gaussians) << "keyframe " << f;
  }
  const GaussianMap& a = one.map();
  const GaussianMap& b = three.map();
  ASSERT_EQ(a.size(), b.size());
  ASSERT_GT(a.size(), 1000u);
  EXPECT_EQ(a.positions(), b.positions());
  EXPECT_EQ(a.log_scales(), b.log_scales());
  EXPECT_EQ(a.rotations(), b.rotations());
  EXPECT_EQ(a.colours(), b.colours());
  EXPECT_EQ(a.opacities(), b.opacities());
  EXPECT_EQ(a.object_ids_per_gaussian(), b.object_ids_per_gaussian());
}

// Depth-edge pixels of a depth image: some 8-neighbour differs by more than max(5 cm, 3 %).
std::vector<uint8_t> depth_edges(const DepthImage& depth) {
  std::vector<uint8_t> edge(depth.data.size(), 0);
  for (int v = 1; v + 1 < depth.height; ++v)
    for (int u = 1; u + 1 < depth.width; ++u) {
      const float d = depth.at(u, v);
      for (int dv = -1; dv <= 1; ++dv)
        for (int du = -1; du <= 1; ++du) {
          const float dn = depth.at(u + du, v + dv);
          if (d > 0.f && dn > 0.f && std::abs(dn - d) > std::max(0.05f, 0.03f * d))
            edge[static_cast<size_t>(v) * depth.width + u] = 1;
        }
    }
  return edge;
}

// Params::surface_depth changes what render() gives, not what training does: the same keyframes
// make the same map; render() then gives the rasteriser's surface depth, which at the depth edges
// of the keyframes is nearer the measurement than the normalised depth that mixes the two sides.
TEST(Trainer, RendersTheSurfaceDepth) {
  GaussianTrainer::Params params;
  params.iterations = 30;
  params.surface_depth = false;
  GaussianTrainer mixed(params, make_cpu_rasteriser(2));
  params.surface_depth = true;
  GaussianTrainer surface(params, make_cpu_rasteriser(2));
  const std::vector<int> frames = {0, 2};
  for (const int f : frames) {
    mixed.add_keyframe(keyframe_of(f));
    surface.add_keyframe(keyframe_of(f));
  }
  ASSERT_EQ(mixed.map().positions(), surface.map().positions());
  ASSERT_EQ(mixed.map().log_scales(), surface.map().log_scales());

  double edge_mixed = 0.0, edge_surface = 0.0;
  size_t n_edge = 0;
  for (const int f : frames) {
    const Frame& frame = tiny_frame(f);
    RenderOutput a, b, reference;
    mixed.render(tiny().camera, frame.T_wc, &a);
    surface.render(tiny().camera, frame.T_wc, &b);
    RenderSettings settings;
    settings.surface_depth = true;
    surface.rasteriser().forward(surface.map(), tiny().camera, frame.T_wc.inverse(), settings,
                                 &reference, nullptr);
    ASSERT_EQ(b.depth, reference.depth);
    ASSERT_EQ(a.rgb, b.rgb);
    const std::vector<uint8_t> edge = depth_edges(frame.depth);
    for (size_t p = 0; p < edge.size(); ++p) {
      if (!edge[p]) continue;
      edge_mixed += std::abs(a.depth[p] - frame.depth.data[p]);
      edge_surface += std::abs(b.depth[p] - frame.depth.data[p]);
      ++n_edge;
    }
  }
  ASSERT_GT(n_edge, 100u);
  EXPECT_LT(edge_surface, 0.8 * edge_mixed);  // 10.5 → 6.8 cm measured
}

TEST(Trainer, FirstKeyframeCoversTheView) {
  GaussianTrainer::Params params;
  params.iterations = 0;
  GaussianTrainer trainer(params, make_cpu_rasteriser(2));
  const KeyframeReport r = trainer.add_keyframe(keyframe_of(0));
  const int w = tiny().camera.width, h = tiny().camera.height;
  EXPECT_EQ(r.missing_pixels, static_cast<size_t>(w * h));
  EXPECT_EQ(r.added_error, 0u);
  // One Gaussian per stride² pixels with depth in range.
  EXPECT_NEAR(static_cast<double>(r.added_missing), w * h / 4.0, w * h * 0.02);
  RenderOutput out;
  trainer.render(tiny().camera, tiny_frame(0).T_wc, &out);
  size_t covered = 0;
  for (const float a : out.alpha) covered += a > 0.5f ? 1 : 0;
  EXPECT_GT(covered, 0.97 * w * h);
  // Object IDs come from the labels, and a second look at the same view adds (almost) nothing.
  EXPECT_GT(id_agreement(out, tiny_frame(0).instance), 0.9);
  const KeyframeReport again = trainer.add_keyframe(keyframe_of(0));
  EXPECT_LT(again.added_missing, r.added_missing / 100);
  // Untrained (0 iterations), the render still differs in colour here and there: about
  // error_sample_rate of those pixels get a Gaussian.
  EXPECT_LT(again.added_error, 2 * params.error_sample_rate * again.error_pixels + 10);
}

TEST(Trainer, StabilisesAndFreezes) {
  GaussianTrainer::Params params;
  params.iterations = 40;
  params.window = 1;
  params.stable_confidence = 30.f;  // reached within one keyframe by every Gaussian in view
  GaussianTrainer trainer(params, make_cpu_rasteriser(2));
  const KeyframeReport r = trainer.add_keyframe(keyframe_of(0));
  EXPECT_GT(r.became_stable, r.added_missing * 9 / 10);
  EXPECT_EQ(r.num_unstable, r.num_gaussians - r.became_stable);

  // Stable Gaussians do not move when the next keyframe is trained.
  const GaussianMap before = trainer.map();
  const KeyframeReport r2 = trainer.add_keyframe(keyframe_of(1));
  const size_t pruned = r2.pruned_stale + r2.pruned_oversized + r2.pruned_invisible;
  ASSERT_EQ(pruned, 0u);
  size_t checked = 0;
  for (size_t i = 0; i < before.size(); ++i) {
    if (!before.stable()[i]) continue;
    for (int k = 0; k < 3; ++k) {
      ASSERT_EQ(trainer.map().positions()[3 * i + k], before.positions()[3 * i + k]);
      ASSERT_EQ(trainer.map().colours()[3 * i + k], before.colours()[3 * i + k]);
    }
    ++checked;
  }
  EXPECT_GT(checked, 1000u);
}

TEST(Trainer, PrunesStaleUnstableGaussians) {
  GaussianTrainer::Params params;
  params.iterations = 5;
  params.stable_confidence = 1e9f;  // nothing becomes stable
  params.max_unstable_age = 1;      // gone two keyframes after birth
  GaussianTrainer trainer(params, make_cpu_rasteriser(2));
  const size_t born0 = trainer.add_keyframe(keyframe_of(0)).num_gaussians;
  trainer.add_keyframe(keyframe_of(1));
  const KeyframeReport r = trainer.add_keyframe(keyframe_of(2));
  EXPECT_EQ(r.pruned_stale, born0);
  for (const uint32_t b : trainer.map().birth_keyframes()) EXPECT_GE(b, 1u);
}

// The pruning lists its removals per chunk of 65 536 Gaussians and plans the removal from the
// joined list: over a map of several chunks, exactly the stale Gaussians go (tagged by object ID,
// one in three, spread over every chunk), every other one stays.
TEST(Trainer, PruningRemovesExactlyTheStaleAcrossChunks) {
  GaussianTrainer::Params params;
  params.iterations = 0;
  params.stable_confidence = 1e9f;
  params.max_unstable_age = 2;
  params.max_invisible_keyframes = 0;
  GaussianTrainer trainer(params, make_cpu_rasteriser(2));
  for (int k = 0; k < 3; ++k) trainer.add_keyframe(keyframe_of(k % 2));  // keyframes 0, 1, 2
  GaussianMap map = trainer.map();
  const Frame& f = tiny_frame(0);
  std::mt19937 rng(5);
  size_t stale = 0, young = 0;
  for (int i = 0; i < 200000; ++i) {
    GaussianInit g;
    // Behind the camera: they change no render, and no view reviews them.
    const Eigen::Vector3d p_c(std::uniform_real_distribution<double>(-1, 1)(rng),
                              std::uniform_real_distribution<double>(-1, 1)(rng), -1.0);
    g.position = (f.T_wc * p_c).cast<float>();
    g.log_scale = Eigen::Vector3f::Constant(std::log(0.01f));
    const bool old = i % 3 == 0;
    g.object_id = old ? 77 : 78;
    g.birth_keyframe = old ? 0 : 2;
    (old ? stale : young) += 1;
    map.add(g);
  }
  trainer.set_map(map);
  const size_t pruned_stale = trainer.add_keyframe(keyframe_of(1)).pruned_stale;
  // At keyframe 3 those born at 0 are three keyframes old (> 2): gone; those born at 2 stay.
  EXPECT_TRUE(trainer.map().indices_of(77).empty());
  EXPECT_EQ(trainer.map().indices_of(78).size(), young);
  EXPECT_GE(pruned_stale, stale);
}

TEST(Trainer, PrunesOversizedAndInvisibleGaussians) {
  GaussianTrainer::Params params;
  params.iterations = 20;
  params.max_invisible_keyframes = 2;
  // Behind the surface a pixel keeps a few per cent transmittance: the hidden Gaussian below
  // contributes ~0.06, visible ones > 0.3 (1 % quantile).
  params.min_contribution = 0.2f;
  GaussianTrainer trainer(params, make_cpu_rasteriser(2));
  trainer.add_keyframe(keyframe_of(0));

  // One Gaussian far too large, one hidden 5 cm behind the surface seen at the image centre.
  GaussianMap map = trainer.map();
  const Frame& f = tiny_frame(0);
  const PinholeCamera& cam = tiny().camera;
  const int u = cam.width / 2, v = cam.height / 2;
  const double d = f.depth.at(u, v);
  ASSERT_GT(d, 0.3);
  GaussianInit big;
  big.position = (f.T_wc * cam.back_project(u, v, 0.8 * d)).cast<float>();
  big.log_scale = Eigen::Vector3f::Constant(std::log(2.0f));
  big.object_id = 98;
  map.add(big);
  GaussianInit hidden;
  hidden.position = (f.T_wc * cam.back_project(u, v, d + 0.05)).cast<float>();
  hidden.log_scale = Eigen::Vector3f::Constant(std::log(0.002f));
  hidden.object_id = 99;
  for (auto& s : map.stable()) s = 1;  // freeze the rest, so that the view stays as it is
  map.add(hidden);
  trainer.set_map(map);

  const KeyframeReport r1 = trainer.add_keyframe(keyframe_of(0));
  EXPECT_GE(r1.pruned_oversized, 1u);
  EXPECT_TRUE(trainer.map().indices_of(98).empty());
  EXPECT_FALSE(trainer.map().indices_of(99).empty());  // invisible once: not yet
  const KeyframeReport r2 = trainer.add_keyframe(keyframe_of(0));
  EXPECT_TRUE(trainer.map().indices_of(99).empty());
  EXPECT_GE(r2.pruned_invisible, 1u);
  EXPECT_LT(r1.pruned_invisible + r2.pruned_invisible, map.size() / 20);
}

TEST(Trainer, RelabelRemovalAndPoses) {
  GaussianTrainer::Params params;
  params.iterations = 10;
  GaussianTrainer trainer(params, make_cpu_rasteriser(2));
  trainer.add_keyframe(keyframe_of(0));
  const size_t of1 = trainer.map().indices_of(1).size(), of2 = trainer.map().indices_of(2).size();
  ASSERT_GT(of1, 0u);
  EXPECT_EQ(trainer.relabel(1, 2), of1);
  EXPECT_TRUE(trainer.map().indices_of(1).empty());
  EXPECT_EQ(trainer.map().indices_of(2).size(), of1 + of2);

  std::vector<uint8_t> remove(trainer.map().size(), 0);
  for (size_t i = 0; i < remove.size(); i += 2) remove[i] = 1;
  const size_t n = trainer.map().size();
  EXPECT_EQ(trainer.remove_if(remove), (n + 1) / 2);
  EXPECT_TRUE(trainer.set_keyframe_pose(100, tiny_frame(0).T_wc));
  EXPECT_FALSE(trainer.set_keyframe_pose(7, tiny_frame(0).T_wc));
  // The next keyframe trains on the thinned map and refills it.
  const KeyframeReport r = trainer.add_keyframe(keyframe_of(1));
  EXPECT_GT(r.added_missing + r.added_error, 0u);
  EXPECT_EQ(r.num_gaussians, trainer.map().size());
}

// IDs follow the labels: Gaussians of the book returned to the background by mistake take the
// book's ID back after relabel_keyframes keyframes that show them on its pixels.
TEST(Trainer, IdsFollowTheLabels) {
  GaussianTrainer::Params params;
  params.iterations = 20;
  GaussianTrainer trainer(params, make_cpu_rasteriser(2));
  trainer.add_keyframe(keyframe_of(0));
  const size_t book = trainer.map().indices_of(1).size();
  ASSERT_GT(book, 50u);
  GaussianMap map = trainer.map();
  map.relabel(1, 0);
  trainer.set_map(map);
  // The book's pixels now miss their object (ins = 0): new Gaussians of ID 1 are added on a
  // sample of them; the old ones have one keyframe of evidence, not yet enough.
  const KeyframeReport r1 = trainer.add_keyframe(keyframe_of(0));
  EXPECT_LT(r1.relabelled, book / 10);
  const KeyframeReport r2 = trainer.add_keyframe(keyframe_of(0));
  EXPECT_GT(r2.relabelled, book * 8 / 10);
  EXPECT_LT(r2.relabelled, book * 3 / 2);  // hardly any other Gaussian moved
  EXPECT_GT(trainer.map().indices_of(1).size(), book);
}

TEST(Trainer, RejectsImagesOfAnotherSize) {
  GaussianTrainer trainer(GaussianTrainer::Params(), make_cpu_rasteriser(1));
  TrainingKeyframe kf = keyframe_of(0);
  kf.depth = DepthImage(10, 10, 1, 1.f);
  EXPECT_THROW(trainer.add_keyframe(kf), std::invalid_argument);
  kf = keyframe_of(0);
  kf.labels = LabelImage(3, 3, 1, 0u);
  EXPECT_THROW(trainer.add_keyframe(kf), std::invalid_argument);
  EXPECT_TRUE(trainer.map().empty());
}

// The budget: the map holds max_gaussians after each keyframe; what goes is what contributes
// least, object Gaussians weighted up. Against the same run without a budget, the budgeted map
// renders the views nearly as well, and weighting objects keeps more of them.
TEST(Trainer, BudgetKeepsTheMostUsefulGaussians) {
  const std::vector<int> frames = {0, 2, 4, 6, 8, 10, 12, 14, 16, 18};
  auto run = [&](int budget, float object_weight, size_t* object_gaussians, double* psnr_sum) {
    GaussianTrainer::Params params;
    params.iterations = 20;
    params.max_gaussians = budget;
    params.budget_object_weight = object_weight;
    GaussianTrainer trainer(params, make_cpu_rasteriser(2));
    size_t pruned = 0;
    for (const int f : frames) {
      const KeyframeReport r = trainer.add_keyframe(keyframe_of(f));
      pruned += r.pruned_budget;
      if (budget > 0) {
        EXPECT_LE(r.num_gaussians, static_cast<size_t>(budget));
      }
    }
    *object_gaussians = 0;
    for (const uint32_t id : trainer.map().object_ids_per_gaussian()) *object_gaussians += id != 0;
    *psnr_sum = 0.0;
    for (const int f : frames) {
      RenderOutput out;
      trainer.render(tiny().camera, tiny_frame(f).T_wc, &out);
      *psnr_sum += psnr(out, tiny_frame(f).rgb);
    }
    return std::make_pair(trainer.map().size(), pruned);
  };
  size_t objects_free = 0, objects_flat = 0, objects_weighted = 0;
  double psnr_free = 0, psnr_flat = 0, psnr_weighted = 0;
  const size_t unbounded = run(0, 1.f, &objects_free, &psnr_free).first;
  const int budget = static_cast<int>(unbounded * 6 / 10);
  const auto [size_flat, pruned_flat] = run(budget, 1.f, &objects_flat, &psnr_flat);
  const auto [size_weighted, pruned_weighted] = run(budget, 4.f, &objects_weighted, &psnr_weighted);
  EXPECT_EQ(size_flat, static_cast<size_t>(budget));
  EXPECT_EQ(size_weighted, static_cast<size_t>(budget));
  EXPECT_GT(pruned_flat, 0u);
  EXPECT_GT(objects_weighted, objects_flat);
  // 60 % of the Gaussians, chosen by usefulness, cost little image quality (mean over the views).
  std::printf("unbounded %zu Gaussians (%zu of objects), %.2f dB; budget %d: %.2f dB with %zu "
              "of objects, weighted %.2f dB with %zu\n",
              unbounded, objects_free, psnr_free / frames.size(), budget, psnr_flat / frames.size(),
              objects_flat, psnr_weighted / frames.size(), objects_weighted);
  EXPECT_GT(psnr_flat / frames.size(), psnr_free / frames.size() - 2.0);
  EXPECT_GT(psnr_weighted / frames.size(), psnr_free / frames.size() - 2.0);
}

// A CPU stand-in for a backend whose engine keeps the trained attributes on its "device"
// (TrainingEngine::defer_attributes) and whose rasteriser renders that copy while the engine holds
// the map, as the CUDA backend's pair does. Its training moves every Gaussian a fixed way a step
// (x + 1e-3, every 7th's first log-scale + 0.25, confidence + 1): deterministic, so a trainer that
// defers and one that does not must end with the same map to the bit, prunings of the grown ones
// (on the held values: flag_prune) and removals between fetches included.
struct Shadow {
  bool defer_ok = false;  // the engine defers when asked
  bool deferring = false, pending = false, valid = false;
  size_t count = 0;
  const GaussianMap* synced = nullptr;
  uint64_t revision = 0;
  std::vector<float> attr[5];  // position, log-scale, rotation, colour, confidence
  int fetches = 0, removals_pending = 0;
  int fail = 0;  // the next `fail` batches run out of device memory

  static std::vector<float>* host(GaussianMap* m, int a) {
    std::vector<float>* h[5] = {&m->positions(), &m->log_scales(), &m->rotations(), &m->colours(), &m->confidences()};
    return h[a];
  }
  static size_t width(int a) { return a == 2 ? 4 : a == 4 ? 1 : 3; }
  bool holds(const GaussianMap& m) const {
    return valid && synced == &m && revision == m.revision() && count == m.size();
  }
  void sync(const GaussianMap& m) {
    if (!valid || m.size() < count) valid = false, count = 0;
    for (int a = 0; a < 5; ++a) {
      const std::vector<float>& h = *host(const_cast<GaussianMap*>(&m), a);
      attr[a].resize(count * width(a));
      attr[a].insert(attr[a].end(), h.begin() + count * width(a), h.end());
    }
    count = m.size(), valid = true, synced = &m, revision = m.revision();
  }
  void fetch(GaussianMap* m) {
    if (!pending) return;
    for (int a = 0; a < 5; ++a) std::copy(attr[a].begin(), attr[a].end(), host(m, a)->begin());
    pending = false;
    ++fetches;
  }
  // The map as the engine holds it: `m` with the held attributes.
  GaussianMap as_held(const GaussianMap& m) const {
    GaussianMap copy = m;
    for (int a = 0; a < 5; ++a) std::copy(attr[a].begin(), attr[a].end(), host(&copy, a)->begin());
    return copy;
  }
};

class ShadowEngine final : public TrainingEngine {
 public:
  explicit ShadowEngine(std::shared_ptr<Shadow> s) : s_(std::move(s)) {}
  std::vector<double> run(const std::vector<TrainingView>&, const std::vector<TrainingStep>& steps,
                          const TrainingLoss&, GaussianMap* map, GaussianAdam* adam) override {
    adam->resize_for(*map);
    if (s_->fail > 0) {  // as the CUDA engine fails: deferred attributes down, then the copy dropped
      --s_->fail;
      s_->fetch(map);
      s_->valid = false, s_->pending = false;
      for (auto& a : s_->attr) a.clear();
      throw OutOfDeviceMemory("CUDA: gradients: out of memory");
    }
    s_->sync(*map);
    for (size_t k = 0; k < steps.size(); ++k) {
      for (size_t i = 0; i < s_->count; ++i) {
        s_->attr[0][3 * i] += 1e-3f;
        if (i % 7 == 0) s_->attr[1][3 * i] += 0.25f;
        s_->attr[4][i] += 1.f;
      }
    }
    if (s_->deferring) {
      s_->pending = true;
    } else {
      s_->pending = true;
      s_->fetch(map);
      --s_->fetches;
    }
    return std::vector<double>(steps.size(), 0.0);
  }
  void sync(const GaussianMap& map, const GaussianAdam&) override { s_->sync(map); }
  void map_removed(const RemovalPlan& plan) override {
    if (!s_->valid) return;
    if (plan.size != s_->count) {  // the trainer syncs first while attributes are deferred
      EXPECT_FALSE(s_->pending) << "a removal over Gaussians the engine does not hold, its attributes deferred";
      s_->valid = false;
      return;
    }
    s_->removals_pending += s_->pending ? 1 : 0;
    for (int a = 0; a < 5; ++a) apply_removal(&s_->attr[a], Shadow::width(a), plan);
    s_->count = plan.kept;
    s_->synced = nullptr;
  }
  void map_replaced() override { s_->valid = false, s_->pending = false; }
  bool defer_attributes(bool on) override { return s_->deferring = on && s_->defer_ok; }
  void fetch_attributes(GaussianMap* map) override { s_->fetch(map); }
  bool holds(const GaussianMap& map) const override { return s_->holds(map); }
  // The size test on its own values; the invisibility test on the caller's counters (it keeps none).
  bool flag_prune(const GaussianMap& map, float max_log_scale, int max_invisible, float*, uint16_t* invisible,
                  uint8_t*, std::vector<uint8_t>* flags) override {
    if (!s_->holds(map)) return false;
    flags->resize(s_->count);
    for (size_t i = 0; i < s_->count; ++i) {
      (*flags)[i] = (oversized(&s_->attr[1][3 * i], max_log_scale) ? 1 : 0) |
                    (max_invisible > 0 && invisible[i] >= max_invisible ? 2 : 0);
    }
    return true;
  }
  size_t device_bytes() const override { return 0; }

 private:
  std::shared_ptr<Shadow> s_;
};

class ShadowRasteriser final : public Rasteriser {
 public:
  explicit ShadowRasteriser(std::shared_ptr<Shadow> s) : s_(std::move(s)), cpu_(make_cpu_rasteriser(2)) {}
  void forward(const GaussianMap& map, const PinholeCamera& camera, const SE3& T_cw, const RenderSettings& settings,
               RenderOutput* out, std::unique_ptr<RenderState>* state) override {
    if (s_->holds(map)) {
      cpu_->forward(s_->as_held(map), camera, T_cw, settings, out, state);
    } else {
      cpu_->forward(map, camera, T_cw, settings, out, state);
    }
  }
  void backward(const GaussianMap& map, const PinholeCamera& camera, const SE3& T_cw, const RenderSettings& settings,
                const RenderState& state, const OutputGradients& grad_out, MapGradients* grad_map) override {
    // The trainer's review reads the map's values after its backward: they are fetched first.
    EXPECT_FALSE(s_->pending) << "a backward pass over deferred attributes";
    cpu_->backward(map, camera, T_cw, settings, state, grad_out, grad_map);
  }

 private:
  std::shared_ptr<Shadow> s_;
  std::unique_ptr<Rasteriser> cpu_;
};

// A trainer on the stand-in backend (its rasteriser and engine sharing *shadow, made here); defer:
// whether the engine may keep the trained attributes.
std::unique_ptr<GaussianTrainer> shadow_trainer(const GaussianTrainer::Params& p, bool defer,
                                                std::shared_ptr<Shadow>* shadow) {
  *shadow = std::make_shared<Shadow>();
  (*shadow)->defer_ok = defer;
  return std::make_unique<GaussianTrainer>(p, std::make_unique<ShadowRasteriser>(*shadow),
                                           std::make_unique<ShadowEngine>(*shadow));
}

TEST(Trainer, DeferredAttributesGiveTheSameMapAsFetchingEachBatch) {
  GaussianTrainer::Params p;
  p.iterations = 4;
  p.max_scale = 0.2f;  // the grown Gaussians are pruned within a few keyframes
  std::shared_ptr<Shadow> sd, se;
  auto deferred = shadow_trainer(p, true, &sd);
  auto eager = shadow_trainer(p, false, &se);
  ASSERT_TRUE(deferred->uses_engine());
  size_t pruned = 0;
  for (int k = 0; k < 6; ++k) {
    const KeyframeReport a = deferred->add_keyframe(keyframe_of(k));
    const KeyframeReport b = eager->add_keyframe(keyframe_of(k));
    const std::string where = "keyframe " + std::to_string(k);
    ASSERT_EQ(a.num_gaussians, b.num_gaussians) << where;
    EXPECT_EQ(a.pruned_oversized, b.pruned_oversized) << where;
    pruned += a.pruned_oversized;
    // The deferring trainer's host copy is behind (nothing fetched it during the keyframe) ...
    EXPECT_TRUE(sd->pending) << where;
    EXPECT_NE(deferred->structure().positions(), eager->structure().positions()) << where;
    EXPECT_EQ(deferred->structure().object_ids_per_gaussian(), eager->structure().object_ids_per_gaussian())
        << where;
    // ... and map() brings it level, every attribute to the bit; on every other keyframe only, so
    // that removals and appends also meet attributes deferred over two batches.
    if (k % 2 == 1) {
      const GaussianMap& m = deferred->map();
      EXPECT_FALSE(sd->pending) << where;
      EXPECT_EQ(m.positions(), eager->map().positions()) << where;
      EXPECT_EQ(m.log_scales(), eager->map().log_scales()) << where;
      EXPECT_EQ(m.rotations(), eager->map().rotations()) << where;
      EXPECT_EQ(m.colours(), eager->map().colours()) << where;
      EXPECT_EQ(m.confidences(), eager->map().confidences()) << where;
    }
  }
  EXPECT_GT(pruned, 0u) << "the grown Gaussians were to be pruned on the engine's values";
  EXPECT_GT(sd->removals_pending, 0) << "removals were to meet deferred attributes";
  // (This engine has no review of its own: the trainer's host review fetches at the start of a
  // keyframe, after which the batch, the pruning and its removal run on deferred attributes.)
  EXPECT_EQ(se->fetches, 0);
}

// Out of device memory with the attributes deferred: a failed batch brings them down before the
// engine drops its copy — idle iterations (optimise()) that fail after others left their result
// on the device, and a keyframe's batch, after which the trainer shrinks the map (its removal
// sends the whole map again) and trains; the map stays the one a trainer that fetches after every
// batch ends with, to the bit.
TEST(Trainer, DeferredAttributesSurviveRunningOutOfDeviceMemory) {
  GaussianTrainer::Params p;
  p.iterations = 4;
  std::shared_ptr<Shadow> sd, se;
  auto deferred = shadow_trainer(p, true, &sd);
  auto eager = shadow_trainer(p, false, &se);
  for (int k = 0; k < 5; ++k) {
    const std::string where = "keyframe " + std::to_string(k);
    if (k == 2) {
      deferred->optimise(3), eager->optimise(3);
      EXPECT_TRUE(sd->pending) << "idle iterations left on the device";
      sd->fail = se->fail = 1;
      EXPECT_THROW(deferred->optimise(3), OutOfDeviceMemory);
      EXPECT_THROW(eager->optimise(3), OutOfDeviceMemory);
    }
    if (k == 3) sd->fail = se->fail = 1;
    const KeyframeReport a = deferred->add_keyframe(keyframe_of(k));
    const KeyframeReport b = eager->add_keyframe(keyframe_of(k));
    EXPECT_EQ(a.pruned_memory, b.pruned_memory) << where;
    EXPECT_EQ(a.device_error.empty(), k != 3) << where << ": " << a.device_error;
    EXPECT_EQ(a.iterations, p.iterations) << where << ": trained after shrinking";
    ASSERT_EQ(a.num_gaussians, b.num_gaussians) << where;
  }
  EXPECT_GT(eager->map().size(), 0u);
  const GaussianMap& m = deferred->map();
  EXPECT_EQ(m.positions(), eager->map().positions());
  EXPECT_EQ(m.log_scales(), eager->map().log_scales());
  EXPECT_EQ(m.confidences(), eager->map().confidences());
  EXPECT_EQ(m.object_ids_per_gaussian(), eager->map().object_ids_per_gaussian());
}

// A training engine whose device runs out of memory the next `fail` times it is asked (run()
// throws OutOfDeviceMemory as the CUDA engine does); otherwise it trains nothing (losses of 0).
class FullDeviceEngine final : public TrainingEngine {
 public:
  int fail = 0, failures = 0;
  size_t size_at_failure = 0;
  std::vector<double> run(const std::vector<TrainingView>&, const std::vector<TrainingStep>& steps,
                          const TrainingLoss&, GaussianMap* map, GaussianAdam*) override {
    if (fail > 0) {
      --fail;
      ++failures;
      size_at_failure = map->size();
      throw OutOfDeviceMemory("CUDA: gradients: out of memory");
    }
    return std::vector<double>(steps.size(), 0.0);
  }
  size_t device_bytes() const override { return 0; }
};

TEST(Trainer, OutOfDeviceMemoryShrinksTheMapAndGoesOn) {
  GaussianTrainer::Params p;
  p.iterations = 5;
  auto engine = std::make_unique<FullDeviceEngine>();
  FullDeviceEngine* device = engine.get();
  GaussianTrainer trainer(p, make_cpu_rasteriser(2), std::move(engine));
  ASSERT_TRUE(trainer.uses_engine());
  const KeyframeReport first = trainer.add_keyframe(keyframe_of(0));
  EXPECT_TRUE(first.device_error.empty());
  // The next step fails once: a quarter of the map goes (least useful first), and the step runs.
  device->fail = 1;
  const KeyframeReport second = trainer.add_keyframe(keyframe_of(1));
  EXPECT_EQ(device->failures, 1);
  EXPECT_NE(second.device_error.find("out of memory"), std::string::npos) << second.device_error;
  EXPECT_EQ(second.pruned_memory, device->size_at_failure / 4);
  EXPECT_EQ(second.iterations, p.iterations) << "trained after shrinking";
  EXPECT_EQ(trainer.adam_state().steps.size(), trainer.map().size()) << "optimiser state in step with the map";
  // A device that fails again after shrinking: the keyframe is kept without training, nothing
  // throws.
  device->fail = 2;
  KeyframeReport third;
  EXPECT_NO_THROW(third = trainer.add_keyframe(keyframe_of(2)));
  EXPECT_FALSE(third.device_error.empty());
  EXPECT_EQ(third.iterations, 0);
  EXPECT_EQ(trainer.keyframes_stored(), 3u);
}
}  // namespace
}  // namespace dqo::gs
