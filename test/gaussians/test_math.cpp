// Each stage of the shared per-Gaussian maths (include/dqo_map/gaussians/math/) against central
// finite differences in double precision: forward sanity, then its VJP for random output gradients.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <functional>
#include <random>
#include <vector>

#include "dqo_map/gaussians/math/alpha.h"
#include "dqo_map/gaussians/math/composite.h"
#include "dqo_map/gaussians/math/project_gaussian.h"

namespace dqo::gs {
namespace {

using Vec = std::vector<double>;
using Fn = std::function<Vec(const Vec&)>;
using VjpFn = std::function<Vec(const Vec& x, const Vec& v_out)>;

double uniform(std::mt19937_64& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

Vec random_vec(std::mt19937_64& rng, size_t n, double lo = -1.0, double hi = 1.0) {
  Vec v(n);
  for (double& x : v) x = uniform(rng, lo, hi);
  return v;
}

// ⟨v_out, f(x)⟩ differentiated by central differences against vjp(x, v_out), entry by entry.
void check_vjp(const Fn& f, const VjpFn& vjp, const Vec& x, std::mt19937_64& rng, double eps = 1e-6,
               double tol = 1e-7) {
  const Vec y = f(x);
  const Vec v_out = random_vec(rng, y.size());
  const Vec analytic = vjp(x, v_out);
  ASSERT_EQ(analytic.size(), x.size());
  double scale = 0.0;
  Vec numeric(x.size());
  for (size_t i = 0; i < x.size(); ++i) {
    Vec xp = x, xm = x;
    xp[i] += eps;
    xm[i] -= eps;
    const Vec yp = f(xp), ym = f(xm);
    double d = 0.0;
    for (size_t k = 0; k < y.size(); ++k) d += v_out[k] * (yp[k] - ym[k]);
    numeric[i] = d / (2 * eps);
    scale = std::max(scale, std::abs(numeric[i]));
  }
  for (size_t i = 0; i < x.size(); ++i)
    EXPECT_NEAR(analytic[i], numeric[i], tol * std::max(1.0, scale)) << "input " << i;
}

Mat3<double> mat3_of(const double* p) {
  Mat3<double> m;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) m.m[i][j] = p[3 * i + j];
  return m;
}
void append(Vec* v, const Mat3<double>& m) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) v->push_back(m.m[i][j]);
}

Mat3<double> random_rotation(std::mt19937_64& rng) {
  Eigen::Quaterniond q(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1),
                       uniform(rng, -1, 1));
  q.normalize();
  const Eigen::Matrix3d R = q.toRotationMatrix();
  Mat3<double> m;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) m.m[i][j] = R(i, j);
  return m;
}

Mat3<double> random_spd(std::mt19937_64& rng) {
  const Mat3<double> R = random_rotation(rng);
  Mat3<double> D = mat3_zero<double>();
  for (int i = 0; i < 3; ++i) D.m[i][i] = uniform(rng, 0.001, 0.01);
  return R * D * transpose(R);
}

const PinholeIntrinsics<double> kK = {300.0, 310.0, 160.5, 118.0, 320, 240};

TEST(GaussianMath, QuaternionMatchesEigenAndItsVjp) {
  std::mt19937_64 rng(1);
  for (int trial = 0; trial < 5; ++trial) {
    const Vec q = random_vec(rng, 4);
    const Mat3<double> R = quat_to_rotmat(Quat<double>{q[0], q[1], q[2], q[3]});
    const Eigen::Matrix3d Re =
        Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) EXPECT_NEAR(R.m[i][j], Re(i, j), 1e-12);
    check_vjp(
        [](const Vec& x) {
          Vec y;
          append(&y, quat_to_rotmat(Quat<double>{x[0], x[1], x[2], x[3]}));
          return y;
        },
        [](const Vec& x, const Vec& v) {
          Quat<double> g = {0, 0, 0, 0};
          quat_to_rotmat_vjp(Quat<double>{x[0], x[1], x[2], x[3]}, mat3_of(v.data()), &g);
          return Vec{g.w, g.x, g.y, g.z};
        },
        q, rng);
  }
}

