#pragma once
// Small POD vector and matrix types for the per-Gaussian maths shared by the CPU reference
// rasteriser and the CUDA kernels (DESIGN.md, "Maths shared by CPU and GPU code"). Templated on the
// scalar: float for speed, double for the finite-difference tests. Deliberately not Eigen (fragile
// in device code) and not CUDA's float3 (absent without nvcc, and float only).
//
// Conventions of every header in math/:
// - matrices are row-major, m[row][col];
// - a symmetric 2x2 matrix is a Sym2 {xx, xy, yy}; its gradient is taken with respect to those
//   three numbers, so the gradient of xy counts both off-diagonal entries;
// - 3x3 covariances are full Mat3 and their gradients are full-matrix gradients (dL/dM_ij for every
//   entry, as if the entries were independent), which is exact for any matrix, symmetric or not;
// - `_vjp` functions take the forward inputs, the output gradient (v_*) and ADD into the
// accumulated
//   gradients of their inputs (pointers), so a caller can chain them without zeroing in between.
//
// No std:: containers, no exceptions, no Eigen here: nvcc compiles these headers unchanged.

#include <math.h>
#include <string.h>

#include "dqo_map/common/host_device.h"

namespace dqo::gs {

template <typename T>
struct Vec2 {
  T x, y;
};

template <typename T>
struct Vec3 {
  T x, y, z;
};

// Quaternion (w, x, y, z); not necessarily of unit norm where it is a trainable parameter.
template <typename T>
struct Quat {
  T w, x, y, z;
};

template <typename T>
struct Sym2 {
  T xx, xy, yy;
};

template <typename T>
struct Mat3 {
  T m[3][3];
};

// ---------------------------------------------------------------- scalar functions
// Overloads pick the float or double C function, which exist on host and device alike.
// exp in float is our own, evaluated by the same operations on host and device: CUDA's expf and
// the C library's differ in the last bit, and that moves pixels across the α ≥ 1/255 and
// transmittance cut-offs between the CPU reference and the kernels (a Gaussian in on one side, out
// on the other: differences of 4e-4 where the tests allow 1e-4). Cody–Waite reduction
// x = k ln2 + r, |r| ≤ ln2/2, a degree-7 polynomial for e^r (error about 1 ulp), times 2^k made
// from the exponent bits. Bit-identical on both sides as long as neither contracts a·b + c into an
// FMA (the CUDA ring compiles its kernels with -fmad=false; x86-64 g++ without -march has no FMA).
DQO_HD float hd_exp(float x) {
  if (!(x >= -87.0f)) return 0.0f;  // below the normal range (and NaN): the callers need "tiny"
  if (x > 88.0f) x = 88.0f;         // keeps 2^k finite; no caller comes near
  const float k = floorf(x * 1.44269504f + 0.5f);
  const float r = (x - k * 0.693145752f) - k * 1.42860677e-06f;
  float p = 1.98412698e-4f;  // 1/7!
  p = p * r + 1.38888889e-3f;
  p = p * r + 8.33333333e-3f;
  p = p * r + 4.16666667e-2f;
  p = p * r + 1.66666667e-1f;
  p = p * r + 0.5f;
  p = p * r + 1.0f;
  p = p * r + 1.0f;
  const unsigned int bits = static_cast<unsigned int>(static_cast<int>(k) + 127) << 23;
#ifdef __CUDA_ARCH__
  const float scale = __uint_as_float(bits);
#else
  float scale;
  memcpy(&scale, &bits, sizeof scale);
#endif
  return p * scale;
}
DQO_HD double hd_exp(double x) { return exp(x); }
DQO_HD float hd_log(float x) { return logf(x); }
DQO_HD double hd_log(double x) { return log(x); }
DQO_HD float hd_sqrt(float x) { return sqrtf(x); }
DQO_HD double hd_sqrt(double x) { return sqrt(x); }
DQO_HD float hd_ceil(float x) { return ceilf(x); }
DQO_HD double hd_ceil(double x) { return ceil(x); }
DQO_HD float hd_floor(float x) { return floorf(x); }
DQO_HD double hd_floor(double x) { return floor(x); }
template <typename T>
DQO_HD T hd_min(T a, T b) {
  return a < b ? a : b;
}
template <typename T>
DQO_HD T hd_max(T a, T b) {
  return a > b ? a : b;
}
template <typename T>
DQO_HD T hd_abs(T x) {
  return x < T(0) ? -x : x;
}
template <typename T>
DQO_HD T hd_clamp(T v, T lo, T hi) {
  return v < lo ? lo : (v > hi ? hi : v);
}

// ---------------------------------------------------------------- Vec3
template <typename T>
DQO_HD Vec3<T> operator+(const Vec3<T>& a, const Vec3<T>& b) {
  return {a.x + b.x, a.y + b.y, a.z + b.z};
}
template <typename T>
DQO_HD Vec3<T> operator-(const Vec3<T>& a, const Vec3<T>& b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
template <typename T>
DQO_HD Vec3<T> operator*(T s, const Vec3<T>& a) {
  return {s * a.x, s * a.y, s * a.z};
}
template <typename T>
DQO_HD void operator+=(Vec3<T>& a, const Vec3<T>& b) {
  a.x += b.x;
  a.y += b.y;
  a.z += b.z;
}
template <typename T>
DQO_HD T dot(const Vec3<T>& a, const Vec3<T>& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}

// ---------------------------------------------------------------- Mat3
template <typename T>
DQO_HD Mat3<T> mat3_zero() {
  Mat3<T> r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r.m[i][j] = T(0);
  return r;
}
template <typename T>
DQO_HD Mat3<T> operator*(const Mat3<T>& a, const Mat3<T>& b) {
  Mat3<T> r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      r.m[i][j] = a.m[i][0] * b.m[0][j] + a.m[i][1] * b.m[1][j] + a.m[i][2] * b.m[2][j];
  return r;
}
template <typename T>
DQO_HD Mat3<T> operator+(const Mat3<T>& a, const Mat3<T>& b) {
  Mat3<T> r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r.m[i][j] = a.m[i][j] + b.m[i][j];
  return r;
}
template <typename T>
DQO_HD void operator+=(Mat3<T>& a, const Mat3<T>& b) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) a.m[i][j] += b.m[i][j];
}
template <typename T>
DQO_HD Mat3<T> transpose(const Mat3<T>& a) {
  Mat3<T> r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r.m[i][j] = a.m[j][i];
  return r;
}
template <typename T>
DQO_HD Vec3<T> operator*(const Mat3<T>& a, const Vec3<T>& v) {
  return {a.m[0][0] * v.x + a.m[0][1] * v.y + a.m[0][2] * v.z,
          a.m[1][0] * v.x + a.m[1][1] * v.y + a.m[1][2] * v.z,
          a.m[2][0] * v.x + a.m[2][1] * v.y + a.m[2][2] * v.z};
}
// aᵀ v without forming the transpose.
template <typename T>
DQO_HD Vec3<T> mul_transposed(const Mat3<T>& a, const Vec3<T>& v) {
  return {a.m[0][0] * v.x + a.m[1][0] * v.y + a.m[2][0] * v.z,
          a.m[0][1] * v.x + a.m[1][1] * v.y + a.m[2][1] * v.z,
          a.m[0][2] * v.x + a.m[1][2] * v.y + a.m[2][2] * v.z};
}
// a bᵀ.
template <typename T>
DQO_HD Mat3<T> outer(const Vec3<T>& a, const Vec3<T>& b) {
  Mat3<T> r;
  const T av[3] = {a.x, a.y, a.z};
  const T bv[3] = {b.x, b.y, b.z};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r.m[i][j] = av[i] * bv[j];
  return r;
}

// Loads and stores from flat arrays (the map's layout).
template <typename T>
DQO_HD Vec3<T> load_vec3(const T* p) {
  return {p[0], p[1], p[2]};
}
template <typename T>
DQO_HD Quat<T> load_quat(const T* p) {
  return {p[0], p[1], p[2], p[3]};
}

}  // namespace dqo::gs
