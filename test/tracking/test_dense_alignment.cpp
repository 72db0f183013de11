// Dense RGB-D alignment: the residual maths against central differences, the accumulator against a
// plain sum, the pyramid, and align_dense on rendered views with known relative poses.

#include "dqo_map/tracking/dense_alignment.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "../../src/tracking/dense_residuals.h"
#include "../sim/sim_test_utils.h"
#include "dqo_map/sim/renderer.h"
#include "dqo_map/sim/scene_loader.h"

namespace dqo::tracking {
namespace {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

// ------------------------------------------------------------------ helpers

SE3 motion(double tx, double ty, double tz, double rx_deg, double ry_deg, double rz_deg) {
  Vector6d xi;
  xi << tx, ty, tz, rx_deg * M_PI / 180.0, ry_deg * M_PI / 180.0, rz_deg * M_PI / 180.0;
  return SE3::exp(xi);
}

double angle_deg(const SE3& T) {
  return 2.0 * std::acos(std::min(1.0, std::abs(T.quaternion().w()))) * 180.0 / M_PI;
}

// Each shipped scene loads once per test binary.
const sim::Scene& shipped_scene(const std::string& name) {
  static std::map<std::string, std::unique_ptr<sim::Scene>> cache;
  auto& slot = cache[name];
  if (!slot) {
    std::string error;
    auto scene = sim::load_scene(sim::testing::scene_path(name), {}, &error);
    if (!scene) throw std::runtime_error(error);  // fails the test that asked
    slot = std::make_unique<sim::Scene>(std::move(*scene));
  }
  return *slot;
}

// A reference frame of a scene's trajectory and a second view at T_ref_cur from it.
struct ViewPair {
  PinholeCamera camera;
  Frame ref;
  Frame cur;
};

ViewPair render_pair(const std::string& scene_name, int frame, const SE3& T_ref_cur, bool noise) {
  const sim::Scene& scene = shipped_scene(scene_name);
  const sim::Renderer renderer(scene, 0);
  ViewPair pair;
  pair.camera = scene.camera;
  pair.ref = renderer.render(frame, noise);
  pair.cur = renderer.render_view(pair.ref.T_wc * T_ref_cur, frame + 1, 0.0, noise);
  return pair;
}

DenseResult align(const ViewPair& pair, const SE3& guess, const DenseParams& params) {
  const RgbdPyramid ref(pair.camera, pair.ref.rgb, pair.ref.depth, params);
  const RgbdPyramid cur(pair.camera, pair.cur.rgb, pair.cur.depth, params);
  return align_dense(ref, cur, guess, params);
}

// `tiny` is 160x120: align it from the full resolution.
DenseParams tiny_params() {
  DenseParams p;
  p.pyramid_levels = 3;
  p.finest_level = 0;
  return p;
}

void expect_pose_near(const DenseResult& r, const SE3& truth, double max_mm, double max_deg) {
  ASSERT_TRUE(r.ok) << r.failure;
  const SE3 error = truth.inverse() * r.T_ref_cur;
  EXPECT_LT(error.translation().norm() * 1e3, max_mm);
  EXPECT_LT(angle_deg(error), max_deg);
}

// ------------------------------------------------------------------ residual maths

// Analytic intensity with its exact gradient, so that the chain rule is checked alone.
double smooth_image(double u, double v, double* du, double* dv) {
  const double a = 0.05 * u + 0.2, b = 0.07 * v - 0.1;
  *du = 0.3 * 0.05 * std::cos(a) * std::cos(b);
  *dv = -0.3 * 0.07 * std::sin(a) * std::sin(b);
  return 0.5 + 0.3 * std::sin(a) * std::cos(b);
}

TEST(DenseResiduals, JacobiansMatchCentralDifferences) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  const double fx = 262.5, fy = 261.0, cx = 159.5, cy = 119.5;
  for (int trial = 0; trial < 20; ++trial) {
    SCOPED_TRACE("trial " + std::to_string(trial));
    const SE3 T = motion(0.1 * uni(rng), 0.1 * uni(rng), 0.1 * uni(rng), 10 * uni(rng),
                         10 * uni(rng), 10 * uni(rng));
    const Eigen::Vector3d p(0.4 * uni(rng), 0.3 * uni(rng), 1.2 + 0.5 * uni(rng));
    const Eigen::Vector3d p_ref = T * p + 0.01 * Eigen::Vector3d(uni(rng), uni(rng), uni(rng));
    const Eigen::Vector3d n_ref = Eigen::Vector3d(uni(rng), uni(rng), -2.0).normalized();

    // Both residuals as functions of the pose, in double.
    auto geometric = [&](const SE3& pose) { return n_ref.dot(pose * p - p_ref); };
    auto photometric = [&](const SE3& pose) {
      const Eigen::Vector3d q = pose * p;
      double du, dv;
      return smooth_image(fx * q.x() / q.z() + cx, fy * q.y() / q.z() + cy, &du, &dv);
    };

    // Analytic (float) left-perturbation Jacobians at T.
    const Eigen::Vector3f q = (T * p).cast<float>();
    const Eigen::Matrix<float, 6, 1> J_geo = dense::jacobian_from_direction(q, n_ref.cast<float>());
    double gu, gv;
    smooth_image(fx * q.x() / q.z() + cx, fy * q.y() / q.z() + cy, &gu, &gv);
    const Eigen::Matrix<float, 6, 1> J_pho = dense::jacobian_from_direction(
        q, dense::photometric_direction(q, static_cast<float>(gu), static_cast<float>(gv),
                                        static_cast<float>(fx), static_cast<float>(fy)));
    EXPECT_NEAR(dense::point_to_plane_residual(q, p_ref.cast<float>(), n_ref.cast<float>()),
                geometric(T), 1e-5);

    // Central differences, left (exp(xi) T, the solver's) and right (T exp(xi), the header's).
    const double h = 1e-6;
    Vector6d fd_geo_left, fd_pho_left, fd_geo_right, fd_pho_right;
    for (int k = 0; k < 6; ++k) {
      Vector6d e = Vector6d::Zero();
      e[k] = h;
      fd_geo_left[k] = (geometric(SE3::exp(e) * T) - geometric(SE3::exp(-e) * T)) / (2 * h);
      fd_pho_left[k] = (photometric(SE3::exp(e) * T) - photometric(SE3::exp(-e) * T)) / (2 * h);
      fd_geo_right[k] = (geometric(T * SE3::exp(e)) - geometric(T * SE3::exp(-e))) / (2 * h);
      fd_pho_right[k] = (photometric(T * SE3::exp(e)) - photometric(T * SE3::exp(-e))) / (2 * h);
    }
    const Vector6d geo = J_geo.cast<double>(), pho = J_pho.cast<double>();
    EXPECT_LT((geo - fd_geo_left).norm(), 1e-4 * (1.0 + fd_geo_left.norm()));
    EXPECT_LT((pho - fd_pho_left).norm(), 1e-4 * (1.0 + fd_pho_left.norm()));
    // A right-perturbation Jacobian is the left one times the adjoint.
    const Matrix6d Ad = dense::adjoint(T);
    EXPECT_LT((Ad.transpose() * geo - fd_geo_right).norm(), 1e-4 * (1.0 + fd_geo_right.norm()));
    EXPECT_LT((Ad.transpose() * pho - fd_pho_right).norm(), 1e-4 * (1.0 + fd_pho_right.norm()));
  }
}

TEST(DenseResiduals, HuberWeight) {
  EXPECT_FLOAT_EQ(dense::huber_weight(0.0f, 0.02f), 1.0f);
  EXPECT_FLOAT_EQ(dense::huber_weight(-0.019f, 0.02f), 1.0f);
  EXPECT_FLOAT_EQ(dense::huber_weight(0.04f, 0.02f), 0.5f);
  EXPECT_FLOAT_EQ(dense::huber_weight(-0.08f, 0.02f), 0.25f);
}

TEST(DenseResiduals, NormalEquationsMatchAPlainSum) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> uni(-1.0f, 1.0f);
  auto block = std::make_unique<dense::ResidualBlock>();
  dense::NormalEquations ne;
  Matrix6d H = Matrix6d::Zero();
  Vector6d g = Vector6d::Zero();
  double cost = 0.0;
  // Three full blocks and a partial one (padded with weightless slots), magnitudes as in use.
  for (int b = 0; b < 4; ++b) {
    const int n = b < 3 ? dense::ResidualBlock::kSize : 40;
    for (int i = 0; i < dense::ResidualBlock::kSize; ++i) {
      const bool used = i < n && i % 7 != 3;  // some rejected slots inside too
      block->qx[i] = 0.5f * uni(rng);
      block->qy[i] = 0.4f * uni(rng);
      block->qz[i] = 1.5f + 0.5f * uni(rng);
      block->ax[i] = uni(rng);
      block->ay[i] = uni(rng);
      block->az[i] = uni(rng);
      block->r[i] = 0.01f * uni(rng);
      block->w[i] = used ? 1e5f * (1.5f + uni(rng)) : 0.0f;
      if (!used) continue;
      const Eigen::Vector3d q(block->qx[i], block->qy[i], block->qz[i]);
      const Eigen::Vector3d a(block->ax[i], block->ay[i], block->az[i]);
      Vector6d J;
      J << a, q.cross(a);
      H += double(block->w[i]) * J * J.transpose();
      g += double(block->w[i]) * double(block->r[i]) * J;
      cost += double(block->w[i]) * double(block->r[i]) * double(block->r[i]);
    }
    ne.add(*block, (n + 7) / 8 * 8);
  }
  EXPECT_LT((ne.hessian() - H).norm(), 1e-5 * H.norm());
  EXPECT_LT((ne.gradient() - g).norm(), 1e-5 * g.norm());
  EXPECT_NEAR(ne.cost(), cost, 1e-5 * cost);
}

