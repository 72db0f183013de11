// align_dense: coarse-to-fine Gauss-Newton on SE(3) over projective point-to-plane ICP and a
// photometric term, both robustified with Huber weights (IRLS).
//
// Each current sample p_cur is mapped by the estimate into the reference frame
// (q = T_ref_cur p_cur) and projected into the reference image; the reference surfel at the
// nearest pixel is its correspondence (projective data association, KinectFusion), rejected when
// farther than the level's distance limit or when the normals differ by more than
// max_normal_angle_deg. An accepted pair contributes
//   r_geo = n_refᵀ (q - p_ref)                      weight huber(r_geo) / σ(z)²
//   r_pho = I_ref(π(q)) - I_cur(p_cur)              weight colour_weight huber(r_pho) / σ_I²
// with I_ref and its gradient sampled bilinearly. The photometric term only uses pixels the
// geometry accepted, so occlusions do not drag it; in textureless scenes the geometry alone holds.
//
// Schedule: geometry alone until, on one of the two finest levels, a step moves the image by less
// than kColourStartPx; from then on both terms. Far from the solution the photometric cost of a
// textured scene is riddled with local minima (a stripe matched to its neighbour); the geometric
// one is smooth but has weak directions, which the colour term then pins down. The distance limit
// doubles per level above the finest so that coarse levels accept the larger displacements of a
// poor guess. Each level stops when a step moves the image by less than convergence_px.
//
// Failure (ok = false, the guess returned): too few correspondences or inliers at the finest
// level, a whitened residual RMS above max_whitened_rms (a wrong local minimum), or a solution
// farther from the guess than max_update_m / max_update_deg.
//
// The normal equations are accumulated by hand (6x6, vectorised float blocks flushed to double,
// see dense_residuals.h) rather than through a Ceres problem with one residual block per pixel: at
// up to 150k residuals per iteration and a 5 ms budget for the whole alignment, Ceres' per-block
// bookkeeping and its own Jacobian evaluation would cost an order of magnitude more than the
// arithmetic. The solver steps in the left perturbation (exp(xi) T, cheapest per pixel) and
// converts the information matrix to the right perturbation promised by the header at the end.

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <Eigen/Cholesky>

#include "cpu_clones.h"
#include "dense_residuals.h"
#include "dqo_map/tracking/dense_alignment.h"

