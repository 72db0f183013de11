#pragma once
// Counter-based random numbers: a value is a pure function of (seed, frame, pixel, stream), so
// noise does not depend on which thread renders which pixel, nor in which order.

#include <cmath>
#include <cstdint>

namespace dqo::sim {

// SplitMix64's finaliser: a bijective 64-bit mix with good avalanche.
inline uint64_t mix64(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

inline uint64_t hash_combine(uint64_t a, uint64_t b) { return mix64(a ^ mix64(b)); }

// Uniform in (0, 1): never 0, so log() below is finite.
inline double uniform_from_key(uint64_t key) {
  return (static_cast<double>(mix64(key) >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}

// Two independent standard normals from one key (Box–Muller).
inline void gaussian_pair_from_key(uint64_t key, double* g0, double* g1) {
  const double u1 = uniform_from_key(key);
  const double u2 = uniform_from_key(key ^ 0x5851f42d4c957f2dULL);
  const double r = std::sqrt(-2.0 * std::log(u1));
  const double a = 6.283185307179586 * u2;
  *g0 = r * std::cos(a);
  *g1 = r * std::sin(a);
}

}  // namespace dqo::sim