TEST(GaussianMath, Covariance3dAndItsVjp) {
  std::mt19937_64 rng(2);
  for (int trial = 0; trial < 5; ++trial) {
    Vec x = random_vec(rng, 3, -3.0, -1.0);
    append(&x, random_rotation(rng));
    // Forward: Σ = R S² Rᵀ is symmetric with eigenvalues exp(2 log_scale).
    const Mat3<double> cov = covariance_3d(Vec3<double>{x[0], x[1], x[2]}, mat3_of(x.data() + 3));
    Eigen::Matrix3d C;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) C(i, j) = cov.m[i][j];
    EXPECT_NEAR(C.determinant(), std::exp(2 * (x[0] + x[1] + x[2])), 1e-15);
    EXPECT_NEAR(C.trace(), std::exp(2 * x[0]) + std::exp(2 * x[1]) + std::exp(2 * x[2]), 1e-12);
    // The VJP treats R's entries as independent (exact for any matrix).
    check_vjp(
        [](const Vec& x) {
          Vec y;
          append(&y, covariance_3d(Vec3<double>{x[0], x[1], x[2]}, mat3_of(x.data() + 3)));
          return y;
        },
        [](const Vec& x, const Vec& v) {
          Vec3<double> g_ls = {0, 0, 0};
          Mat3<double> g_R = mat3_zero<double>();
          covariance_3d_vjp(Vec3<double>{x[0], x[1], x[2]}, mat3_of(x.data() + 3),
                            mat3_of(v.data()), &g_ls, &g_R);
          Vec g = {g_ls.x, g_ls.y, g_ls.z};
          append(&g, g_R);
          return g;
        },
        x, rng, 1e-6, 1e-7);
  }
}

TEST(GaussianMath, WorldToCameraAndItsVjp) {
  std::mt19937_64 rng(3);
  // Position: inputs R (9), t (3), p_w (3).
  Vec x;
  append(&x, random_rotation(rng));
  for (double v : random_vec(rng, 6)) x.push_back(v);
  check_vjp(
      [](const Vec& x) {
        const Vec3<double> p = position_world_to_camera(
            mat3_of(x.data()), Vec3<double>{x[9], x[10], x[11]}, Vec3<double>{x[12], x[13], x[14]});
        return Vec{p.x, p.y, p.z};
      },
      [](const Vec& x, const Vec& v) {
        Vec3<double> g_p = {0, 0, 0}, g_t = {0, 0, 0};
        Mat3<double> g_R = mat3_zero<double>();
        position_world_to_camera_vjp(mat3_of(x.data()), Vec3<double>{x[12], x[13], x[14]},
                                     Vec3<double>{v[0], v[1], v[2]}, &g_p, &g_R, &g_t);
        Vec g;
        append(&g, g_R);
        for (double d : {g_t.x, g_t.y, g_t.z, g_p.x, g_p.y, g_p.z}) g.push_back(d);
        return g;
      },
      x, rng);
  // Covariance: inputs R (9), Σ_w (9).
  Vec y;
  append(&y, random_rotation(rng));
  append(&y, random_spd(rng));
  check_vjp(
      [](const Vec& x) {
        Vec out;
        append(&out, covariance_world_to_camera(mat3_of(x.data()), mat3_of(x.data() + 9)));
        return out;
      },
      [](const Vec& x, const Vec& v) {
        Mat3<double> g_R = mat3_zero<double>(), g_S = mat3_zero<double>();
        covariance_world_to_camera_vjp(mat3_of(x.data()), mat3_of(x.data() + 9), mat3_of(v.data()),
                                       &g_S, &g_R);
        Vec g;
        append(&g, g_R);
        append(&g, g_S);
        return g;
      },
      y, rng);
}

Vec projection_fn(const Vec& x) {
  Vec2<double> mean;
  Sym2<double> cov;
  perspective_projection(Vec3<double>{x[0], x[1], x[2]}, mat3_of(x.data() + 3), kK, &mean, &cov);
  return {mean.x, mean.y, cov.xx, cov.xy, cov.yy};
}