// ------------------------------------------------------------------ pyramid

TEST(RgbdPyramid, LevelsHalveWithMatchingIntrinsics) {
  const ViewPair pair = render_pair("tiny", 0, SE3::identity(), false);
  DenseParams params = tiny_params();
  const RgbdPyramid pyramid(pair.camera, pair.ref.rgb, pair.ref.depth, params);
  ASSERT_EQ(pyramid.levels(), 3);
  EXPECT_TRUE(pyramid.has_colour());
  for (int l = 1; l < pyramid.levels(); ++l) {
    const PinholeCamera& fine = pyramid.camera(l - 1);
    const PinholeCamera& coarse = pyramid.camera(l);
    EXPECT_EQ(coarse.width, fine.width / 2);
    EXPECT_EQ(coarse.height, fine.height / 2);
    EXPECT_DOUBLE_EQ(coarse.fx, fine.fx / 2);
    // A point's pixel at level l is the centre of the 2x2 block it falls in at level l - 1.
    const Eigen::Vector3d p(0.1, -0.05, 1.3);
    const Eigen::Vector2d u_fine = fine.project(p), u_coarse = coarse.project(p);
    EXPECT_NEAR(u_coarse.x(), (u_fine.x() - 0.5) / 2, 1e-12);
    EXPECT_NEAR(u_coarse.y(), (u_fine.y() - 0.5) / 2, 1e-12);
    EXPECT_GT(pyramid.valid_points(l), 0);
  }
  // The points are the depth back-projected; the normals unit length and facing the camera.
  const RgbdPyramid::Level& L = pyramid.level(0);
  int checked = 0;
  for (size_t i = 0; i < L.surfels.size(); ++i) {
    const RgbdPyramid::Surfel& s = L.surfels[i];
    if (s.n.squaredNorm() == 0.0f) continue;
    const int x = static_cast<int>(i % L.camera.width), y = static_cast<int>(i / L.camera.width);
    EXPECT_NEAR((L.camera.project(s.p.cast<double>()) - Eigen::Vector2d(x, y)).norm(), 0.0, 1e-3);
    EXPECT_NEAR(s.n.norm(), 1.0f, 1e-4f);
    EXPECT_LT(s.n.dot(s.p), 0.0f);
    ++checked;
  }
  EXPECT_EQ(checked, pyramid.valid_points(0));
}

