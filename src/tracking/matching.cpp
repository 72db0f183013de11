#include "matching.h"

#include <algorithm>
#include <cmath>
#include <limits>


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

}  // namespace

std::vector<std::pair<int, int>> match_descriptors(const std::vector<Descriptor>& query,
                                                   const std::vector<Descriptor>& train,
                                                   float ratio, int max_distance) {
  std::vector<std::pair<int, int>> out;
  if (query.empty() || train.size() < 2) return out;
  std::vector<Nearest> knn(query.size());
#ifdef DQO_POPCNT_DISPATCH
  static const bool has_popcnt = __builtin_cpu_supports("popcnt");
  if (has_popcnt)
    nearest_two_popcnt(query, train, &knn);
  else
#endif
    nearest_two(query, train, &knn);
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