Vec projection_vjp(const Vec& x, const Vec& v) {
  Vec3<double> g_p = {0, 0, 0};
  Mat3<double> g_S = mat3_zero<double>();
  perspective_projection_vjp(Vec3<double>{x[0], x[1], x[2]}, mat3_of(x.data() + 3), kK,
                             Vec2<double>{v[0], v[1]}, Sym2<double>{v[2], v[3], v[4]}, &g_p, &g_S);
  Vec g = {g_p.x, g_p.y, g_p.z};
  append(&g, g_S);
  return g;
}

TEST(GaussianMath, PerspectiveProjectionAndItsVjp) {
  std::mt19937_64 rng(4);
  // Inside the frustum, then outside its margin in x (clamped J) and in y.
  const Vec3<double> points[] = {
      {0.3, -0.2, 2.0}, {-0.1, 0.15, 1.5}, {4.0, 0.1, 2.0}, {0.2, -3.5, 2.0}};
  for (const Vec3<double>& p : points) {
    Vec x = {p.x, p.y, p.z};
    append(&x, random_spd(rng));
    // Forward against Eigen: mean through K, Σ_2D = J Σ Jᵀ at the clamped direction.
    const Vec y = projection_fn(x);
    EXPECT_NEAR(y[0], kK.fx * p.x / p.z + kK.cx, 1e-12);
    EXPECT_NEAR(y[1], kK.fy * p.y / p.z + kK.cy, 1e-12);
    const FrustumLimits<double> lim = frustum_limits(kK);
    const double u = std::clamp(p.x / p.z, -lim.x_neg, lim.x_pos);
    const double v = std::clamp(p.y / p.z, -lim.y_neg, lim.y_pos);
    Eigen::Matrix<double, 2, 3> J;
    J << kK.fx / p.z, 0, -kK.fx * u / p.z, 0, kK.fy / p.z, -kK.fy * v / p.z;
    Eigen::Matrix3d S;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) S(i, j) = x[3 + 3 * i + j];
    const Eigen::Matrix2d C = J * S * J.transpose();
    EXPECT_NEAR(y[2], C(0, 0), 1e-9);
    EXPECT_NEAR(y[3], C(0, 1), 1e-9);
    EXPECT_NEAR(y[4], C(1, 1), 1e-9);
    check_vjp(projection_fn, projection_vjp, x, rng, 1e-7, 1e-7);
  }
  // The frustum clamp: 1.3 × the half field for a centred principal point.
  const PinholeIntrinsics<double> centred = {300.0, 300.0, 160.0, 120.0, 320, 240};
  EXPECT_NEAR(frustum_limits(centred).x_pos, 1.3 * 160.0 / 300.0, 1e-12);
  EXPECT_NEAR(frustum_limits(centred).y_neg, 1.3 * 120.0 / 300.0, 1e-12);
}

TEST(GaussianMath, ConicAndRadius) {
  std::mt19937_64 rng(5);
  for (int trial = 0; trial < 5; ++trial) {
    const double a = uniform(rng, 1, 20), c = uniform(rng, 1, 20);
    const double b = uniform(rng, -0.9, 0.9) * std::sqrt(a * c);
    Sym2<double> conic;
    ASSERT_TRUE(conic_from_covariance(Sym2<double>{a, b, c}, &conic));
    EXPECT_NEAR(a * conic.xx + b * conic.xy, 1.0, 1e-12);
    EXPECT_NEAR(a * conic.xy + b * conic.yy, 0.0, 1e-12);
    EXPECT_NEAR(b * conic.xy + c * conic.yy, 1.0, 1e-12);
    check_vjp(
        [](const Vec& x) {
          Sym2<double> k{};
          conic_from_covariance(Sym2<double>{x[0], x[1], x[2]}, &k);
          return Vec{k.xx, k.xy, k.yy};
        },
        [](const Vec& x, const Vec& v) {
          Sym2<double> k{}, g = {0, 0, 0};
          conic_from_covariance(Sym2<double>{x[0], x[1], x[2]}, &k);
          conic_from_covariance_vjp(k, Sym2<double>{v[0], v[1], v[2]}, &g);
          return Vec{g.xx, g.xy, g.yy};
        },
        Vec{a, b, c}, rng);
    const double lambda_max = 0.5 * (a + c) + std::sqrt(0.25 * (a - c) * (a - c) + b * b);
    EXPECT_EQ(radius_3sigma(Sym2<double>{a, b, c}),
              static_cast<int>(std::ceil(3 * std::sqrt(lambda_max))));
  }
  Sym2<double> k;
  EXPECT_FALSE(conic_from_covariance(Sym2<double>{1.0, 2.0, 1.0}, &k));  // indefinite
}