TEST(RgbdPyramid, DepthIsNotAveragedAcrossEdges) {
  // A fronto-parallel step: 1 m left of column 33, 2 m from it on (odd, so that 2x2 blocks at
  // level 1 straddle the edge).
  PinholeCamera camera;
  camera.width = 64;
  camera.height = 48;
  camera.fx = camera.fy = 60.0;
  camera.cx = 31.5;
  camera.cy = 23.5;
  DepthImage depth(64, 48, 1, 0.0f);
  for (int y = 0; y < 48; ++y) {
    for (int x = 0; x < 64; ++x) depth.at(x, y) = x < 33 ? 1.0f : 2.0f;
  }
  DenseParams params;
  params.pyramid_levels = 3;
  params.finest_level = 0;
  const RgbdPyramid pyramid(camera, ImageRgb8(), depth, params);
  EXPECT_FALSE(pyramid.has_colour());
  for (int l = 1; l < 3; ++l) {
    for (const float z : pyramid.level(l).depth) {
      EXPECT_TRUE(z == 1.0f || z == 2.0f) << "level " << l << " depth " << z;
    }
  }
  // Normals: (0, 0, -1) on either plane, none next to the edge.
  const RgbdPyramid::Level& L = pyramid.level(0);
  for (int y = 1; y < 47; ++y) {
    for (int x = 1; x < 63; ++x) {
      const Eigen::Vector3f& n = L.surfels[y * 64 + x].n;
      if (x == 32 || x == 33) {
        EXPECT_EQ(n.squaredNorm(), 0.0f) << x << "," << y;
      } else {
        EXPECT_LT((n - Eigen::Vector3f(0, 0, -1)).norm(), 1e-4f) << x << "," << y;
      }
    }
  }
}

