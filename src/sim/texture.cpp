#include "dqo_map/sim/texture.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace dqo::sim {
namespace {

// Value noise on a permutation table (Perlin's scheme): a few L1 loads per lattice point instead
// of a hash, which matters because the walls evaluate several octaves at every pixel. The lattice
// repeats every 256 cells; each seed and octave shifts it, so the repeats do not line up.
struct NoiseTable {
  uint8_t perm[512];
  float value[256];
};

const NoiseTable& noise_table() {
  static const NoiseTable table = [] {
    NoiseTable t;
    uint64_t state = 0x243f6a8885a308d3ULL;
    auto next = [&state] {
      state += 0x9e3779b97f4a7c15ULL;
      uint64_t z = state;
      z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
      z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
      return z ^ (z >> 31);
    };
    for (int i = 0; i < 256; ++i) t.perm[i] = static_cast<uint8_t>(i);
    for (int i = 255; i > 0; --i) std::swap(t.perm[i], t.perm[next() % (i + 1)]);
    for (int i = 0; i < 256; ++i) t.perm[256 + i] = t.perm[i];
    for (int i = 0; i < 256; ++i)
      t.value[i] = static_cast<float>(next() >> 40) * (1.0f / 16777216.0f);
    return t;
  }();
  return table;
}

// floor() without SSE4.1 (the portable x86-64 baseline) is a slow library sequence; these are a
// compare and a conversion. Valid well beyond the coordinate range of a scene.
inline int floor_int(float x) {
  const int i = static_cast<int>(x);
  return i - (x < static_cast<float>(i));
}
inline double floor_d(double x) {
  const double i = static_cast<double>(static_cast<int64_t>(x));
  return i - (x < i);
}

inline float smooth(float f) { return f * f * (3.0f - 2.0f * f); }
inline float lerp(float a, float b, float t) { return a + (b - a) * t; }

// One octave: trilinear interpolation of lattice values with a smoothstep fade.
float noise3(const Eigen::Vector3d& p, uint32_t seed) {
  const NoiseTable& t = noise_table();
  // Float from here: lattice coordinates stay below ~1e4, where float keeps 1e-3 of a cell.
  const float px = static_cast<float>(p.x()), py = static_cast<float>(p.y()),
              pz = static_cast<float>(p.z());
  const int jx = floor_int(px), jy = floor_int(py), jz = floor_int(pz);
  const float fx = static_cast<float>(jx), fy = static_cast<float>(jy), fz = static_cast<float>(jz);
  // The seed shifts the lattice by whole cells.
  const int ix = jx + static_cast<int>(seed & 255u);
  const int iy = jy + static_cast<int>((seed >> 8) & 255u);
  const int iz = jz + static_cast<int>((seed >> 16) & 255u);
  const int x0 = ix & 255, x1 = (ix + 1) & 255;
  const int y0 = iy & 255, y1 = (iy + 1) & 255;
  const int z0 = iz & 255, z1 = (iz + 1) & 255;
  const int a = t.perm[x0], b = t.perm[x1];
  const int aa = t.perm[a + y0], ab = t.perm[a + y1], ba = t.perm[b + y0], bb = t.perm[b + y1];
  const float tx = smooth(px - fx);
  const float ty = smooth(py - fy);
  const float tz = smooth(pz - fz);
  const float c00 = lerp(t.value[t.perm[aa + z0]], t.value[t.perm[ba + z0]], tx);
  const float c10 = lerp(t.value[t.perm[ab + z0]], t.value[t.perm[bb + z0]], tx);
  const float c01 = lerp(t.value[t.perm[aa + z1]], t.value[t.perm[ba + z1]], tx);
  const float c11 = lerp(t.value[t.perm[ab + z1]], t.value[t.perm[bb + z1]], tx);
  return lerp(lerp(c00, c10, ty), lerp(c01, c11, ty), tz);
}

// Seed of octave i: a different shift of the lattice per octave and per texture seed.
inline uint32_t octave_seed(uint32_t seed, int i) {
  uint32_t h = seed * 0x9e3779b1u + static_cast<uint32_t>(i) * 0x85ebca6bu;
  h ^= h >> 15;
  h *= 0x2c1b3c6du;
  h ^= h >> 12;
  return h;
}

// Octaves whose feature is smaller than the footprint fade to the mean (0.5).
float fbm(const Eigen::Vector3d& p, int octaves, uint32_t seed, double footprint) {
  float sum = 0.0f, weight = 0.0f, amp = 1.0f;
  double freq = 1.0;
  for (int i = 0; i < octaves; ++i) {
    const double feature = 1.0 / freq;
    const float keep = static_cast<float>(std::clamp(1.5 - footprint / feature, 0.0, 1.0));
    const float value = keep > 0.0f ? noise3(p * freq, octave_seed(seed, i)) : 0.5f;
    sum += amp * (0.5f + keep * (value - 0.5f));
    weight += amp;
    amp *= 0.5f;
    freq *= 2.0;
  }
  return weight > 0.0f ? sum / weight : 0.5f;
}

Eigen::Vector3f mix(const Eigen::Vector3f& a, const Eigen::Vector3f& b, float t) {
  return a + (b - a) * t;
}

// Box-filtered 2D checker of period 2 in cell units (after Inigo Quilez): 0 or 1 when sharp,
// 0.5 when the filter spans many cells.
float filtered_checker(double x, double y, double w) {
  if (w < 1e-3) {
    return static_cast<float>(
        (static_cast<int64_t>(floor_d(x)) + static_cast<int64_t>(floor_d(y))) & 1);
  }
  auto tri = [](double v) { return std::abs(v - floor_d(v) - 0.5); };
  const double ix = 2.0 * (tri((x - 0.5 * w) * 0.5) - tri((x + 0.5 * w) * 0.5)) / w;
  const double iy = 2.0 * (tri((y - 0.5 * w) * 0.5) - tri((y + 0.5 * w) * 0.5)) / w;
  return static_cast<float>(0.5 - 0.5 * ix * iy);
}

float smoothstep(double e0, double e1, double x) {
  const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return static_cast<float>(t * t * (3.0 - 2.0 * t));
}

}  // namespace

