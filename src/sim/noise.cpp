#include "dqo_map/sim/noise.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <thread>
#include <vector>

#include "dqo_map/sim/random.h"

namespace dqo::sim {
namespace {

// Streams of the per-pixel key, so that the depth, hole and colour draws are independent.
constexpr uint64_t kDepthStream = 0x1d8e4e27c47d124fULL;
constexpr uint64_t kHoleStream = 0x2b7e151628aed2a6ULL;
constexpr uint64_t kColourStream = 0x3c6ef372fe94f82bULL;

// Gaussian from one key by Box–Muller in float (the depth noise needs real tails).
inline float gaussian(uint64_t key) {
  const uint64_t h = mix64(key);
  const float u1 = (static_cast<float>(h >> 40) + 0.5f) * (1.0f / 16777216.0f);
  const float u2 = static_cast<float>((h >> 8) & 0xffffffu) * (1.0f / 16777216.0f);
  return std::sqrt(-2.0f * std::log(u1)) * std::cos(6.2831853f * u2);
}

// Near-gaussian from one key: the sum of four 16-bit uniforms (Irwin–Hall), unit variance, tails
// cut at 3.5 sigma. Plenty for 8-bit colour noise, and no log or cosine per channel.
inline float gaussian_ih(uint64_t key) {
  const uint64_t h = mix64(key);
  const float sum =
      static_cast<float>((h & 0xffff) + ((h >> 16) & 0xffff) + ((h >> 32) & 0xffff) + (h >> 48)) *
      (1.0f / 65536.0f);
  return (sum - 2.0f) * 1.7320508f;
}

void noise_rows(const SensorNoiseParams& params, uint64_t frame_key, const DepthImage& clean,
                int row_begin, int row_end, Frame* frame) {
  const int w = clean.width, h = clean.height;
  constexpr float kNone = std::numeric_limits<float>::infinity();
  // Nearest return among the three rows around y, per column (0 = no return, ignored); the 3x3
  // minimum is then the minimum of three neighbouring columns.
  std::vector<float> column_min(static_cast<size_t>(w));
  const float rgb_sigma = static_cast<float>(params.rgb_sigma);
  for (int y = row_begin; y < row_end; ++y) {
    for (int x = 0; x < w; ++x) {
      float m = kNone;
      for (int yy = std::max(0, y - 1); yy <= std::min(h - 1, y + 1); ++yy) {
        const float z = clean.at(x, yy);
        if (z > 0.0f && z < m) m = z;
      }
      column_min[x] = m;
    }
    for (int x = 0; x < w; ++x) {
      const uint64_t key = hash_combine(frame_key, static_cast<uint64_t>(y) * w + x);
      const float z = clean.at(x, y);
      if (z > 0.0f) {
        bool hole = z > params.max_depth;
        if (!hole && params.edge_hole_probability > 0.0) {
          float nearest = column_min[x];
          if (x > 0) nearest = std::min(nearest, column_min[x - 1]);
          if (x + 1 < w) nearest = std::min(nearest, column_min[x + 1]);
          const double jump = std::max(params.edge_jump, params.edge_jump_relative * z);
          hole = z - nearest > jump &&
                 uniform_from_key(key ^ kHoleStream) < params.edge_hole_probability;
        }
        if (hole) {
          frame->depth.at(x, y) = 0.0f;
        } else {
          const double zd = z;
          const double noisy = zd + params.depth_sigma * zd * zd * gaussian(key ^ kDepthStream);
          frame->depth.at(x, y) = static_cast<float>(std::max(0.0, noisy));
        }
      }
      if (rgb_sigma > 0.0f && !frame->rgb.empty()) {
        for (int c = 0; c < 3; ++c) {
          uint8_t& v = frame->rgb.at(x, y, c);
          const float noisy = v + rgb_sigma * gaussian_ih(key ^ (kColourStream + c));
          v = static_cast<uint8_t>(std::clamp(noisy, 0.0f, 255.0f) + 0.5f);
        }
      }
    }
  }
}

}  // namespace

void apply_sensor_noise(const SensorNoiseParams& params, uint64_t seed, int threads, Frame* frame) {
  if (frame->depth.empty()) return;
  // Holes are decided on the clean depth: a hole must not make its neighbour an edge.
  const DepthImage clean = frame->depth;
  const uint64_t frame_key = hash_combine(seed, static_cast<uint64_t>(frame->index));
  const int h = clean.height;
  threads = std::max(1, std::min(threads, h));
  if (threads == 1) {
    noise_rows(params, frame_key, clean, 0, h, frame);
    return;
  }
  std::vector<std::thread> workers;
  for (int i = 0; i < threads; ++i) {
    workers.emplace_back(noise_rows, std::cref(params), frame_key, std::cref(clean),
                         h * i / threads, h * (i + 1) / threads, frame);
  }
  for (auto& t : workers) t.join();
}

}  // namespace dqo::sim