TEST(RgbdPyramid, RebuildMatchesConstruction) {
  const ViewPair pair = render_pair("tiny", 3, motion(0.03, 0, 0, 0, 3, 0), false);
  const DenseParams params = tiny_params();
  RgbdPyramid rebuilt(pair.camera, pair.ref.rgb, pair.ref.depth, params);
  rebuilt.rebuild(pair.camera, pair.cur.rgb, pair.cur.depth, params);
  const RgbdPyramid fresh(pair.camera, pair.cur.rgb, pair.cur.depth, params);
  for (int l = 0; l < fresh.levels(); ++l) {
    ASSERT_EQ(rebuilt.valid_points(l), fresh.valid_points(l));
    EXPECT_EQ(rebuilt.level(l).samples.x, fresh.level(l).samples.x);
    EXPECT_EQ(rebuilt.level(l).samples.intensity, fresh.level(l).samples.intensity);
    EXPECT_EQ(rebuilt.level(l).depth, fresh.level(l).depth);
  }
}

// ------------------------------------------------------------------ alignment

TEST(AlignDense, RecoversSmallMotionsNoiseFree) {
  const SE3 motions[] = {motion(0.02, 0.0, 0.0, 0, 2, 0), motion(-0.03, 0.02, 0.01, 2, -3, 1),
                         motion(0.0, -0.04, 0.05, -4, 0, 5)};
  for (const SE3& truth : motions) {
    SCOPED_TRACE(truth.log().transpose());
    const ViewPair pair = render_pair("tiny", 5, truth, false);
    expect_pose_near(align(pair, SE3::identity(), tiny_params()), truth, 1.0, 0.1);
  }
}

TEST(AlignDense, RecoversSmallMotionsWithNoise) {
  const SE3 motions[] = {motion(0.02, 0.01, -0.01, 1, 2, 0), motion(-0.03, 0.0, 0.04, -2, 3, 4)};
  for (const SE3& truth : motions) {
    SCOPED_TRACE(truth.log().transpose());
    const ViewPair pair = render_pair("tabletop", 40, truth, true);
    expect_pose_near(align(pair, SE3::identity(), DenseParams()), truth, 3.0, 0.2);
  }
}

TEST(AlignDense, ConvergesFromIdentityAcrossTheBasin) {
  // 10 cm and 10° along single axes (yaw, about the camera's y, to 8°: beyond it the table and
  // walls slide along themselves, see the next test), and a combined motion.
  const SE3 motions[] = {motion(0.10, 0, 0, 0, 0, 0),  motion(0, 0, -0.10, 0, 0, 0),
                         motion(0, 0, 0, 10, 0, 0),    motion(0, 0, 0, 0, 0, 10),
                         motion(0, 0, 0, 0, -8, 0),    motion(0.06, -0.03, 0.04, 4, -5, 3)};
  for (const SE3& truth : motions) {
    SCOPED_TRACE(truth.log().transpose());
    const ViewPair pair = render_pair("tabletop", 0, truth, true);
    expect_pose_near(align(pair, SE3::identity(), DenseParams()), truth, 3.0, 0.2);
  }
}