float value_noise(const Eigen::Vector3d& p, int octaves, uint32_t seed) {
  return fbm(p, octaves, seed, 0.0);
}

Eigen::Vector3f evaluate_texture(const Texture& tex, const Eigen::Vector3d& p,
                                 const Eigen::Vector3d& n, double footprint) {
  switch (tex.type) {
    case TextureType::kUniform:
      return tex.colour_a;
    case TextureType::kChecker: {
      // The two axes across the surface: a 3D checker would flicker on a face that lies exactly
      // on a cell boundary (a floor at z = 0).
      int drop = 0;
      if (std::abs(n.y()) > std::abs(n[drop])) drop = 1;
      if (std::abs(n.z()) > std::abs(n[drop])) drop = 2;
      const int a = drop == 0 ? 1 : 0;
      const int b = drop == 2 ? 1 : 2;
      const double inv = 1.0 / tex.scale;
      return mix(tex.colour_a, tex.colour_b,
                 filtered_checker(p[a] * inv, p[b] * inv, footprint * inv));
    }
    case TextureType::kNoise: {
      float v = fbm(p / tex.scale, tex.octaves, tex.seed, footprint / tex.scale);
      v = std::clamp(0.5f + static_cast<float>(tex.contrast) * (v - 0.5f), 0.0f, 1.0f);
      return mix(tex.colour_a, tex.colour_b, v);
    }
    case TextureType::kStripes: {
      const double phase = p.dot(tex.axis) / tex.scale;
      const double x = phase - floor_d(phase);  // band a on [0, 0.5)
      const double dist = x < 0.5 ? std::min(x, 0.5 - x) : -std::min(x - 0.5, 1.0 - x);
      const double w = 0.5 * std::max(tex.softness, footprint / tex.scale) + 1e-9;
      return mix(tex.colour_b, tex.colour_a, smoothstep(-w, w, dist));
    }
    case TextureType::kWood: {
      // Rings around the grain axis, wobbled by stretched noise along the grain, plus fine grain.
      const double along = p.dot(tex.axis);
      const Eigen::Vector3d across = p - along * tex.axis;
      const double inv = 1.0 / tex.scale;
      const Eigen::Vector3d q = across * (2.0 * inv) + tex.axis * (along * 0.25 * inv);
      const float wobble = fbm(q, tex.octaves, tex.seed, footprint * 2.0 * inv);
      const double r = across.norm() * inv + 1.5 * wobble;
      const double ring = r - floor_d(r);
      // Late wood (dark) is a thin band in each ring; it fades to its mean when rings get smaller
      // than a pixel.
      const float band = smoothstep(0.55, 0.85, ring) * (1.0f - smoothstep(0.85, 1.0, ring) * 0.6f);
      const float sharp = static_cast<float>(std::clamp(1.5 - footprint * inv, 0.0, 1.0));
      const float t = 0.35f + sharp * (band - 0.35f);
      const float grain = fbm(q * 6.0, 1, tex.seed + 17u, footprint * 12.0 * inv);
      return mix(tex.colour_a, tex.colour_b, std::clamp(t + 0.25f * (grain - 0.5f), 0.0f, 1.0f));
    }
  }
  return tex.colour_a;
}

bool texture_type_from_string(const std::string& name, TextureType* type) {
  if (name == "uniform") {
    *type = TextureType::kUniform;
  } else if (name == "checker") {
    *type = TextureType::kChecker;
  } else if (name == "noise") {
    *type = TextureType::kNoise;
  } else if (name == "stripes") {
    *type = TextureType::kStripes;
  } else if (name == "wood") {
    *type = TextureType::kWood;
  } else {
    return false;
  }
  return true;
}

}  // namespace dqo::sim
