// Properties of the CPU rasteriser's forward pass: one Gaussian's rendered mass against the
// analytic integral, independence of insertion order, thread-count independence of the images, the
// instance opacity `ins`, the dominant object ID, the depth of a flat wall, the surface depth.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <stdexcept>

#include "dqo_map/gaussians/math/alpha.h"
#include "dqo_map/gaussians/math/composite.h"
#include "dqo_map/gaussians/math/project_gaussian.h"
#include "raster_test_util.h"

namespace dqo::gs {
namespace {

using testing::DoubleGaussians;
using testing::Images;
using testing::render;
using testing::uniform;

GaussianMap random_map(const PinholeCamera& cam, const SE3& T_cw, size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  GaussianMap map;
  for (size_t i = 0; i < n; ++i) {
    GaussianInit g = testing::gaussian_at(cam, T_cw, uniform(rng, -10, cam.width + 10),
                                          uniform(rng, -10, cam.height + 10), uniform(rng, 1, 5),
                                          rng, std::log(0.01), std::log(0.08));
    g.object_id = static_cast<uint32_t>(i % 4);
    g.type = i % 7 == 0 ? GaussianType::kTransparent : GaussianType::kOpaque;
    map.add(g);
  }
  return map;
}

// Σ_pixels α of one faint Gaussian = ∫ o exp(−½ dᵀ Σ⁻¹ d) over the ellipse where α ≥ 1/255, which
// is 2π sqrt(det Σ_2D) (o − 1/255); Σ_2D computed here independently with Eigen (J R Σ Rᵀ Jᵀ +
// 0.3).
TEST(Rasteriser, RenderedMassMatchesTheIntegral) {
  const PinholeCamera cam = testing::make_camera(160, 128, 170.0);
  const SE3 T_cw = testing::test_pose();
  std::mt19937_64 rng(3);
  for (int trial = 0; trial < 3; ++trial) {
    GaussianInit g =
        testing::gaussian_at(cam, T_cw, uniform(rng, 60, 100), uniform(rng, 50, 80),
                             uniform(rng, 1.5, 2.5), rng, std::log(0.03), std::log(0.08));
    const double o = 0.2;  // no saturation, and the α = 1/255 ellipse lies inside the 3σ square
    DoubleGaussians d;
    d.add(g, o);
    RenderSettings settings;
    const Images<double> im = render(d.arrays(), cam, T_cw, settings, 2);
    const double mass = std::accumulate(im.alpha.begin(), im.alpha.end(), 0.0);

    const Eigen::Quaterniond q(d.rotation[0], d.rotation[1], d.rotation[2], d.rotation[3]);
    const Eigen::Matrix3d R = q.normalized().toRotationMatrix();
    const Eigen::Vector3d s(std::exp(d.log_scale[0]), std::exp(d.log_scale[1]),
                            std::exp(d.log_scale[2]));
    const Eigen::Matrix3d cov_w = R * s.cwiseAbs2().asDiagonal() * R.transpose();
    const Eigen::Vector3d p_c = T_cw * Eigen::Vector3d(d.position[0], d.position[1], d.position[2]);
    Eigen::Matrix<double, 2, 3> J;
    J << cam.fx / p_c.z(), 0, -cam.fx * p_c.x() / (p_c.z() * p_c.z()), 0, cam.fy / p_c.z(),
        -cam.fy * p_c.y() / (p_c.z() * p_c.z());
    const Eigen::Matrix2d cov2d =
        J * T_cw.rotation() * cov_w * T_cw.rotation().transpose() * J.transpose() +
        0.3 * Eigen::Matrix2d::Identity();
    const double expected = 2 * M_PI * std::sqrt(cov2d.determinant()) * (o - 1.0 / 255.0);
    EXPECT_NEAR(mass, expected, 2e-3 * expected) << "trial " << trial;
    EXPECT_GT(std::sqrt(cov2d.determinant()), 4.0);  // several pixels wide: the sum is an integral

    // The float backend: same mass.
    GaussianMap map;
    g.opacity = static_cast<float>(o);
    map.add(g);
    RenderOutput out;
    make_cpu_rasteriser(1)->forward(map, cam, T_cw, settings, &out, nullptr);
    const double mass_f = std::accumulate(out.alpha.begin(), out.alpha.end(), 0.0);
    EXPECT_NEAR(mass_f, expected, 2e-3 * expected);
    // A single Gaussian: ins and alpha coincide when it is the requested object's OG.
  }
}

// The plainest renderer the definition allows: every pixel walks all Gaussians in depth order,
// takes those whose 3σ square's tiles hold it, with the shared maths (no bins, no masks, no row
// spans, no loop swap). The rasteriser must agree with it exactly. The surface depth is computed
// here from its definition over the pixel's list of contributors, without the shared maths'
// running form (surface_step).
Images<double> naive_render(const DoubleGaussians& d, const PinholeCamera& cam, const SE3& T_cw,
                            const RenderSettings& settings) {
  CameraView<double> view;
  view.K = {cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height};
  const Eigen::Matrix3d R = T_cw.rotation();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) view.R_cw.m[i][j] = R(i, j);
  view.t_cw = {T_cw.translation().x(), T_cw.translation().y(), T_cw.translation().z()};
  view.near = settings.near;
  struct Entry {
    size_t index;
    ProjectedGaussian<double> p;
    int tx0, ty0, tx1, ty1;
  };
  std::vector<Entry> entries;
  for (size_t i = 0; i < d.size(); ++i) {
    Entry e{i, {}, 0, 0, 0, 0};
    if (!project_gaussian(&d.position[3 * i], &d.log_scale[3 * i], &d.rotation[4 * i], view, &e.p))
      continue;
    const double r = e.p.radius;
    const double x0 = std::max(0.0, std::ceil(e.p.mean2d.x - r));
    const double x1 = std::min(cam.width - 1.0, std::floor(e.p.mean2d.x + r));
    const double y0 = std::max(0.0, std::ceil(e.p.mean2d.y - r));
    const double y1 = std::min(cam.height - 1.0, std::floor(e.p.mean2d.y + r));
    if (x0 > x1 || y0 > y1) continue;
    e.tx0 = int(x0) / 16, e.tx1 = int(x1) / 16, e.ty0 = int(y0) / 16, e.ty1 = int(y1) / 16;
    entries.push_back(e);
  }
  std::stable_sort(entries.begin(), entries.end(),
                   [](const Entry& a, const Entry& b) { return a.p.depth < b.p.depth; });
  Images<double> im;
  const size_t n = static_cast<size_t>(cam.width) * cam.height;
  im.rgb.resize(3 * n);
  im.depth.resize(n);
  im.alpha.resize(n);
  im.ins.resize(n);
  im.dominant_id.resize(n);
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      PixelAccum<double> acc = pixel_accum_start<double>();
      double ins = 0, best = 0;
      uint32_t best_id = 0;
      struct Contribution {
        double alpha, z, t_after;
      };
      std::vector<Contribution> contributions;
      for (const Entry& e : entries) {
        if (x / 16 < e.tx0 || x / 16 > e.tx1 || y / 16 < e.ty0 || y / 16 > e.ty1) continue;
        double alpha, vis;
        if (!evaluate_alpha(e.p.conic, e.p.mean2d, d.opacity[e.index], double(x), double(y), &alpha,
                            &vis))
          continue;
        const double w = acc.transmittance * alpha;
        const Vec3<double> c = {d.colour[3 * e.index], d.colour[3 * e.index + 1],
                                d.colour[3 * e.index + 2]};
        if (!composite_step(alpha, c, e.p.depth, &acc)) break;
        contributions.push_back({alpha, e.p.depth, acc.transmittance});
        if (d.object_id[e.index] == settings.ins_object && settings.ins_object != 0 &&
            d.type[e.index] == uint8_t(GaussianType::kOpaque))
          ins += alpha;
        if (w > best) best = w, best_id = d.object_id[e.index];
      }
      const size_t p = static_cast<size_t>(y) * cam.width + x;
      const double t = acc.transmittance;
      im.rgb[3 * p] = acc.rgb.x + t * settings.background[0];
      im.rgb[3 * p + 1] = acc.rgb.y + t * settings.background[1];
      im.rgb[3 * p + 2] = acc.rgb.z + t * settings.background[2];
      im.depth[p] = acc.depth;
      if (settings.surface_depth && !contributions.empty()) {
        // Runs [begin, end) split at gaps; the surface: the first run where T_after reaches ½,
        // else the last.
        size_t begin = 0, end = 0, run_begin = 0;
        for (size_t k = 0; k <= contributions.size(); ++k) {
          const bool gap =
              k == contributions.size() ||
              (k > 0 && contributions[k].z - contributions[k - 1].z >
                            std::max<double>(settings.surface_gap, settings.surface_gap_relative *
                                                                       contributions[k - 1].z));
          if (!gap) continue;
          begin = run_begin, end = k;
          if (contributions[k - 1].t_after <= 0.5) break;
          run_begin = k;
        }
        double num = 0, den = 0, t = 1;
        for (size_t k = begin; k < end; ++k) {
          num += t * contributions[k].alpha * contributions[k].z;
          den += t * contributions[k].alpha;
          t *= 1 - contributions[k].alpha;
        }
        im.depth[p] = num / den;
      }
      im.alpha[p] = 1 - t;
      im.ins[p] = ins;
      im.dominant_id[p] = best_id;
    }
  return im;
}