TEST(AlignDense, ReportsFailureRatherThanAWrongPose) {
  // Beyond the basin: whatever comes out is either right or flagged.
  const SE3 motions[] = {motion(0, 0, 0, 0, 12, 0), motion(0, 0, 0, 0, -10, 0)};
  for (const SE3& truth : motions) {
    SCOPED_TRACE(truth.log().transpose());
    const ViewPair pair = render_pair("tabletop", 150, truth, true);
    const DenseResult r = align(pair, SE3::identity(), DenseParams());
    if (r.ok) {
      EXPECT_LT((truth.inverse() * r.T_ref_cur).translation().norm(), 0.005);
    } else {
      EXPECT_STRNE(r.failure, "");
      EXPECT_TRUE(r.T_ref_cur.translation().isZero());  // the guess, unchanged
    }
  }
}

TEST(AlignDense, TexturelessSceneAlignsFromGeometry) {
  const SE3 truth = motion(0.04, -0.02, 0.02, 3, -4, 2);
  const ViewPair pair = render_pair("tabletop_plain", 60, truth, true);
  expect_pose_near(align(pair, SE3::identity(), DenseParams()), truth, 3.0, 0.2);
}

TEST(AlignDense, FailsWithoutDepth) {
  const ViewPair pair = render_pair("tiny", 0, motion(0.02, 0, 0, 0, 0, 0), false);
  const DenseParams params = tiny_params();
  const SE3 guess = motion(0.01, 0, 0, 0, 1, 0);
  const RgbdPyramid ref(pair.camera, pair.ref.rgb, pair.ref.depth, params);

  const RgbdPyramid empty(pair.camera, pair.cur.rgb, DepthImage(), params);
  DenseResult r = align_dense(ref, empty, guess, params);
  EXPECT_FALSE(r.ok);
  EXPECT_STRNE(r.failure, "");
  EXPECT_TRUE(r.T_ref_cur.matrix().isApprox(guess.matrix()));
  EXPECT_TRUE(r.information.isZero());

  DepthImage zeros = pair.cur.depth;
  std::fill(zeros.data.begin(), zeros.data.end(), 0.0f);
  const RgbdPyramid blank(pair.camera, pair.cur.rgb, zeros, params);
  EXPECT_EQ(blank.valid_points(0), 0);
  EXPECT_FALSE(align_dense(ref, blank, guess, params).ok);
  EXPECT_FALSE(align_dense(blank, ref, guess, params).ok);
  EXPECT_FALSE(align_dense(RgbdPyramid(), ref, guess, params).ok);

  // A handful of valid pixels is not enough either.
  DepthImage sparse = zeros;
  for (int i = 0; i < 30; ++i) sparse.at(60 + i, 60) = 1.2f;
  const RgbdPyramid few(pair.camera, pair.cur.rgb, sparse, params);
  EXPECT_FALSE(align_dense(ref, few, guess, params).ok);
}

TEST(AlignDense, InformationIsSymmetricPositiveDefiniteAndGrowsWithPoints) {
  const SE3 truth = motion(0.02, 0.01, 0.0, 1, 2, -1);
  const ViewPair pair = render_pair("tiny", 8, truth, false);
  const DenseParams params = tiny_params();
  const DenseResult full = align(pair, SE3::identity(), params);
  ASSERT_TRUE(full.ok) << full.failure;

  // The same frames with the left third of the current depth removed: fewer points.
  ViewPair cropped = pair;
  for (int y = 0; y < cropped.cur.depth.height; ++y) {
    for (int x = 0; x < cropped.cur.depth.width / 3; ++x) cropped.cur.depth.at(x, y) = 0.0f;
  }
  const DenseResult fewer = align(cropped, SE3::identity(), params);
  ASSERT_TRUE(fewer.ok) << fewer.failure;
  EXPECT_LT(fewer.inliers, full.inliers);

  for (const DenseResult* r : {&full, &fewer}) {
    EXPECT_TRUE(r->information.isApprox(r->information.transpose(), 1e-12));
    const Eigen::SelfAdjointEigenSolver<Matrix6d> eig(r->information);
    EXPECT_GT(eig.eigenvalues().minCoeff(), 0.0);
    EXPECT_EQ(Eigen::LLT<Matrix6d>(r->information).info(), Eigen::Success);
  }
  // Fewer points, larger covariance in every direction.
  const Matrix6d cov_full = full.information.inverse();
  const Matrix6d cov_fewer = fewer.information.inverse();
  for (int k = 0; k < 6; ++k) EXPECT_GT(cov_fewer(k, k), cov_full(k, k)) << "axis " << k;
}

