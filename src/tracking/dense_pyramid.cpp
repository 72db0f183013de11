// RgbdPyramid: the per-frame preparation of dense alignment. Depth and intensity are halved level
// by level (2x2 blocks, depth averaged only within one surface), then every level that is aligned
// gets intensity gradients, back-projected points, normals and the compact list of samples.
// Everything here runs once per frame, so the alignment's iterations only read. Plain loops over
// rows: no allocation once the buffers exist (rebuild()), and nothing that hides the arithmetic.

#include <algorithm>
#include <cmath>
#include <limits>

#include "cpu_clones.h"
#include "dqo_map/tracking/dense_alignment.h"

namespace dqo::tracking {
namespace {

using Level = RgbdPyramid::Level;

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr int kMaxLevels = 4;  // DenseParams::iterations has four entries
// The steepest surface treated as continuous: tilted 75° from the viewing ray, i.e. a depth step of
// tan(75°) ≈ 3.7 pixel footprints between neighbours. Steeper steps are depth edges, across which
// depth is not averaged and normals are not taken.
constexpr float kMaxSlope = 3.7f;

// Largest depth difference between two pixels `pixels` apart on one surface at depth z, for a
// level of focal length 1/inv_f: the slope above plus three times the sensor noise (σ = k z²).
inline float max_depth_step(float z, float pixels, float inv_f, float k_noise) {
  return pixels * kMaxSlope * z * inv_f + 3.0f * k_noise * z * z;
}

// Depth in the levels is 0 where there is none (never NaN: a NaN check next to arithmetic keeps
// GCC from vectorising a loop).
inline float sanitise_depth(float d, float max_depth) {
  const float valid = d > 0.0f ? d : 0.0f;  // also maps NaN to 0
  return valid <= max_depth ? valid : 0.0f;
}

// One depth for a 2x2 block: the valid depths within one surface of the block's lower median
// (the nearer surface wins a tie), averaged. Mixing a foreground and a background depth would
// invent a surface floating in between. Branch-free, so that the loops calling it vectorise: a
// sorting network, missing depths sorted last as +inf (never within the limit), and an empty
// block giving 0.
inline float merge_depths(float a, float b, float c, float d, float inv_f, float k_noise) {
  float v0 = a > 0.0f ? a : kInf, v1 = b > 0.0f ? b : kInf;
  float v2 = c > 0.0f ? c : kInf, v3 = d > 0.0f ? d : kInf;
  auto order = [](float& x, float& y) {
    const float lo = std::min(x, y);
    y = std::max(x, y);
    x = lo;
  };
  order(v0, v1);
  order(v2, v3);
  order(v0, v2);
  order(v1, v3);
  order(v1, v2);
  // The lower median of the valid values: v1 when three or four are valid, else v0.
  const float ref = v2 < kInf ? v1 : v0;
  const float limit = max_depth_step(ref, 1.5f, inv_f, k_noise);  // diagonal neighbours
  // 0/1 each: false for inf - inf = NaN; min() keeps the products finite where v is +inf.
  const float in0 = std::abs(v0 - ref) <= limit ? 1.0f : 0.0f;
  const float in1 = std::abs(v1 - ref) <= limit ? 1.0f : 0.0f;
  const float in2 = std::abs(v2 - ref) <= limit ? 1.0f : 0.0f;
  const float in3 = std::abs(v3 - ref) <= limit ? 1.0f : 0.0f;
  constexpr float kBig = 1e30f;
  const float sum = in0 * std::min(v0, kBig) + in1 * std::min(v1, kBig) +
                    in2 * std::min(v2, kBig) + in3 * std::min(v3, kBig);
  return sum / (in0 + in1 + in2 + in3 + 1e-30f);  // no select before a division (see normal_row)
}

PinholeCamera half_camera(const PinholeCamera& c) {
  PinholeCamera h;
  h.width = c.width / 2;
  h.height = c.height / 2;
  h.fx = 0.5 * c.fx;
  h.fy = 0.5 * c.fy;
  // The 2x2 block of pixels 2x and 2x+1 has its centre at 2x + 0.5 of the finer level.
  h.cx = 0.5 * (c.cx - 0.5);
  h.cy = 0.5 * (c.cy - 0.5);
  return h;
}

// Level 1 straight from the input (level 0 is never aligned by default, so it is not stored).
DQO_AVX2_CLONE
void halve_input(const DepthImage& depth, const ImageRgb8* rgb, float max_depth, float inv_f_fine,
                 float k_noise, Level* out) {
  const int w = out->camera.width;
  const int h = out->camera.height;
  const int wi = depth.width;
  out->depth.resize(static_cast<size_t>(w) * h);
  if (rgb) out->texels.resize(static_cast<size_t>(w) * h);
  // Rec. 601 luma of the block's four pixels, averaged, scaled to [0, 1].
  const float kr = 0.299f / (4.0f * 255.0f), kg = 0.587f / (4.0f * 255.0f),
              kb = 0.114f / (4.0f * 255.0f);
  for (int y = 0; y < h; ++y) {
    const float* d0 = depth.data.data() + static_cast<size_t>(2 * y) * wi;
    const float* d1 = d0 + wi;
    float* dout = out->depth.data() + static_cast<size_t>(y) * w;
    for (int x = 0; x < w; ++x) {
      dout[x] = merge_depths(sanitise_depth(d0[2 * x], max_depth),
                             sanitise_depth(d0[2 * x + 1], max_depth),
                             sanitise_depth(d1[2 * x], max_depth),
                             sanitise_depth(d1[2 * x + 1], max_depth), inv_f_fine, k_noise);
    }
    if (!rgb) continue;
    const uint8_t* c0 = rgb->data.data() + static_cast<size_t>(2 * y) * wi * 3;
    const uint8_t* c1 = c0 + static_cast<size_t>(wi) * 3;
    RgbdPyramid::Texel* tout = out->texels.data() + static_cast<size_t>(y) * w;
    for (int x = 0; x < w; ++x) {
      const uint8_t* a = c0 + 6 * x;
      const uint8_t* b = c1 + 6 * x;
      const int r = a[0] + a[3] + b[0] + b[3];
      const int g = a[1] + a[4] + b[1] + b[4];
      const int bl = a[2] + a[5] + b[2] + b[5];
      tout[x].intensity = kr * r + kg * g + kb * bl;
    }
  }
}

// Level l + 1 from level l's depth and intensity.
DQO_AVX2_CLONE
void halve_level(const Level& fine, bool colour, float inv_f_fine, float k_noise, Level* out) {
  const int w = out->camera.width;
  const int h = out->camera.height;
  const int wf = fine.camera.width;
  out->depth.resize(static_cast<size_t>(w) * h);
  if (colour) out->texels.resize(static_cast<size_t>(w) * h);
  for (int y = 0; y < h; ++y) {
    const float* d0 = fine.depth.data() + static_cast<size_t>(2 * y) * wf;
    const float* d1 = d0 + wf;
    float* dout = out->depth.data() + static_cast<size_t>(y) * w;
    for (int x = 0; x < w; ++x) {
      dout[x] = merge_depths(d0[2 * x], d0[2 * x + 1], d1[2 * x], d1[2 * x + 1], inv_f_fine,
                             k_noise);
    }
    if (!colour) continue;
    const RgbdPyramid::Texel* t0 = fine.texels.data() + static_cast<size_t>(2 * y) * wf;
    const RgbdPyramid::Texel* t1 = t0 + wf;
    RgbdPyramid::Texel* tout = out->texels.data() + static_cast<size_t>(y) * w;
    for (int x = 0; x < w; ++x) {
      tout[x].intensity = 0.25f * (t0[2 * x].intensity + t0[2 * x + 1].intensity +
                                   t1[2 * x].intensity + t1[2 * x + 1].intensity);
    }
  }
}

// Central-difference gradients of the texels' intensity; zero on the border.
DQO_AVX2_CLONE
void compute_gradients(Level* L) {
  const int w = L->camera.width;
  const int h = L->camera.height;
  RgbdPyramid::Texel* t = L->texels.data();
  for (int y = 0; y < h; ++y) {
    RgbdPyramid::Texel* row = t + static_cast<size_t>(y) * w;
    if (y == 0 || y == h - 1) {
      for (int x = 0; x < w; ++x) row[x].gx = row[x].gy = 0.0f;
      continue;
    }
    const RgbdPyramid::Texel* up = row - w;
    const RgbdPyramid::Texel* down = row + w;
    row[0].gx = row[0].gy = row[w - 1].gx = row[w - 1].gy = 0.0f;
    for (int x = 1; x < w - 1; ++x) {
      row[x].gx = 0.5f * (row[x + 1].intensity - row[x - 1].intensity);
      row[x].gy = 0.5f * (down[x].intensity - up[x].intensity);
    }
  }
}

// Unnormalised normals of one interior row: the cross product of the central differences of the
// neighbouring points, oriented towards the camera, and zero unless all four neighbours lie on the
// same surface as the centre. Branch-free over plain arrays, so that it vectorises: copysign, not
// a select, for the orientation, and the square root left to the caller (either would keep the
// loop scalar).
DQO_AVX2_CLONE
void normal_row(const float* __restrict du, const float* __restrict dm, const float* __restrict dd,
                int w, float ry_up, float ry, float ry_down, float cx, float ifx, float k_noise,
                float* __restrict nx, float* __restrict ny, float* __restrict nz,
                float* __restrict norms) {
  for (int x = 1; x < w - 1; ++x) {
    const float z = dm[x], zl = dm[x - 1], zr = dm[x + 1], zu = du[x], zd = dd[x];
    const float step = max_depth_step(z, 1.0f, ifx, k_noise);
    const float min_z = std::min(std::min(std::min(z, zl), std::min(zr, zu)), zd);
    const float max_step = std::max(std::max(std::abs(zr - z), std::abs(z - zl)),
                                    std::max(std::abs(zd - z), std::abs(z - zu)));
    float ok = min_z > 0.0f ? 1.0f : 0.0f;
    ok = max_step <= step ? ok : 0.0f;
    const float xf = static_cast<float>(x);
    const float rx = (xf - cx) * ifx;
    const float dx0 = ((xf + 1.0f - cx) * zr - (xf - 1.0f - cx) * zl) * ifx;
    const float dx1 = ry * (zr - zl);
    const float dx2 = zr - zl;
    const float dy0 = rx * (zd - zu);
    const float dy1 = ry_down * zd - ry_up * zu;
    const float dy2 = zd - zu;
    const float n0 = dx1 * dy2 - dx2 * dy1;
    const float n1 = dx2 * dy0 - dx0 * dy2;
    const float n2 = dx0 * dy1 - dx1 * dy0;
    // The point's own direction from the camera is (rx, ry, 1) z.
    const float scale = ok * -std::copysign(1.0f, (n0 * rx + n1 * ry + n2) * z);
    nx[x] = n0 * scale;
    ny[x] = n1 * scale;
    nz[x] = n2 * scale;
    norms[x] = ok * (n0 * n0 + n1 * n1 + n2 * n2);
  }
}

// Points from depth, then normals (see normal_row). Missing points and normals are zeros (see
// Surfel); the border has no normals (align_dense relies on pixel 0 having none).
DQO_AVX2_CLONE
void compute_surfels(Level* L, float k_noise, std::vector<float>* scratch) {
  const PinholeCamera& cam = L->camera;
  const int w = cam.width;
  const int h = cam.height;
  L->surfels.resize(static_cast<size_t>(w) * h);
  scratch->resize(4 * static_cast<size_t>(w));
  float* nx = scratch->data();
  float* ny = nx + w;
  float* nz = ny + w;
  float* norms = nz + w;  // squared length of the unnormalised normal; 0 where there is none
  const float ifx = static_cast<float>(1.0 / cam.fx);
  const float ify = static_cast<float>(1.0 / cam.fy);
  const float cx = static_cast<float>(cam.cx), cy = static_cast<float>(cam.cy);
  const float* depth = L->depth.data();
  RgbdPyramid::Surfel* surfels = L->surfels.data();
  for (int y = 0; y < h; ++y) {
    const float* dm = depth + static_cast<size_t>(y) * w;
    const float ry = (y - cy) * ify;
    std::fill(nx, nx + 4 * w, 0.0f);
    if (y > 0 && y < h - 1) {
      normal_row(dm - w, dm, dm + w, w, (y - 1 - cy) * ify, ry, (y + 1 - cy) * ify, cx, ifx,
                 k_noise, nx, ny, nz, norms);
    }
    RgbdPyramid::Surfel* s = surfels + static_cast<size_t>(y) * w;
    for (int x = 0; x < w; ++x) {
      const float z = dm[x];
      s[x].p = Eigen::Vector3f((x - cx) * ifx * z, ry * z, z);
      const float inv_norm = norms[x] > 0.0f ? 1.0f / std::sqrt(norms[x]) : 0.0f;
      s[x].n = Eigen::Vector3f(nx[x], ny[x], nz[x]) * inv_norm;
    }
  }
}

DQO_AVX2_CLONE
void gather_samples(const DenseParams& params, bool colour, Level* L) {
  const size_t n_pixels = L->surfels.size();
  const RgbdPyramid::Surfel* s = L->surfels.data();
  size_t n = 0;
  for (size_t i = 0; i < n_pixels; ++i) n += s[i].n.squaredNorm() > 0.0f;
  RgbdPyramid::Samples& S = L->samples;
  for (std::vector<float>* a : {&S.x, &S.y, &S.z, &S.nx, &S.ny, &S.nz, &S.intensity,
                                &S.inv_sigma2, &S.textured}) {
    a->resize(n);
  }
  const float floor2 = static_cast<float>(params.min_depth_sigma_m * params.min_depth_sigma_m);
  const float k = static_cast<float>(params.depth_sigma_per_m2);
  const float min_g2 = static_cast<float>(params.min_gradient * params.min_gradient);
  double depth_sum = 0.0;
  size_t j = 0;
  for (size_t i = 0; i < n_pixels; ++i) {
    if (!(s[i].n.squaredNorm() > 0.0f)) continue;
    const float z = s[i].p.z();
    S.x[j] = s[i].p.x();
    S.y[j] = s[i].p.y();
    S.z[j] = z;
    S.nx[j] = s[i].n.x();
    S.ny[j] = s[i].n.y();
    S.nz[j] = s[i].n.z();
    if (colour) {
      const RgbdPyramid::Texel& t = L->texels[i];
      S.intensity[j] = t.intensity;
      S.textured[j] = t.gx * t.gx + t.gy * t.gy >= min_g2 ? 1.0f : 0.0f;
    } else {
      S.intensity[j] = 0.0f;
      S.textured[j] = 0.0f;
    }
    depth_sum += z;
    ++j;
  }
  for (size_t i = 0; i < n; ++i) {  // apart, so that it vectorises
    const float sz = k * S.z[i] * S.z[i];
    S.inv_sigma2[i] = 1.0f / (floor2 + sz * sz);
  }
  L->mean_depth = n > 0 ? depth_sum / n : 0.0;
}

void clear_samples(RgbdPyramid::Samples* S) {
  for (std::vector<float>* a : {&S->x, &S->y, &S->z, &S->nx, &S->ny, &S->nz, &S->intensity,
                                &S->inv_sigma2, &S->textured}) {
    a->clear();
  }
}

}  // namespace

RgbdPyramid::RgbdPyramid(const PinholeCamera& camera, const ImageRgb8& rgb,
                         const DepthImage& depth, const DenseParams& params) {
  rebuild(camera, rgb, depth, params);
}

void RgbdPyramid::rebuild(const PinholeCamera& camera, const ImageRgb8& rgb,
                          const DepthImage& depth, const DenseParams& params) {
  const int num_levels = std::clamp(params.pyramid_levels, 1, kMaxLevels);
  finest_level_ = std::clamp(params.finest_level, 0, num_levels - 1);
  levels_.resize(num_levels);
  levels_[0].camera = camera;
  for (int l = 1; l < num_levels; ++l) levels_[l].camera = half_camera(levels_[l - 1].camera);

  const int w = camera.width;
  const int h = camera.height;
  const bool depth_ok = w > 1 && h > 1 && depth.same_size(w, h) && depth.channels == 1 &&
                        depth.data.size() == static_cast<size_t>(w) * h;
  has_colour_ = depth_ok && rgb.same_size(w, h) && rgb.channels == 3 &&
                rgb.data.size() == static_cast<size_t>(w) * h * 3;
  // Buffers keep their capacity (a rebuilt pyramid allocates nothing, and resize() to the same size
  // writes nothing); every element of a filled buffer is overwritten below, the others emptied.
  for (int l = 0; l < num_levels; ++l) {
    Level& L = levels_[l];
    clear_samples(&L.samples);
    L.mean_depth = 0.0;
    if (!depth_ok || l < finest_level_) L.surfels.clear();
    if (!depth_ok || (l == 0 && finest_level_ > 0)) L.depth.clear();
    if (!has_colour_ || (l == 0 && finest_level_ > 0)) L.texels.clear();
  }
  if (!depth_ok) return;  // no valid points anywhere: align_dense fails cleanly

  const float max_depth = static_cast<float>(params.max_depth);
  const float k_noise = static_cast<float>(params.depth_sigma_per_m2);
  if (finest_level_ == 0) {
    Level& L = levels_[0];
    L.depth.resize(static_cast<size_t>(w) * h);
    if (has_colour_) L.texels.resize(L.depth.size());
    for (size_t i = 0; i < L.depth.size(); ++i) {
      L.depth[i] = sanitise_depth(depth.data[i], max_depth);
      if (has_colour_) {
        const uint8_t* c = rgb.data.data() + 3 * i;
        L.texels[i].intensity = (0.299f * c[0] + 0.587f * c[1] + 0.114f * c[2]) / 255.0f;
      }
    }
  }
  for (int l = 1; l < num_levels; ++l) {
    const float inv_f_fine = static_cast<float>(1.0 / levels_[l - 1].camera.fx);
    if (l == 1 && finest_level_ > 0) {
      halve_input(depth, has_colour_ ? &rgb : nullptr, max_depth, inv_f_fine, k_noise,
                  &levels_[1]);
    } else {
      halve_level(levels_[l - 1], has_colour_, inv_f_fine, k_noise, &levels_[l]);
    }
  }
  for (int l = finest_level_; l < num_levels; ++l) {
    Level& L = levels_[l];
    if (L.camera.width < 3 || L.camera.height < 3) {
      L.surfels.clear();
      continue;
    }
    if (has_colour_) compute_gradients(&L);
    compute_surfels(&L, k_noise, &scratch_);
    gather_samples(params, has_colour_, &L);
  }
}

}  // namespace dqo::tracking