TEST(Rasteriser, MatchesANaiveRenderer) {
  const PinholeCamera cam = testing::make_camera(90, 70, 70.0);
  const SE3 T_cw = testing::test_pose();
  std::mt19937_64 rng(12);
  DoubleGaussians d;
  for (int i = 0; i < 600; ++i) {
    // Some off-screen, some near the camera, many overlapping (the early stop is reached).
    GaussianInit g =
        testing::gaussian_at(cam, T_cw, uniform(rng, -30, 120), uniform(rng, -30, 100),
                             uniform(rng, 0.3, 4.0), rng, std::log(0.01), std::log(0.2));
    g.object_id = static_cast<uint32_t>(i % 5);
    g.type = i % 3 == 0 ? GaussianType::kTransparent : GaussianType::kOpaque;
    d.add(g, i % 4 == 0 ? uniform(rng, 0.001, 0.05) : uniform(rng, 0.5, 1.0));
  }
  RenderSettings settings;
  settings.ins_object = 2;
  settings.background[0] = 0.4f;
  const Images<double> ref = naive_render(d, cam, T_cw, settings);
  const Images<double> im = render(d.arrays(), cam, T_cw, settings, 2);
  int stopped = 0;
  for (size_t p = 0; p < ref.alpha.size(); ++p) {
    for (int c = 0; c < 3; ++c) ASSERT_NEAR(im.rgb[3 * p + c], ref.rgb[3 * p + c], 1e-12) << p;
    ASSERT_NEAR(im.depth[p], ref.depth[p], 1e-12) << p;
    ASSERT_NEAR(im.alpha[p], ref.alpha[p], 1e-12) << p;
    ASSERT_NEAR(im.ins[p], ref.ins[p], 1e-12) << p;
    ASSERT_EQ(im.dominant_id[p], ref.dominant_id[p]) << p;
    stopped += ref.alpha[p] > 1 - 1e-3;  // T below 1e-4 / (1 − α) for α ≤ 0.9: stopped
  }
  EXPECT_GT(stopped, 100);  // the early stop was exercised
}