namespace dqo::tracking {
namespace {

using Level = RgbdPyramid::Level;
using dense::Matrix6d;

constexpr float kMinZ = 1e-3f;
// A step needs this many correspondences to be worth taking (six unknowns, robust weights).
constexpr int kMinStepCorrespondences = 30;
// The photometric term joins once a geometric step moves the image by less than this (pixels of
// the level): then the colour residuals compare the right texels.
constexpr double kColourStartPx = 0.5;
// ... and only on the finest levels: on the coarsest, box-filtered texture aliases and a geometric
// solution can still be in a wrong basin, which the colour term would then hold on to.
constexpr int kColourLevels = 2;

struct Pass {
  dense::NormalEquations ne;
  int inliers = 0;
  double sq_point_to_plane = 0.0;
};

struct LoopConstants {
  float max_d2;
  float cos_normal;
  float huber_geo;
  float huber_pho;
  float pho_weight;  // colour_weight / σ_I²
};

// Scratch for one chunk of samples, through which the phases of accumulate() talk (~40 KB, on the
// stack, L1-resident).
struct Chunk {
  static constexpr int kSize = dense::ResidualBlock::kSize;
  alignas(32) float u[kSize];   // projection into the reference level (clamped; see `idx`)
  alignas(32) float v[kSize];
  alignas(32) float inv_z[kSize];
  alignas(32) float nx[kSize];  // the current normal rotated into the reference frame
  alignas(32) float ny[kSize];
  alignas(32) float nz[kSize];
  alignas(32) int32_t idx[kSize];  // nearest reference pixel; 0 (no normal there) when off-image
  alignas(32) float mpx[kSize];    // the reference surfel at idx
  alignas(32) float mpy[kSize];
  alignas(32) float mpz[kSize];
  alignas(32) float mnx[kSize];
  alignas(32) float mny[kSize];
  alignas(32) float mnz[kSize];
  alignas(32) int32_t corner[kSize];  // top-left texel of the bilinear lookup at (u, v)
  alignas(32) float w00[kSize];       // its weights
  alignas(32) float w10[kSize];
  alignas(32) float w01[kSize];
  alignas(32) float w11[kSize];
  alignas(32) float I[kSize];      // the reference texel at (u, v), bilinear
  alignas(32) float gx[kSize];
  alignas(32) float gy[kSize];
  dense::ResidualBlock geo;
  dense::ResidualBlock pho;
};

// The loops below stay vectorisable under the default -ftrapping-math (checked with
// -fopt-info-vec-missed; GCC will not if-convert floating-point arithmetic that might sit inside a
// condition), so every value is computed unconditionally and kept finite (missing surfels are
// zeros, not NaN; nothing divides by zero), a rejection multiplies by a 0/1 mask or is a chained
// select between finished values, and no select feeds a division.
inline float mask(bool condition) { return condition ? 1.0f : 0.0f; }

// Slots [n, end) of a block count for nothing.
void zero_tail(dense::ResidualBlock* b, int n, int end) {
  for (int i = n; i < end; ++i) {
    b->qx[i] = b->qy[i] = b->qz[i] = b->ax[i] = b->ay[i] = b->az[i] = b->r[i] = b->w[i] = 0.0f;
  }
}

// One pass over the current samples at one level: the normal equations at T_ref_cur. The samples
// go through in chunks, each in phases that are either plain arithmetic on arrays (transform and
// project; residuals and weights; the 6x6 sums), which the compiler vectorises, or the gathers
// from the reference images, which stay scalar. Rejected samples keep their slot with weight 0
// rather than being compacted away, so no phase branches.
DQO_AVX2_CLONE
void accumulate(const Level& ref, const Level& cur, const SE3& T_ref_cur, const LoopConstants& k,
                bool colour, Pass* out) {
  const Eigen::Matrix3f R = T_ref_cur.rotation().cast<float>();
  const Eigen::Vector3f t = T_ref_cur.translation().cast<float>();
  const float r00 = R(0, 0), r01 = R(0, 1), r02 = R(0, 2);
  const float r10 = R(1, 0), r11 = R(1, 1), r12 = R(1, 2);
  const float r20 = R(2, 0), r21 = R(2, 1), r22 = R(2, 2);
  const float tx = t.x(), ty = t.y(), tz = t.z();
  const float fx = static_cast<float>(ref.camera.fx), fy = static_cast<float>(ref.camera.fy);
  const float cx = static_cast<float>(ref.camera.cx), cy = static_cast<float>(ref.camera.cy);
  const int w = ref.camera.width;
  const float wf = static_cast<float>(w);
  // Bilinear interpolation reads pixel x0 + 1, so u stays below width - 1.
  const float u_max = static_cast<float>(ref.camera.width - 1) - 1e-3f;
  const float v_max = static_cast<float>(ref.camera.height - 1) - 1e-3f;
  const RgbdPyramid::Surfel* surfels = ref.surfels.data();
  const RgbdPyramid::Texel* texels = ref.texels.data();
  const RgbdPyramid::Samples& S = cur.samples;
  const int total = static_cast<int>(S.size());
  // Locals, not reads through `k`, which the compiler could not keep in registers across stores.
  const float max_d2 = k.max_d2, cos_normal = k.cos_normal;
  const float huber_geo = k.huber_geo, huber_pho = k.huber_pho, pho_weight = k.pho_weight;

  Chunk c;
  dense::ResidualBlock& geo = c.geo;
  dense::ResidualBlock& pho = c.pho;
  int inliers = 0;
  double sq = 0.0;
  for (int begin = 0; begin < total; begin += Chunk::kSize) {
    const int n = std::min(Chunk::kSize, total - begin);
    const int end = (n + dense::NormalEquations::kLanes - 1) / dense::NormalEquations::kLanes *
                    dense::NormalEquations::kLanes;
    const float* px = S.x.data() + begin;
    const float* py = S.y.data() + begin;
    const float* pz = S.z.data() + begin;
    const float* nx = S.nx.data() + begin;
    const float* ny = S.ny.data() + begin;
    const float* nz = S.nz.data() + begin;

    // 1. Transform into the reference frame and project (vectorised).
    for (int i = 0; i < n; ++i) {
      const float qx = r00 * px[i] + r01 * py[i] + r02 * pz[i] + tx;
      const float qy = r10 * px[i] + r11 * py[i] + r12 * pz[i] + ty;
      const float qz = r20 * px[i] + r21 * py[i] + r22 * pz[i] + tz;
      geo.qx[i] = qx;
      geo.qy[i] = qy;
      geo.qz[i] = qz;
      // Finite for any qz (|iz| <= 1e20, and a rejected sample's gradient is zeroed before it
      // meets iz again); exact where it matters, qz >= kMinZ.
      const float iz = 1.0f / (std::abs(qz) + 1e-20f);
      const float u = fx * qx * iz + cx;
      const float v = fy * qy * iz + cy;
      // Clamped into the image, so that the conversions below stay in range; a sample whose
      // projection the clamp moved is off the image.
      const float uc = std::min(std::max(0.0f, u), u_max);
      const float vc = std::min(std::max(0.0f, v), v_max);
      float in = qz >= kMinZ ? 1.0f : 0.0f;
      in = uc == u ? in : 0.0f;
      in = vc == v ? in : 0.0f;
      // Row and column in float (exact below 2^24), so no 32-bit integer multiply is needed.
      const float row = static_cast<float>(static_cast<int32_t>(vc + 0.5f));
      const float col = static_cast<float>(static_cast<int32_t>(uc + 0.5f));
      c.idx[i] = static_cast<int32_t>(in * (row * wf + col));
      c.u[i] = uc;
      c.v[i] = vc;
      c.inv_z[i] = iz;
      c.nx[i] = r00 * nx[i] + r01 * ny[i] + r02 * nz[i];
      c.ny[i] = r10 * nx[i] + r11 * ny[i] + r12 * nz[i];
      c.nz[i] = r20 * nx[i] + r21 * ny[i] + r22 * nz[i];
    }
    // 2. Gather the reference surfels (off-image samples read pixel 0: on the border, no normal).
    for (int i = 0; i < n; ++i) {
      const RgbdPyramid::Surfel& m = surfels[c.idx[i]];
      c.mpx[i] = m.p.x();
      c.mpy[i] = m.p.y();
      c.mpz[i] = m.p.z();
      c.mnx[i] = m.n.x();
      c.mny[i] = m.n.y();
      c.mnz[i] = m.n.z();
    }
    // 3. Point-to-plane residuals, gating and weights (vectorised).
    const float* inv_sigma2 = S.inv_sigma2.data() + begin;
    for (int i = 0; i < n; ++i) {
      const float mx = c.mnx[i], my = c.mny[i], mz = c.mnz[i];
      const float dx = geo.qx[i] - c.mpx[i];
      const float dy = geo.qy[i] - c.mpy[i];
      const float dz = geo.qz[i] - c.mpz[i];
      const float d2 = dx * dx + dy * dy + dz * dz;
      const float cos_angle = c.nx[i] * mx + c.ny[i] * my + c.nz[i] * mz;
      // A missing surfel has n = 0, so cos_angle = 0 rejects it.
      const float ok = mask(cos_angle >= cos_normal) * mask(d2 <= max_d2);
      const float r = mx * dx + my * dy + mz * dz;
      const float weight = dense::huber_weight(r, huber_geo) * inv_sigma2[i];
      geo.r[i] = ok * r;
      geo.w[i] = ok * weight;
      geo.ax[i] = ok * mx;
      geo.ay[i] = ok * my;
      geo.az[i] = ok * mz;
    }
    zero_tail(&geo, n, end);
    for (int i = 0; i < n; ++i) {
      inliers += geo.w[i] > 0.0f;
      sq += geo.r[i] * geo.r[i];
    }
    // 4. The geometric sums (vectorised).
    out->ne.add(geo, end);
    if (!colour) continue;

    // 5. Bilinear lookups of the reference intensity and gradient: the corner and the weights for
    // all samples (vectorised; (u, v) is already clamped into the image), then the four texels
    // blended as 4-float vectors (scalar gather), then the gradient zeroed wherever the geometry
    // rejected the sample or it is untextured (the mask in phase 6 needs it finite, and iz may be
    // huge there).
    const float* textured = S.textured.data() + begin;
    for (int i = 0; i < n; ++i) {
      const float x0 = static_cast<float>(static_cast<int32_t>(c.u[i]));
      const float y0 = static_cast<float>(static_cast<int32_t>(c.v[i]));
      const float a = c.u[i] - x0, b = c.v[i] - y0;
      c.corner[i] = static_cast<int32_t>(y0 * wf + x0);
      c.w00[i] = (1.0f - a) * (1.0f - b);
      c.w10[i] = a * (1.0f - b);
      c.w01[i] = (1.0f - a) * b;
      c.w11[i] = a * b;
    }
    for (int i = 0; i < n; ++i) {
      const RgbdPyramid::Texel* t = texels + c.corner[i];
      using V4 = Eigen::Map<const Eigen::Vector4f>;
      const Eigen::Vector4f blend =
          c.w00[i] * V4(&t[0].intensity) + c.w10[i] * V4(&t[1].intensity) +
          c.w01[i] * V4(&t[w].intensity) + c.w11[i] * V4(&t[w + 1].intensity);
      c.I[i] = blend[0];
      c.gx[i] = blend[1];
      c.gy[i] = blend[2];
    }
    for (int i = 0; i < n; ++i) {
      const float use = mask(geo.w[i] > 0.0f) * textured[i];
      c.gx[i] *= use;
      c.gy[i] *= use;
    }
    // 6. Photometric residuals and weights (vectorised), then their sums.
    const float* intensity = S.intensity.data() + begin;
    for (int i = 0; i < n; ++i) {
      const float ok = mask(geo.w[i] > 0.0f) * textured[i];
      const float iz = c.inv_z[i];
      const float qx = geo.qx[i], qy = geo.qy[i];
      // dense::photometric_direction, inlined with the clamped iz (it would divide by qz).
      const float a = c.gx[i] * fx * iz;
      const float b = c.gy[i] * fy * iz;
      const float az = -(a * qx + b * qy) * iz;
      const float rp = c.I[i] - intensity[i];
      const float weight = dense::huber_weight(rp, huber_pho) * pho_weight;
      pho.qx[i] = qx;
      pho.qy[i] = qy;
      pho.qz[i] = geo.qz[i];
      pho.ax[i] = ok * a;
      pho.ay[i] = ok * b;
      pho.az[i] = ok * az;
      pho.r[i] = ok * rp;
      pho.w[i] = ok * weight;
    }
    zero_tail(&pho, n, end);
    out->ne.add(pho, end);
  }
  out->inliers = inliers;
  out->sq_point_to_plane = sq;
}

// Gauss-Newton step for H xi = -g, with a whisper of Levenberg damping so that directions the
// scene does not constrain (a single plane leaves three) stay where they are instead of blowing up.
bool solve_step(const Matrix6d& H, const Vector6d& g, Vector6d* xi) {
  Matrix6d A = H;
  A.diagonal() *= 1.0 + 1e-6;
  A.diagonal().array() += 1e-12 * H.diagonal().maxCoeff() + 1e-12;
  const Eigen::LDLT<Matrix6d> ldlt(A);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return false;
  *xi = -ldlt.solve(g);
  return xi->allFinite();
}

// How far a step moves the image of a point at the level's mean depth, in pixels of the level.
double step_pixels(const Vector6d& xi, const Level& level) {
  const double z = std::max(level.mean_depth, 0.1);
  return level.camera.fx * (xi.tail<3>().norm() + xi.head<3>().norm() / z);
}

double rotation_angle_deg(const SE3& T) {
  const double w = std::min(1.0, std::abs(T.quaternion().w()));
  return 2.0 * std::acos(w) * 180.0 / M_PI;
}

}  // namespace

DenseResult align_dense(const RgbdPyramid& reference, const RgbdPyramid& current,
                        const SE3& T_ref_cur_guess, const DenseParams& params) {
  DenseResult result;
  result.T_ref_cur = T_ref_cur_guess;
  auto fail = [&](const char* why) {
    result.ok = false;
    result.failure = why;
    result.T_ref_cur = T_ref_cur_guess;
    result.information.setZero();
    return result;
  };
  if (reference.levels() == 0 || reference.levels() != current.levels() ||
      reference.finest_level() != current.finest_level()) {
    return fail("pyramids built with different parameters");
  }
  const int finest = current.finest_level();
  if (current.valid_points(finest) == 0 || reference.valid_points(finest) == 0) {
    return fail("no valid depth");
  }

  LoopConstants k;
  // Positive, so that a missing surfel (zero normal) never passes.
  k.cos_normal = static_cast<float>(
      std::max(1e-3, std::cos(params.max_normal_angle_deg * M_PI / 180.0)));
  k.huber_geo = static_cast<float>(params.huber_delta);
  k.huber_pho = static_cast<float>(params.huber_delta_intensity);
  k.pho_weight =
      static_cast<float>(params.colour_weight / (params.intensity_sigma * params.intensity_sigma));
  const bool colour = params.colour_weight > 0.0 && reference.has_colour() && current.has_colour();

  SE3 T = T_ref_cur_guess;
  bool colour_on = false;
  Pass last;                    // the finest level's pass at the pose before its last step
  bool last_is_final = false;   // ... which is (to within convergence) the returned pose
  for (int l = current.levels() - 1; l >= finest; --l) {
    const Level& ref = reference.level(l);
    const Level& cur = current.level(l);
    if (!ref.built() || !cur.built()) continue;
    const double max_d = params.max_point_distance * std::ldexp(1.0, l - finest);
    k.max_d2 = static_cast<float>(max_d * max_d);
    const int iterations = params.iterations[std::min(l, 3)];
    for (int it = 0; it < iterations; ++it) {
      Pass& pass = last;  // only the finest level's pass is kept as `last`
      pass = Pass();
      accumulate(ref, cur, T, k, colour_on, &pass);
      last_is_final = l == finest && colour_on == colour;
      if (pass.inliers < kMinStepCorrespondences) break;
      Vector6d xi;
      if (!solve_step(pass.ne.hessian(), pass.ne.gradient(), &xi)) break;
      T = SE3::exp(xi) * T;
      ++result.iterations;
      if (!T.translation().allFinite() || !T.quaternion().coeffs().allFinite()) {
        return fail("diverged (not finite)");
      }
      const double px = step_pixels(xi, cur);
      const bool converged = px < params.convergence_px;
      // After a step that was not negligible the pass belongs to the previous pose.
      last_is_final = l == finest && converged && colour_on == colour;
      if (colour && !colour_on && l <= finest + kColourLevels - 1 && px < kColourStartPx) {
        colour_on = true;
        continue;  // one more step with both terms before calling it converged
      }
      if (converged) break;
    }
  }
  if (!last_is_final) {
    last = Pass();
    accumulate(reference.level(finest), current.level(finest), T, k, colour, &last);
  }

  result.inliers = last.inliers;
  result.inlier_ratio = static_cast<double>(last.inliers) / current.valid_points(finest);
  result.rmse_m = last.inliers > 0 ? std::sqrt(last.sq_point_to_plane / last.inliers) : 0.0;
  result.whitened_rms = last.inliers > 0 ? std::sqrt(last.ne.cost() / last.inliers) : 0.0;
  if (last.inliers < params.min_inliers) return fail("too few correspondences");
  if (result.inlier_ratio < params.min_inlier_ratio) return fail("too few inliers");
  // A wrong local minimum (surfaces slid along each other after a poor guess) leaves residuals
  // several σ wide where a right one leaves them within the noise; on `tabletop` the two sit near
  // 2.5 and 0.35.
  if (result.whitened_rms > params.max_whitened_rms) return fail("residuals too large");
  const SE3 update = T_ref_cur_guess.inverse() * T;
  if (update.translation().norm() > params.max_update_m ||
      rotation_angle_deg(update) > params.max_update_deg) {
    return fail("diverged (too far from the guess)");
  }
  const Matrix6d Ad = dense::adjoint(T);
  result.information = Ad.transpose() * last.ne.hessian() * Ad;
  result.information = 0.5 * (result.information + result.information.transpose());
  result.T_ref_cur = T;
  result.ok = true;
  return result;
}

}  // namespace dqo::tracking