TEST(GaussianMath, AlphaAndItsVjp) {
  std::mt19937_64 rng(6);
  const Sym2<double> conic = {0.08, -0.02, 0.05};
  const Vec2<double> mean = {10.3, 7.6};
  double alpha = 0, vis = 0;
  ASSERT_TRUE(evaluate_alpha(conic, mean, 0.6, 10.3, 7.6, &alpha, &vis));
  EXPECT_DOUBLE_EQ(alpha, 0.6);
  ASSERT_TRUE(evaluate_alpha(conic, mean, 1.0, 10.3, 7.6, &alpha, &vis));
  EXPECT_DOUBLE_EQ(alpha, double(kAlphaMax));
  EXPECT_FALSE(evaluate_alpha(conic, mean, 0.6, 40.0, 40.0, &alpha, &vis));  // below 1/255
  // Inputs: conic (3), mean (2), opacity; pixel fixed.
  const double px = 12.0, py = 5.0;
  const Vec x = {conic.xx, conic.xy, conic.yy, mean.x, mean.y, 0.6};
  check_vjp(
      [&](const Vec& x) {
        double a = 0, g = 0;
        evaluate_alpha(Sym2<double>{x[0], x[1], x[2]}, Vec2<double>{x[3], x[4]}, x[5], px, py, &a,
                       &g);
        return Vec{a};
      },
      [&](const Vec& x, const Vec& v) {
        Sym2<double> g_c = {0, 0, 0};
        Vec2<double> g_m = {0, 0};
        double g_o = 0, a = 0, g = 0;
        EXPECT_TRUE(evaluate_alpha(Sym2<double>{x[0], x[1], x[2]}, Vec2<double>{x[3], x[4]}, x[5],
                                   px, py, &a, &g));
        evaluate_alpha_vjp(Sym2<double>{x[0], x[1], x[2]}, Vec2<double>{x[3], x[4]}, x[5], px, py,
                           g, v[0], &g_c, &g_m, &g_o);
        return Vec{g_c.xx, g_c.xy, g_c.yy, g_m.x, g_m.y, g_o};
      },
      x, rng);
  // Under the 0.99 cap alpha is flat: the VJP gives zero.
  Sym2<double> g_c = {0, 0, 0};
  Vec2<double> g_m = {0, 0};
  double g_o = 0;
  ASSERT_TRUE(evaluate_alpha(conic, mean, 1.0, 10.3, 7.6, &alpha, &vis));
  evaluate_alpha_vjp(conic, mean, 1.0, 10.3, 7.6, vis, 1.0, &g_c, &g_m, &g_o);
  EXPECT_EQ(g_o, 0.0);
  EXPECT_EQ(g_m.x, 0.0);
  // The extent bounds every pixel where alpha reaches 1/255.
  const Sym2<double> cov = {30.0, 8.0, 12.0};
  Sym2<double> k;
  ASSERT_TRUE(conic_from_covariance(cov, &k));
  Vec2<double> half;
  ASSERT_TRUE(alpha_extent(cov, 0.7, &half));
  for (int dy = -30; dy <= 30; ++dy)
    for (int dx = -30; dx <= 30; ++dx)
      if (evaluate_alpha(k, Vec2<double>{0.25, -0.4}, 0.7, double(dx), double(dy), &alpha, &vis)) {
        EXPECT_LE(std::abs(dx - 0.25), half.x);
        EXPECT_LE(std::abs(dy + 0.4), half.y);
        // ... and the row span of the power threshold contains it.
        double lo = 0, hi = 0;
        const double min_power = -std::log(255 * 0.7);
        ASSERT_TRUE(power_row_span(k, -0.4 - dy, min_power, &lo, &hi));
        EXPECT_GE(0.25 - dx, lo - 1e-9);
        EXPECT_LE(0.25 - dx, hi + 1e-9);
      }
}