// The same for the surface depth, on a scene of many overlapping surfaces.
TEST(Rasteriser, SurfaceDepthMatchesANaiveRenderer) {
  const PinholeCamera cam = testing::make_camera(90, 70, 70.0);
  const SE3 T_cw = testing::test_pose();
  std::mt19937_64 rng(13);
  DoubleGaussians d;
  for (int i = 0; i < 400; ++i) {
    GaussianInit g =
        testing::gaussian_at(cam, T_cw, uniform(rng, -30, 120), uniform(rng, -30, 100),
                             uniform(rng, 0.5, 4.0), rng, std::log(0.01), std::log(0.2));
    d.add(g, uniform(rng, 0.05, 0.95));
  }
  RenderSettings settings;
  settings.surface_depth = true;
  const Images<double> ref = naive_render(d, cam, T_cw, settings);
  const Images<double> im = render(d.arrays(), cam, T_cw, settings, 2);
  settings.surface_depth = false;
  settings.normalise_depth = true;
  const Images<double> mixed = render(d.arrays(), cam, T_cw, settings, 2);
  int differs = 0;
  for (size_t p = 0; p < ref.depth.size(); ++p) {
    ASSERT_NEAR(im.depth[p], ref.depth[p], 1e-12) << p;
    differs += std::abs(im.depth[p] - mixed.depth[p]) > 0.05;
  }
  EXPECT_GT(differs, 500);  // the surfaces are split, often
}