// The floor (a large quad at z = 0, normal up) and a camera 1.5 m above it looking down.
struct FloorScene {
  SE3 T_wr = SE3::from_rotation_translation(Eigen::Vector3d(1, -1, -1).asDiagonal().toDenseMatrix(),
                                            Eigen::Vector3d(0, 0, 1.5));
  sim::Scene scene;
  explicit FloorScene(const sim::Texture& texture) {
    scene = sim::testing::empty_scene(160, 120, 140.0, T_wr);
    scene.background.push_back(sim::testing::make_object(
        0, std::make_shared<sim::Quad>(Eigen::Vector2d(20.0, 20.0)), SE3::identity()));
    scene.background.back().material = texture;
  }
  ViewPair views(const SE3& T_ref_cur) const {
    const sim::Renderer renderer(scene, 0);
    ViewPair pair;
    pair.camera = scene.camera;
    pair.ref = renderer.render_view(T_wr, 0, 0.0, false);
    pair.cur = renderer.render_view(T_wr * T_ref_cur, 1, 0.0, false);
    return pair;
  }
};

TEST(AlignDense, ColourPinsDownWhatAPlaneLeavesFree) {
  // Sliding over a textured floor: the geometry cannot see it, the photometric term can.
  sim::Texture texture;
  texture.type = sim::TextureType::kNoise;
  texture.colour_a = Eigen::Vector3f(0.9f, 0.8f, 0.6f);
  texture.colour_b = Eigen::Vector3f(0.2f, 0.25f, 0.3f);
  texture.scale = 0.08;
  const FloorScene floor(texture);
  const SE3 truth = motion(0.02, -0.015, 0.0, 0, 0, 3);  // in the plane, and about its normal
  const ViewPair pair = floor.views(truth);
  DenseParams params = tiny_params();
  expect_pose_near(align(pair, SE3::identity(), params), truth, 1.0, 0.1);

  params.colour_weight = 0.0;
  const DenseResult geometric = align(pair, SE3::identity(), params);
  ASSERT_TRUE(geometric.ok) << geometric.failure;
  EXPECT_GT((truth.inverse() * geometric.T_ref_cur).translation().norm(), 0.01);
}

TEST(AlignDense, InformationLivesInTheRightPerturbation) {
  // A single plane (the floor, seen from 1.5 m) constrains only the translation along its normal
  // and the rotations about axes in it. With the current camera tilted against the reference, the
  // directions it leaves free are [t; 0] for t in the plane and [0; n] with n the normal, where
  // both are expressed in the CURRENT camera's frame for the right perturbation.
  const FloorScene floor{sim::Texture()};  // uniform: geometry only
  const SE3 T_rc = motion(0.05, 0.02, 0.0, 20, -10, 5);
  DenseParams params = tiny_params();
  params.colour_weight = 0.0;
  const DenseResult r = align(floor.views(T_rc), T_rc, params);
  ASSERT_TRUE(r.ok) << r.failure;

  const Eigen::Vector3d n_w(0, 0, 1);  // the floor's normal
  const Eigen::Vector3d n_cur = (floor.T_wr * T_rc).rotation().transpose() * n_w;
  const Eigen::Vector3d n_ref = floor.T_wr.rotation().transpose() * n_w;
  const double scale = r.information.norm();
  auto response = [&](const Vector6d& v) { return (r.information * v).norm() / scale; };
  Eigen::Vector3d t1 = n_cur.unitOrthogonal(), t2 = n_cur.cross(t1);
  Vector6d v;
  v << t1, Eigen::Vector3d::Zero();
  EXPECT_LT(response(v), 1e-6);
  v << t2, Eigen::Vector3d::Zero();
  EXPECT_LT(response(v), 1e-6);
  v << Eigen::Vector3d::Zero(), n_cur;
  EXPECT_LT(response(v), 1e-6);
  // The constrained directions respond; so does the rotation about the normal as seen from the
  // reference, which a left-perturbation matrix would have left free instead.
  v << n_cur, Eigen::Vector3d::Zero();
  EXPECT_GT(response(v), 1e-3);
  v << Eigen::Vector3d::Zero(), n_ref;
  EXPECT_GT(response(v), 1e-4);
}

}  // namespace
}  // namespace dqo::tracking