// Composites a pixel from per-Gaussian (α, r, g, b, z) and returns (C, D, A).
Vec composite_fn(const Vec& x, const Vec3<double>& bg) {
  PixelAccum<double> acc = pixel_accum_start<double>();
  for (size_t i = 0; i + 5 <= x.size(); i += 5)
    EXPECT_TRUE(composite_step(x[i], Vec3<double>{x[i + 1], x[i + 2], x[i + 3]}, x[i + 4], &acc));
  const double t = acc.transmittance;
  return {acc.rgb.x + t * bg.x, acc.rgb.y + t * bg.y, acc.rgb.z + t * bg.z, acc.depth, 1 - t};
}

TEST(GaussianMath, CompositingAndItsVjp) {
  std::mt19937_64 rng(7);
  const Vec3<double> bg = {0.2, 0.5, 0.9};
  Vec x;
  for (int i = 0; i < 5; ++i) {
    x.push_back(uniform(rng, 0.1, 0.8));
    for (double c : random_vec(rng, 3, 0, 1)) x.push_back(c);
    x.push_back(uniform(rng, 1, 4));
  }
  check_vjp([&](const Vec& x) { return composite_fn(x, bg); },
            [&](const Vec& x, const Vec& v) {
              const double t_final = 1 - composite_fn(x, bg)[4];
              PixelAccumBack<double> back = pixel_accum_back_start(t_final);
              Vec g(x.size(), 0.0);
              for (size_t i = x.size(); i >= 5; i -= 5) {
                const size_t b = i - 5;
                Vec3<double> g_c = {0, 0, 0};
                double g_z = 0;
                g[b] = composite_step_vjp(x[b], Vec3<double>{x[b + 1], x[b + 2], x[b + 3]},
                                          x[b + 4], t_final, bg, Vec3<double>{v[0], v[1], v[2]},
                                          v[3], v[4], &back, &g_c, &g_z);
                g[b + 1] = g_c.x;
                g[b + 2] = g_c.y;
                g[b + 3] = g_c.z;
                g[b + 4] = g_z;
              }
              EXPECT_NEAR(back.transmittance, 1.0, 1e-12);
              return g;
            },
            x, rng);
  // Early stop: a Gaussian that would take T below 1e-4 is refused and leaves the pixel alone.
  PixelAccum<double> acc = pixel_accum_start<double>();
  acc.transmittance = 2e-4;
  EXPECT_FALSE(composite_step(0.9, Vec3<double>{1, 1, 1}, 1.0, &acc));
  EXPECT_EQ(acc.transmittance, 2e-4);
  EXPECT_EQ(acc.rgb.x, 0.0);
}