// At a silhouette, a front wall (z = 1.5, x < 0) over a back wall (z = 3): the surface depth is
// the back wall's where the front one's fringe covers less than half the pixel, and the front
// wall's where it covers more, though the back one still shows through; the normalised depth
// mixes the two on those pixels. The front wall's coverage comes from a render of it alone.
TEST(Rasteriser, SurfaceDepthAtASilhouette) {
  const PinholeCamera cam = testing::make_camera(64, 48, 50.0);
  GaussianMap front, both;
  auto wall = [](GaussianMap* map, double z, double x1, double spacing) {
    for (double y = -2.0; y <= 2.0; y += spacing)
      for (double x = -3.0; x <= x1; x += spacing) {
        GaussianInit g;
        g.position = Eigen::Vector3f(x, y, z);
        g.log_scale = Eigen::Vector3f(std::log(spacing), std::log(spacing), std::log(0.001));
        g.opacity = 0.9f;
        map->add(g);
      }
  };
  wall(&front, 1.5, 0.0, 0.03);
  wall(&both, 1.5, 0.0, 0.03);
  wall(&both, 3.0, 3.0, 0.06);
  auto r = make_cpu_rasteriser(2);
  RenderOutput coverage, surface, mixed;
  RenderSettings settings;
  r->forward(front, cam, SE3(), settings, &coverage, nullptr);
  settings.normalise_depth = true;
  r->forward(both, cam, SE3(), settings, &mixed, nullptr);
  settings.surface_depth = true;
  r->forward(both, cam, SE3(), settings, &surface, nullptr);
  int fringe = 0, front_kept = 0;
  for (size_t p = 0; p < surface.depth.size(); ++p) {
    ASSERT_GT(surface.alpha[p], 0.99f);
    const float a = coverage.alpha[p];
    if (a < 0.01f) {
      EXPECT_NEAR(surface.depth[p], 3.0, 1e-4);
    } else if (a < 0.45f) {
      EXPECT_NEAR(surface.depth[p], 3.0, 1e-4) << p;
      EXPECT_LT(mixed.depth[p], 3.0 - 0.01) << p;
      ++fringe;
    } else if (a > 0.55f) {
      EXPECT_NEAR(surface.depth[p], 1.5, 1e-4) << p;
      if (a < 0.99f) {
        EXPECT_GT(mixed.depth[p], 1.5 + 0.01) << p;
        ++front_kept;
      }
    }
  }
  EXPECT_GT(fringe, 0);
  EXPECT_GT(front_kept, 0);
}

TEST(Rasteriser, EmptyMapRendersTheBackground) {
  const PinholeCamera cam = testing::make_camera(40, 30, 40.0);
  GaussianMap map;
  RenderSettings settings;
  settings.background[1] = 0.25f;
  RenderOutput out;
  std::unique_ptr<RenderState> state;
  auto r = make_cpu_rasteriser(2);
  r->forward(map, cam, SE3(), settings, &out, &state);
  ASSERT_EQ(out.rgb.size(), 3u * 40 * 30);
  for (size_t p = 0; p < out.alpha.size(); ++p) {
    EXPECT_EQ(out.rgb[3 * p + 1], 0.25f);
    EXPECT_EQ(out.alpha[p], 0.f);
    EXPECT_EQ(out.dominant_id[p], 0u);
  }
  MapGradients g;
  OutputGradients og;
  og.rgb.assign(out.rgb.size(), 1.f);
  r->backward(map, cam, SE3(), settings, *state, og, &g);
  EXPECT_TRUE(g.position.empty());
}

