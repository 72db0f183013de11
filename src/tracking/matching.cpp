#include "matching.h"

#include <algorithm>
#include <cmath>
#include <limits>

#if defined(__x86_64__)
#include <immintrin.h>
#endif


namespace dqo::tracking {
namespace {

constexpr int kHistogramBins = 30;

}  // namespace

std::vector<Match> search_by_projection(const OrbFrame& frame, const PinholeCamera& camera,
                                        const ScalePyramid& scales, const SE3& T_wc,
                                        const std::vector<ProjectionCandidate>& candidates,
                                        const ProjectionSearch& search,
                                        const std::vector<char>* taken,
                                        std::vector<char>* in_frustum) {
  const SE3 T_cw = T_wc.inverse();
  const Eigen::Matrix3d R_cw = T_cw.rotation();
  const Eigen::Vector3d t_cw = T_cw.translation();
  const Eigen::Vector3d centre_w = T_wc.translation();
  const int top_level = scales.levels() - 1;

  // Per keypoint: the best candidate so far and its distance.
  std::vector<int> best_candidate(frame.size(), -1);
  std::vector<int> best_distance(frame.size(), std::numeric_limits<int>::max());
  if (in_frustum != nullptr) in_frustum->assign(candidates.size(), 0);

  std::vector<int> window;
  for (size_t c = 0; c < candidates.size(); ++c) {
    const ProjectionCandidate& cand = candidates[c];
    const Eigen::Vector3d p_c = R_cw * cand.p_w + t_cw;
    if (p_c.z() <= 1e-3) continue;
    const double inv_z = 1.0 / p_c.z();
    const Eigen::Vector2f uv(static_cast<float>(camera.fx * p_c.x() * inv_z + camera.cx),
                             static_cast<float>(camera.fy * p_c.y() * inv_z + camera.cy));
    if (uv.x() < 0.0f || uv.y() < 0.0f || uv.x() > camera.width - 1 ||
        uv.y() > camera.height - 1)
      continue;

    int level = cand.level;
    if (search.check_viewing) {
      const Eigen::Vector3d ray = cand.p_w - centre_w;
      const double distance = ray.norm();
      if (cand.max_distance > 0.0f &&
          (distance < 0.8 * cand.min_distance || distance > 1.2 * cand.max_distance))
        continue;
      if (ray.dot(cand.normal) < 0.5 * distance) continue;  // viewed at more than 60°
      level = cand.max_distance > 0.0f
                  ? scales.predict_level(static_cast<float>(distance), cand.max_distance)
                  : cand.level;
    }
    if (in_frustum != nullptr) (*in_frustum)[c] = 1;

    const float radius = static_cast<float>(search.radius_px) * scales.scale[level];
    const int min_level = std::max(0, level - search.levels_below);
    const int max_level = std::min(top_level, level + search.levels_above);
    frame.grid.query(frame.keypoints, uv, radius, min_level, max_level, &window);

    int best = std::numeric_limits<int>::max(), second = std::numeric_limits<int>::max();
    int best_index = -1, best_level = -1, second_level = -1;
    for (const int k : window) {
      if (taken != nullptr && (*taken)[k]) continue;
      const int d = hamming(cand.descriptor, frame.descriptors[k]);
      if (d < best) {
        second = best;
        second_level = best_level;
        best = d;
        best_index = k;
        best_level = frame.keypoints[k].octave;
      } else if (d < second) {
        second = d;
        second_level = frame.keypoints[k].octave;
      }
    }
    if (best_index < 0 || best > search.max_distance) continue;
    // Similar descriptors on different levels may well be the same point seen at two scales.
    if (search.ratio < 1.0f && best_level == second_level &&
        static_cast<float>(best) > search.ratio * static_cast<float>(second))
      continue;
    if (best < best_distance[best_index]) {
      best_distance[best_index] = best;
      best_candidate[best_index] = static_cast<int>(c);
    }
  }

  std::vector<Match> matches;
  for (size_t k = 0; k < frame.size(); ++k)
    if (best_candidate[k] >= 0)
      matches.push_back({static_cast<int>(k), best_candidate[k], best_distance[k]});
  if (search.check_orientation) {
    keep_consistent_orientation(
        frame, [&](const Match& m) { return candidates[m.candidate].angle; }, &matches);
  }
  return matches;
}

void orientation_filter(const std::vector<float>& rotation_deg, std::vector<char>* keep) {
  keep->assign(rotation_deg.size(), 1);
  std::vector<int> bin_of(rotation_deg.size(), -1);
  int count[kHistogramBins] = {0};
  for (size_t i = 0; i < rotation_deg.size(); ++i) {
    if (rotation_deg[i] < 0.0f) continue;
    int bin = static_cast<int>(std::lround(rotation_deg[i] * kHistogramBins / 360.0f));
    bin %= kHistogramBins;
    bin_of[i] = bin;
    ++count[bin];
  }
  // The three fullest bins.
  int top[3] = {-1, -1, -1};
  for (int b = 0; b < kHistogramBins; ++b) {
    if (top[0] < 0 || count[b] > count[top[0]]) {
      top[2] = top[1];
      top[1] = top[0];
      top[0] = b;
    } else if (top[1] < 0 || count[b] > count[top[1]]) {
      top[2] = top[1];
      top[1] = b;
    } else if (top[2] < 0 || count[b] > count[top[2]]) {
      top[2] = b;
    }
  }
  if (top[0] < 0) return;
  const int first = count[top[0]];
  bool allowed[kHistogramBins] = {false};
  allowed[top[0]] = true;
  for (int j = 1; j < 3; ++j)
    if (top[j] >= 0 && count[top[j]] > 0.1 * first) allowed[top[j]] = true;
  for (size_t i = 0; i < rotation_deg.size(); ++i)
    if (bin_of[i] >= 0 && !allowed[bin_of[i]]) (*keep)[i] = 0;
}

namespace {

// The two nearest train descriptors of one query, as cv::BFMatcher's knnMatch(k = 2) with
// NORM_HAMMING gives them (the earlier train index wins a tie).
struct Nearest {
  int query = 0, first = -1, second = -1, d_first = 0, d_second = 0;
};

// The brute-force loop, written once and compiled twice below. Hamming distance by popcount on the
// 256-bit descriptors: OpenCV's matcher spent most of its time outside the distances (a call and a
// trace region per pair), and x86-64's baseline has no popcount instruction, so the builtin becomes
// a library call unless the function is compiled for one.
inline __attribute__((always_inline)) void nearest_two_body(const std::vector<Descriptor>& query,
                                                            const std::vector<Descriptor>& train,
                                                            std::vector<Nearest>* knn) {
  for (size_t qi = 0; qi < query.size(); ++qi) {
    Nearest& n = (*knn)[qi];
    n.query = static_cast<int>(qi);
    n.d_first = n.d_second = std::numeric_limits<int>::max();
    const Descriptor& q = query[qi];
    for (size_t ti = 0; ti < train.size(); ++ti) {
      const Descriptor& t = train[ti];
      const int d = hamming(q, t);  // inlined: compiled for the caller's target
      if (d < n.d_first) {
        n.second = n.first, n.d_second = n.d_first;
        n.first = static_cast<int>(ti), n.d_first = d;
      } else if (d < n.d_second) {
        n.second = static_cast<int>(ti), n.d_second = d;
      }
    }
  }
}

void nearest_two(const std::vector<Descriptor>& query, const std::vector<Descriptor>& train,
                 std::vector<Nearest>* knn) {
  nearest_two_body(query, train, knn);
}

#if (defined(__x86_64__) || defined(__i386__)) && !defined(__POPCNT__) && defined(__GNUC__)
#define DQO_POPCNT_DISPATCH 1
// The same loop with the popcnt instruction, for the CPUs that have it (every x86-64 of the last
// fifteen years; checked at run time).
__attribute__((target("popcnt"))) void nearest_two_popcnt(const std::vector<Descriptor>& query,
                                                          const std::vector<Descriptor>& train,
                                                          std::vector<Nearest>* knn) {
  nearest_two_body(query, train, knn);
}
#endif

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__linux__)
#define DQO_VPOPCNT_DISPATCH 1
// The same two nearest with AVX-512's vector popcount (Ice Lake and Zen 4 on): the train
// descriptors transposed into blocks of eight, word by word, so that one query's distances to
// eight of them take four xor-popcount-add steps; only blocks with a distance below the current
// second best go through the scalar update, in index order, so the result (ties included) is the
// loop's above. 4x faster on the dev machine; PnP against a keyframe runs it on every frame that
// the motion model cannot track.
__attribute__((target("popcnt,avx512f,avx512vl,avx512vpopcntdq"))) void nearest_two_vpopcnt(
    const std::vector<Descriptor>& query, const std::vector<Descriptor>& train,
    std::vector<Nearest>* knn) {
  constexpr size_t kBlock = 8;
  const size_t blocks = (train.size() + kBlock - 1) / kBlock;
  // Block b holds word k of train descriptor b * 8 + l at [b * 32 + k * 8 + l]; the padding of
  // the last block is never read back.
  std::vector<uint64_t> words(blocks * 4 * kBlock, 0);
  for (size_t t = 0; t < train.size(); ++t)
    for (size_t k = 0; k < 4; ++k)
      words[(t / kBlock) * 4 * kBlock + k * kBlock + t % kBlock] = train[t][k];
  alignas(64) int64_t d[kBlock];
  for (size_t qi = 0; qi < query.size(); ++qi) {
    Nearest& n = (*knn)[qi];
    n.query = static_cast<int>(qi);
    n.d_first = n.d_second = std::numeric_limits<int>::max();
    const Descriptor& q = query[qi];
    const __m512i q0 = _mm512_set1_epi64(static_cast<long long>(q[0]));
    const __m512i q1 = _mm512_set1_epi64(static_cast<long long>(q[1]));
    const __m512i q2 = _mm512_set1_epi64(static_cast<long long>(q[2]));
    const __m512i q3 = _mm512_set1_epi64(static_cast<long long>(q[3]));
    for (size_t b = 0; b < blocks; ++b) {
      const uint64_t* w = words.data() + b * 4 * kBlock;
      __m512i s = _mm512_popcnt_epi64(_mm512_xor_si512(q0, _mm512_loadu_si512(w)));
      s = _mm512_add_epi64(s, _mm512_popcnt_epi64(_mm512_xor_si512(q1, _mm512_loadu_si512(w + 8))));
      s = _mm512_add_epi64(s,
                           _mm512_popcnt_epi64(_mm512_xor_si512(q2, _mm512_loadu_si512(w + 16))));
      s = _mm512_add_epi64(s,
                           _mm512_popcnt_epi64(_mm512_xor_si512(q3, _mm512_loadu_si512(w + 24))));
      // A distance not below the second best changes nothing (the update's tests are strict).
      if (_mm512_cmplt_epi64_mask(s, _mm512_set1_epi64(n.d_second)) == 0) continue;
      _mm512_store_si512(d, s);
      const size_t end = std::min(kBlock, train.size() - b * kBlock);
      for (size_t l = 0; l < end; ++l) {
        const int dist = static_cast<int>(d[l]);
        const int ti = static_cast<int>(b * kBlock + l);
        if (dist < n.d_first) {
          n.second = n.first, n.d_second = n.d_first;
          n.first = ti, n.d_first = dist;
        } else if (dist < n.d_second) {
          n.second = ti, n.d_second = dist;
        }
      }
    }
  }
}
#endif

}  // namespace