// The chained front end, including the pose gradients.
TEST(GaussianMath, ProjectGaussianAndItsVjp) {
  std::mt19937_64 rng(8);
  const Mat3<double> R0 = random_rotation(rng);
  // Inputs: position (3), log_scale (3), quaternion (4), R_cw (9), t_cw (3).
  Vec x = {0.1, -0.2, 0.3, -2.5, -3.0, -2.2, 0.8, 0.3, -0.4, 0.5};
  append(&x, R0);
  // Put the Gaussian 2 m in front of the camera.
  const Vec3<double> p_c0 = R0 * Vec3<double>{x[0], x[1], x[2]};
  for (double d : {0.05 - p_c0.x, -0.03 - p_c0.y, 2.0 - p_c0.z}) x.push_back(d);
  auto view_of = [](const Vec& x) {
    CameraView<double> cam;
    cam.K = kK;
    cam.R_cw = mat3_of(x.data() + 10);
    cam.t_cw = {x[19], x[20], x[21]};
    cam.near = 0.01;
    return cam;
  };
  auto f = [&](const Vec& x) {
    ProjectedGaussian<double> p{};
    EXPECT_TRUE(project_gaussian(x.data(), x.data() + 3, x.data() + 6, view_of(x), &p));
    return Vec{p.mean2d.x, p.mean2d.y, p.conic.xx, p.conic.xy, p.conic.yy, p.depth};
  };
  EXPECT_NEAR(f(x)[5], 2.0, 1e-12);
  check_vjp(
      f,
      [&](const Vec& x, const Vec& v) {
        Vec g(x.size(), 0.0);
        Mat3<double> g_R = mat3_zero<double>();
        Vec3<double> g_t = {0, 0, 0};
        project_gaussian_vjp(x.data(), x.data() + 3, x.data() + 6, view_of(x),
                             Vec2<double>{v[0], v[1]}, Sym2<double>{v[2], v[3], v[4]}, v[5],
                             g.data(), g.data() + 3, g.data() + 6, &g_R, &g_t);
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) g[10 + 3 * i + j] = g_R.m[i][j];
        g[19] = g_t.x;
        g[20] = g_t.y;
        g[21] = g_t.z;
        return g;
      },
      x, rng, 1e-7, 1e-6);
}


// The tile test of the binning (exact ellipse–tile overlap) is conservative: where it says a
// rectangle is missed, no pixel centre in it passes evaluate_alpha(), so binning by it changes no
// pixel. It also misses real tiles (else it would save nothing): thin, tilted ellipses leave
// corners of their square.
TEST(Math, EllipseTileTestMissesOnlyWhatNoPixelReaches) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int missed = 0, checked = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    // An ellipse from random axes (0.3-30 px) and angle, and the rectangle of a 16 px tile near it.
    const double a = 0.3 + 30 * u(rng) * u(rng), b = 0.3 + 30 * u(rng) * u(rng), th = 3.14159 * u(rng);
    const double c = std::cos(th), s = std::sin(th);
    const double sxx = a * a * c * c + b * b * s * s, syy = a * a * s * s + b * b * c * c, sxy = (a * a - b * b) * c * s;
    const double det = sxx * syy - sxy * sxy;
    const Sym2<float> conic{float(syy / det), float(-sxy / det), float(sxx / det)};
    const Vec2<float> mean{float(100 * u(rng)), float(100 * u(rng))};
    const float opacity = float(0.01 + 0.98 * u(rng));
    const int x0 = int(mean.x + (u(rng) - 0.5) * 4 * std::max(a, b)) - 8, y0 = int(mean.y + (u(rng) - 0.5) * 4 * std::max(a, b)) - 8;
    const bool reaches = ellipse_reaches_rect(conic, mean, opacity, float(x0), float(y0), float(x0 + 15), float(y0 + 15));
    if (reaches) continue;
    ++missed;
    for (int y = y0; y <= y0 + 15; ++y)
      for (int x = x0; x <= x0 + 15; ++x) {
        float alpha, vis;
        ++checked;
        ASSERT_FALSE(evaluate_alpha(conic, mean, opacity, float(x), float(y), &alpha, &vis))
            << "trial " << trial << ": pixel " << x << "," << y << " passes in a missed tile";
      }
  }
  EXPECT_GT(missed, 400) << "the test culls tiles";
  EXPECT_GT(checked, 400 * 256);
  // Where the rectangle holds the mean, it always reaches (if the Gaussian can reach 1/255 at all).
  const Sym2<float> round{0.1f, 0.f, 0.1f};
  EXPECT_TRUE(ellipse_reaches_rect(round, Vec2<float>{5.f, 5.f}, 0.5f, 0.f, 0.f, 15.f, 15.f));
  EXPECT_FALSE(ellipse_reaches_rect(round, Vec2<float>{5.f, 5.f}, 0.003f, 0.f, 0.f, 15.f, 15.f)) << "o·255 < 1";
}

}  // namespace
}  // namespace dqo::gs