// Shuffling the map permutes the gradients and changes nothing in the images, to the bit.
TEST(Rasteriser, IndependentOfInsertionOrder) {
  const PinholeCamera cam = testing::make_camera(96, 72, 80.0);
  const SE3 T_cw = testing::test_pose();
  const GaussianMap map = random_map(cam, T_cw, 3000, 5);
  std::vector<size_t> perm(map.size());
  std::iota(perm.begin(), perm.end(), 0);
  std::shuffle(perm.begin(), perm.end(), std::mt19937_64(6));
  GaussianMap shuffled;
  for (size_t i : perm) {
    GaussianInit g;
    g.position = Eigen::Map<const Eigen::Vector3f>(map.positions().data() + 3 * i);
    g.log_scale = Eigen::Map<const Eigen::Vector3f>(map.log_scales().data() + 3 * i);
    g.rotation = Eigen::Map<const Eigen::Vector4f>(map.rotations().data() + 4 * i);
    g.colour = Eigen::Map<const Eigen::Vector3f>(map.colours().data() + 3 * i);
    g.opacity = map.opacities()[i];
    g.object_id = map.object_ids_per_gaussian()[i];
    g.type = static_cast<GaussianType>(map.types()[i]);
    shuffled.add(g);
  }
  RenderSettings settings;
  settings.ins_object = 2;
  settings.background[2] = 1.f;
  auto r = make_cpu_rasteriser(2);
  RenderOutput a, b;
  std::unique_ptr<RenderState> sa, sb;
  r->forward(map, cam, T_cw, settings, &a, &sa);
  r->forward(shuffled, cam, T_cw, settings, &b, &sb);
  EXPECT_EQ(a.rgb, b.rgb);
  EXPECT_EQ(a.depth, b.depth);
  EXPECT_EQ(a.alpha, b.alpha);
  EXPECT_EQ(a.ins, b.ins);
  EXPECT_EQ(a.dominant_id, b.dominant_id);
  EXPECT_GT(*std::max_element(a.alpha.begin(), a.alpha.end()), 0.9f);

  std::mt19937_64 rng(7);
  OutputGradients og;
  og.rgb.resize(a.rgb.size());
  og.depth.resize(a.depth.size());
  og.ins.resize(a.ins.size());
  for (float& v : og.rgb) v = static_cast<float>(uniform(rng, -1, 1));
  for (float& v : og.depth) v = static_cast<float>(uniform(rng, -1, 1));
  for (float& v : og.ins) v = static_cast<float>(uniform(rng, -1, 1));
  MapGradients ga, gb;
  r->backward(map, cam, T_cw, settings, *sa, og, &ga);
  r->backward(shuffled, cam, T_cw, settings, *sb, og, &gb);
  for (size_t k = 0; k < perm.size(); ++k) {
    const size_t i = perm[k];
    for (int c = 0; c < 3; ++c) {
      ASSERT_EQ(ga.position[3 * i + c], gb.position[3 * k + c]);
      ASSERT_EQ(ga.log_scale[3 * i + c], gb.log_scale[3 * k + c]);
      ASSERT_EQ(ga.colour[3 * i + c], gb.colour[3 * k + c]);
    }
    for (int c = 0; c < 4; ++c) ASSERT_EQ(ga.rotation[4 * i + c], gb.rotation[4 * k + c]);
    ASSERT_EQ(ga.opacity[i], gb.opacity[k]);
  }
}