std::vector<std::pair<int, int>> match_descriptors(const std::vector<Descriptor>& query,
                                                   const std::vector<Descriptor>& train,
                                                   float ratio, int max_distance) {
  std::vector<std::pair<int, int>> out;
  if (query.empty() || train.size() < 2) return out;
  std::vector<Nearest> knn(query.size());
  // The fastest loop this CPU has (checked once): all three give the same result.
#ifdef DQO_VPOPCNT_DISPATCH
  static const bool has_vpopcnt = __builtin_cpu_supports("avx512f") &&
                                  __builtin_cpu_supports("avx512vl") &&
                                  __builtin_cpu_supports("avx512vpopcntdq");
#else
  constexpr bool has_vpopcnt = false;
#endif
#ifdef DQO_POPCNT_DISPATCH
  static const bool has_popcnt = __builtin_cpu_supports("popcnt");
#else
  constexpr bool has_popcnt = false;
#endif
  if (has_vpopcnt) {
#ifdef DQO_VPOPCNT_DISPATCH
    nearest_two_vpopcnt(query, train, &knn);
#endif
  } else if (has_popcnt) {
#ifdef DQO_POPCNT_DISPATCH
    nearest_two_popcnt(query, train, &knn);
#endif
  } else {
    nearest_two(query, train, &knn);
  }
  std::vector<int> best_query(train.size(), -1);
  std::vector<float> best_distance(train.size(), std::numeric_limits<float>::max());
  for (const Nearest& m : knn) {
    const float d0 = static_cast<float>(m.d_first), d1 = static_cast<float>(m.d_second);
    if (m.first < 0 || d0 > max_distance) continue;
    if (m.second >= 0 && d0 > ratio * d1) continue;
    if (d0 < best_distance[m.first]) {
      best_distance[m.first] = d0;
      best_query[m.first] = m.query;
    }
  }
  for (size_t t_index = 0; t_index < train.size(); ++t_index)
    if (best_query[t_index] >= 0) out.emplace_back(best_query[t_index], static_cast<int>(t_index));
  return out;
}

}  // namespace dqo::tracking