// Neither images nor gradients depend on the thread count, bit for bit (tiles are independent,
// and each Gaussian's per-tile gradients are added in tile order whichever thread made them): the
// same map trains the same on any machine. Thread counts that split the tiles differently, and
// more threads than rows of tiles.
TEST(Rasteriser, ThreadCountChangesNothing) {
  const PinholeCamera cam = testing::make_camera(100, 70, 90.0);
  const SE3 T_cw = testing::test_pose();
  const GaussianMap map = random_map(cam, T_cw, 2000, 8);
  RenderSettings settings;
  settings.normalise_depth = true;
  OutputGradients og;
  MapGradients one;
  RenderOutput one_out;
  for (const int threads : {1, 2, 3, 8, 40}) {
    RenderOutput out;
    std::unique_ptr<RenderState> state;
    const auto r = make_cpu_rasteriser(threads);
    r->forward(map, cam, T_cw, settings, &out, &state);
    if (threads == 1) {
      // Gradients that vary over the image, so that every tile's sums differ.
      std::mt19937_64 rng(5);
      og.rgb.resize(out.rgb.size());
      og.depth.resize(out.depth.size());
      for (float& v : og.rgb) v = static_cast<float>(testing::uniform(rng, -1, 1));
      for (float& v : og.depth) v = static_cast<float>(testing::uniform(rng, -1, 1));
    }
    MapGradients g;
    r->backward(map, cam, T_cw, settings, *state, og, &g);
    if (threads == 1) {
      one = g, one_out = out;
      float scale = 0.f;
      for (float v : g.position) scale = std::max(scale, std::abs(v));
      ASSERT_GT(scale, 0.f);
      continue;
    }
    EXPECT_EQ(out.rgb, one_out.rgb) << threads << " threads";
    EXPECT_EQ(out.depth, one_out.depth) << threads << " threads";
    EXPECT_EQ(g.position, one.position) << threads << " threads";
    EXPECT_EQ(g.log_scale, one.log_scale) << threads << " threads";
    EXPECT_EQ(g.rotation, one.rotation) << threads << " threads";
    EXPECT_EQ(g.opacity, one.opacity) << threads << " threads";
    EXPECT_EQ(g.colour, one.colour) << threads << " threads";
  }
}

// ins = Σ α over the OG Gaussians of the requested object only: the same with or without the other
// Gaussians (none of them occludes it away: no early stop here), and zero where only others are.
TEST(Rasteriser, InsCountsOnlyTheObjectsOpaqueGaussians) {
  const PinholeCamera cam = testing::make_camera(64, 48, 60.0);
  const SE3 T_cw = testing::test_pose();
  std::mt19937_64 rng(9);
  DoubleGaussians all, own, others;
  for (int i = 0; i < 12; ++i) {
    GaussianInit g = testing::gaussian_at(cam, T_cw, uniform(rng, 10, 54), uniform(rng, 8, 40),
                                          uniform(rng, 2, 3), rng, std::log(0.05), std::log(0.12));
    g.object_id = i % 3 == 0 ? 0u : (i % 3 == 1 ? 7u : 8u);
    g.type = i % 4 == 3 ? GaussianType::kTransparent : GaussianType::kOpaque;
    const double o = uniform(rng, 0.2, 0.5);
    all.add(g, o);
    (g.object_id == 7 && g.type == GaussianType::kOpaque ? own : others).add(g, o);
  }
  ASSERT_GT(own.size(), 1u);
  RenderSettings settings;
  settings.ins_object = 7;
  const Images<double> a = render(all.arrays(), cam, T_cw, settings, 2);
  const Images<double> b = render(own.arrays(), cam, T_cw, settings, 2);
  const Images<double> c = render(others.arrays(), cam, T_cw, settings, 2);
  double total = 0.0;
  for (size_t p = 0; p < a.ins.size(); ++p) {
    EXPECT_NEAR(a.ins[p], b.ins[p], 1e-12);
    EXPECT_EQ(c.ins[p], 0.0);
    total += a.ins[p];
  }
  EXPECT_GT(total, 1.0);
  // ins_object = 0 renders no instance opacity.
  settings.ins_object = 0;
  const Images<double> z = render(all.arrays(), cam, T_cw, settings, 2);
  for (double v : z.ins) EXPECT_EQ(v, 0.0);
}

// The masks' per-label render (RenderSettings::ins_labels): at each pixel, the instance opacity
// of the object the pixel is labelled with — the very value a render for that object alone gives
// there — and 0 on background pixels; no gradient of it.
TEST(Rasteriser, PerLabelInsIsEachPixelsOwnObjects) {
  const PinholeCamera cam = testing::make_camera(96, 72, 80.0);
  const SE3 T_cw = testing::test_pose();
  const GaussianMap map = random_map(cam, T_cw, 2000, 21);
  auto r = make_cpu_rasteriser(2);
  // Labels in vertical bands (objects 0-3), as a detector's masks would cut the image.
  std::vector<uint32_t> labels(static_cast<size_t>(cam.width) * cam.height);
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) labels[static_cast<size_t>(y) * cam.width + x] = (x / 24 + y / 36) % 4;
  RenderSettings per_label;
  per_label.ins_labels = labels.data();
  RenderOutput all;
  std::unique_ptr<RenderState> state;
  r->forward(map, cam, T_cw, per_label, &all, &state);
  double total = 0.0;
  for (uint32_t id = 0; id < 4; ++id) {
    RenderSettings one;
    one.ins_object = id;
    RenderOutput single;
    r->forward(map, cam, T_cw, one, &single, nullptr);
    for (size_t p = 0; p < labels.size(); ++p) {
      if (labels[p] != id) continue;
      ASSERT_EQ(all.ins[p], id == 0 ? 0.f : single.ins[p]) << "object " << id << ", pixel " << p;
      total += all.ins[p];
    }
    EXPECT_EQ(all.rgb, single.rgb) << "the colours do not depend on it";
  }
  EXPECT_GT(total, 10.0);
  OutputGradients go;
  go.ins.assign(labels.size(), 1.f);
  MapGradients g;
  EXPECT_THROW(r->backward(map, cam, T_cw, per_label, *state, go, &g), std::invalid_argument);
  go.ins.clear();
  go.rgb.assign(3 * labels.size(), 1.f);
  EXPECT_NO_THROW(r->backward(map, cam, T_cw, per_label, *state, go, &g)) << "other gradients are fine";
}

// MapGradients::colour_only: the same colour gradients as a full backward pass (added to what the
// array held), the other arrays left alone.
TEST(Rasteriser, ColourOnlyBackwardGivesTheColourGradients) {
  const PinholeCamera cam = testing::make_camera(80, 60, 70.0);
  const SE3 T_cw = testing::test_pose();
  const GaussianMap map = random_map(cam, T_cw, 1500, 22);
  auto r = make_cpu_rasteriser(2);
  RenderOutput out;
  std::unique_ptr<RenderState> state;
  r->forward(map, cam, T_cw, RenderSettings{}, &out, &state);
  OutputGradients go;
  std::mt19937_64 rng(22);
  go.rgb.resize(out.rgb.size());
  for (float& v : go.rgb) v = static_cast<float>(uniform(rng, -1, 1));
  MapGradients full, colour;
  r->backward(map, cam, T_cw, RenderSettings{}, *state, go, &full);
  colour.colour_only = true;
  colour.colour.assign(3 * map.size(), 1.f);
  r->backward(map, cam, T_cw, RenderSettings{}, *state, go, &colour);
  ASSERT_EQ(colour.colour.size(), full.colour.size());
  size_t nonzero = 0;
  for (size_t k = 0; k < full.colour.size(); ++k) {
    ASSERT_EQ(colour.colour[k], 1.f + full.colour[k]) << k;
    nonzero += full.colour[k] != 0.f;
  }
  EXPECT_GT(nonzero, full.colour.size() / 10);
  EXPECT_TRUE(colour.position.empty());
}

// Object 1, a dense patch in front, hides object 2, a larger patch behind; object 2 shows around.
TEST(Rasteriser, DominantIdIsTheFrontObject) {
  const PinholeCamera cam = testing::make_camera(80, 60, 80.0);
  const SE3 T_cw;  // identity: the patches are laid out in camera coordinates
  GaussianMap map;
  auto patch = [&](uint32_t id, double z, double half, double spacing) {
    for (double y = -half; y <= half + 1e-9; y += spacing)
      for (double x = -half; x <= half + 1e-9; x += spacing) {
        GaussianInit g;
        g.position = Eigen::Vector3f(x, y, z);
        g.log_scale = Eigen::Vector3f(std::log(spacing), std::log(spacing), std::log(0.002));
        g.object_id = id;
        map.add(g);
      }
  };
  patch(2, 4.0, 2.0, 0.1);   // behind, inserted first
  patch(1, 2.0, 0.2, 0.05);  // in front
  RenderOutput out;
  make_cpu_rasteriser(2)->forward(map, cam, T_cw, RenderSettings(), &out, nullptr);
  const int cx = 40, cy = 30;
  EXPECT_EQ(out.dominant_id[cy * 80 + cx], 1u);
  EXPECT_EQ(out.dominant_id[cy * 80 + cx + 3], 1u);
  EXPECT_EQ(out.dominant_id[cy * 80 + 5], 2u);  // beside the front patch
  EXPECT_EQ(out.dominant_id[5 * 80 + cx], 2u);
  // Pixels whose centre sees only the front patch: all of them 1.
  for (int v = cy - 4; v <= cy + 4; ++v)
    for (int u = cx - 4; u <= cx + 4; ++u) EXPECT_EQ(out.dominant_id[v * 80 + u], 1u);
}

// A flat wall of Gaussians at z = 2.5: normalised depth is 2.5 wherever anything is rendered and
// the raw depth is 2.5 × the accumulated alpha.
TEST(Rasteriser, DepthOfAFlatWall) {
  const PinholeCamera cam = testing::make_camera(64, 48, 50.0);
  const double z = 2.5;
  GaussianMap map;
  for (double y = -1.5; y <= 1.5; y += 0.04)
    for (double x = -2.0; x <= 2.0; x += 0.04) {
      GaussianInit g;
      g.position = Eigen::Vector3f(x, y, z);
      g.log_scale = Eigen::Vector3f(std::log(0.03), std::log(0.03), std::log(0.001));
      map.add(g);
    }
  RenderSettings settings;
  auto r = make_cpu_rasteriser(2);
  RenderOutput raw, normalised;
  r->forward(map, cam, SE3(), settings, &raw, nullptr);
  settings.normalise_depth = true;
  r->forward(map, cam, SE3(), settings, &normalised, nullptr);
  for (size_t p = 0; p < raw.depth.size(); ++p) {
    EXPECT_GT(raw.alpha[p], 0.99f);  // the wall fills the view, opaque
    EXPECT_NEAR(normalised.depth[p], z, 1e-5);
    EXPECT_NEAR(raw.depth[p], z * raw.alpha[p], 1e-5);
  }
}

TEST(Rasteriser, BackwardRefusesAStateOfAnotherMap) {
  const PinholeCamera cam = testing::make_camera(32, 32, 30.0);
  const GaussianMap map = random_map(cam, SE3(), 50, 10);
  const GaussianMap other = random_map(cam, SE3(), 49, 10);
  auto r = make_cpu_rasteriser(1);
  RenderOutput out;
  std::unique_ptr<RenderState> state;
  r->forward(map, cam, SE3(), RenderSettings(), &out, &state);
  MapGradients g;
  OutputGradients og;
  og.rgb.assign(out.rgb.size(), 1.f);
  EXPECT_THROW(r->backward(other, cam, SE3(), RenderSettings(), *state, og, &g),
               std::invalid_argument);
  og.depth.assign(3, 1.f);  // wrong size
  MapGradients g2;
  EXPECT_THROW(r->backward(map, cam, SE3(), RenderSettings(), *state, og, &g2),
               std::invalid_argument);
}

}  // namespace
}  // namespace dqo::gs
