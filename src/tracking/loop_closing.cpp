#include "loop_closing.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <unordered_set>

#include "matching.h"
#include "pose_graph.h"
#include "pose_optimiser.h"
#include "relocaliser.h"

namespace dqo::tracking {
namespace {

// Ranking only (PnP decides): strict enough that look-alikes count little.
constexpr float kRankRatio = 0.8f;
constexpr int kRankMaxDistance = kHammingLow;
// Pose-graph edges: 1 cm and 0.6° for an edge of 100 shared points (weight = shared / 100).
constexpr double kEdgeSigmaT = 0.01;
constexpr double kEdgeSigmaR = 0.01;

int count_matches(const std::vector<Descriptor>& query, const KeyFrame& candidate,
                  const MapStore& map) {
  std::vector<Descriptor> train;
  for (size_t i = 0; i < candidate.map_points.size(); ++i)
    if (map.map_point(candidate.map_points[i]) != nullptr)
      train.push_back(candidate.features.descriptors[i]);
  if (train.empty()) return 0;
  return static_cast<int>(match_descriptors(query, train, kRankRatio, kRankMaxDistance).size());
}

// The most matched first; ties by the older keyframe (deterministic).
void sort_ranked(std::vector<std::pair<int, uint64_t>>* ranked) {
  std::sort(ranked->begin(), ranked->end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second < b.second;
  });
}

}  // namespace

std::vector<uint64_t> loop_candidates(const MapStore& map, uint64_t query, const LoopParams& params) {
  std::vector<uint64_t> out;
  const KeyFrame* q = map.keyframe(query);
  if (q == nullptr) return out;
  std::unordered_set<uint64_t> connected{query};
  for (const auto& [id, n] : q->covisibility) {
    connected.insert(id);
    if (const KeyFrame* c = map.keyframe(id))
      for (const auto& [id2, n2] : c->covisibility) connected.insert(id2);
  }
  const uint64_t gap = static_cast<uint64_t>(std::max(1, params.min_keyframe_gap));
  for (const auto& [id, kf] : map.keyframes())
    if (id + gap <= query && connected.count(id) == 0) out.push_back(id);
  std::sort(out.begin(), out.end());
  return out;
}

LoopDetection detect_loop(const MapStore& map, uint64_t query, const PinholeCamera& camera,
                          const ScalePyramid& scales, const PoseOptimiserParams& pose_params,
                          const LoopParams& params) {
  LoopDetection d;
  d.query = query;
  const KeyFrame* q = map.keyframe(query);
  if (q == nullptr) return d;
  const std::vector<uint64_t> candidates = loop_candidates(map, query, params);
  d.candidates = static_cast<int>(candidates.size());
  const std::vector<Descriptor>& all = q->features.descriptors;
  // First step: a sample of the query's descriptors against every candidate.
  std::vector<uint64_t> shortlist = candidates;
  const size_t sample = static_cast<size_t>(std::max(0, params.sample_descriptors));
  const size_t keep = 4 * static_cast<size_t>(std::max(1, params.max_verify));
  if (sample > 0 && sample < all.size() && candidates.size() > keep) {
    std::vector<Descriptor> sampled;
    for (size_t i = 0; i < sample; ++i) sampled.push_back(all[i * all.size() / sample]);
    std::vector<std::pair<int, uint64_t>> coarse;
    for (const uint64_t id : candidates)
      coarse.emplace_back(count_matches(sampled, *map.keyframe(id), map), id);
    sort_ranked(&coarse);
    coarse.resize(keep);
    shortlist.clear();
    for (const auto& [n, id] : coarse) shortlist.push_back(id);
  }
  std::vector<std::pair<int, uint64_t>> ranked;  // (matches, keyframe)
  for (const uint64_t id : shortlist) {
    const int n = count_matches(all, *map.keyframe(id), map);
    if (n >= params.min_matches) ranked.emplace_back(n, id);
  }
  sort_ranked(&ranked);
  if (!ranked.empty()) d.best_matches = ranked.front().first;
  const size_t tries = std::min(ranked.size(), static_cast<size_t>(std::max(1, params.max_verify)));
  for (size_t i = 0; i < tries; ++i) {
    const PnpResult r = pnp_against_keyframe(q->features, *map.keyframe(ranked[i].second), map,
                                             camera, scales, pose_params, params.min_inliers);
    if (!r.ok) continue;
    d.found = true;
    d.match = ranked[i].second;
    d.T_wc_query = r.T_wc;
    d.matches = r.matches;
    return d;
  }
  return d;
}

LoopCorrection correct_loop(MapStore* map, const LoopDetection& loop, uint64_t gauge_keyframe,
                            const ScalePyramid& scales, const LoopParams& params) {
  const auto start = std::chrono::steady_clock::now();
  LoopCorrection out;
  if (!loop.found || map->keyframe(loop.query) == nullptr || map->keyframe(loop.match) == nullptr)
    return out;
  std::vector<uint64_t> ids;
  for (const auto& [id, kf] : map->keyframes()) ids.push_back(id);
  std::sort(ids.begin(), ids.end());
  std::unordered_map<uint64_t, int> index;
  std::vector<PoseGraphNode> nodes;
  for (const uint64_t id : ids) {
    index.emplace(id, static_cast<int>(nodes.size()));
    nodes.push_back({id, map->keyframe(id)->T_wc, id == gauge_keyframe || id == loop.match});
  }
  std::vector<PoseGraphEdge> edges;
  auto add_edge = [&](uint64_t a, uint64_t b, double weight) {
    const SE3& T_wa = map->keyframe(a)->T_wc;
    const SE3& T_wb = map->keyframe(b)->T_wc;
    edges.push_back({index.at(a), index.at(b), T_wa.inverse() * T_wb,
                     isotropic_information(kEdgeSigmaT, kEdgeSigmaR, weight)});
  };
  // Consecutive keyframes (the spanning chain) and covisibility, each pair once.
  for (size_t i = 0; i < ids.size(); ++i) {
    const KeyFrame* kf = map->keyframe(ids[i]);
    if (i > 0) {
      const auto it = kf->covisibility.find(ids[i - 1]);
      const int shared = it == kf->covisibility.end() ? 0 : it->second;
      add_edge(ids[i - 1], ids[i], std::max(1.0, shared / 100.0));
    }
    for (const auto& [other, shared] : kf->covisibility) {
      if (other >= ids[i] || (i > 0 && other == ids[i - 1]) || shared < params.min_edge_shared ||
          index.count(other) == 0)
        continue;
      add_edge(other, ids[i], shared / 100.0);
    }
  }
  // The loop: the query where the matched keyframe's points place it.
  const SE3 T_match_query = map->keyframe(loop.match)->T_wc.inverse() * loop.T_wc_query;
  edges.push_back({index.at(loop.match), index.at(loop.query), T_match_query,
                   isotropic_information(kEdgeSigmaT, kEdgeSigmaR,
                                         std::max(1.0, loop.matches.size() / 100.0))});
  // The pose graph starts from the query's neighbourhood already corrected (ORB-SLAM2): the
  // query and the keyframes covisible with it jump by the loop's correction.
  const KeyFrame* query = map->keyframe(loop.query);
  const SE3 correction = loop.T_wc_query * query->T_wc.inverse();
  std::vector<PoseGraphNode> start_nodes = nodes;
  for (PoseGraphNode& n : start_nodes)
    if (!n.fixed && (n.id == loop.query || query->covisibility.count(n.id) != 0))
      n.T_wc = correction * n.T_wc;
  const PoseGraphResult solved = optimise_pose_graph(start_nodes, edges, params.pose_graph_iterations);
  out.edges = static_cast<int>(edges.size());
  if (!solved.ok) return out;

  // Map points move with their first keyframe (or the first that still sees them).
  std::unordered_map<uint64_t, SE3> delta;  // T_new T_old⁻¹ per keyframe
  for (size_t i = 0; i < nodes.size(); ++i) {
    if (nodes[i].fixed) continue;
    delta.emplace(nodes[i].id, solved.T_wc[i] * nodes[i].T_wc.inverse());
    out.moved.emplace(nodes[i].id, solved.T_wc[i]);
  }
  std::vector<uint64_t> point_ids;
  for (const auto& [id, p] : map->map_points()) point_ids.push_back(id);
  for (const uint64_t id : point_ids) {
    MapPoint* p = map->map_point(id);
    uint64_t ref = p->first_keyframe;
    if (map->keyframe(ref) == nullptr && !p->observations.empty()) ref = p->observations.front().first;
    const auto it = delta.find(ref);
    if (it != delta.end()) p->p_w = it->second * p->p_w;
  }
  for (const auto& [id, T_wc] : out.moved) map->keyframe(id)->T_wc = T_wc;

  // Fuse: the query's keypoint and the older map point it matched are one point.
  std::unordered_set<uint64_t> touched{loop.query, loop.match};
  for (const auto& [k, older] : loop.matches) {
    if (map->map_point(older) == nullptr) continue;
    const KeyFrame* q = map->keyframe(loop.query);
    const uint64_t newer = q->map_points[k];
    if (newer == older) continue;
    if (map->map_point(newer) != nullptr) {
      const std::vector<std::pair<uint64_t, int>> observations = map->map_point(newer)->observations;
      for (const auto& [kf, keypoint] : observations) {
        if (map->map_point(older)->observation_of(kf) >= 0) continue;
        map->add_observation(older, kf, keypoint);
        touched.insert(kf);
      }
      map->erase_map_point(newer);
    } else {
      map->add_observation(older, loop.query, k);
    }
    map->update_point_appearance(older, scales);
    ++out.fused_points;
  }
  std::vector<uint64_t> update(touched.begin(), touched.end());
  std::sort(update.begin(), update.end());
  for (const uint64_t id : update) map->update_covisibility(id);
  out.ok = true;
  out.milliseconds =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return out;
}

LocalBaProblem global_ba_problem(const MapStore& map, uint64_t gauge_keyframe,
                                 const ScalePyramid& scales, const PoseOptimiserParams& pose_params,
                                 uint64_t generation) {
  LocalBaProblem problem;
  problem.generation = generation;
  std::vector<uint64_t> ids;
  for (const auto& [id, kf] : map.keyframes()) ids.push_back(id);
  std::sort(ids.begin(), ids.end());
  std::unordered_map<uint64_t, int> index;
  for (const uint64_t id : ids) {
    index.emplace(id, static_cast<int>(problem.keyframes.size()));
    problem.keyframes.push_back({id, map.keyframe(id)->T_wc, id == gauge_keyframe});
  }
  if (!problem.keyframes.empty() && index.count(gauge_keyframe) == 0)
    problem.keyframes.front().fixed = true;
  std::vector<uint64_t> point_ids;
  for (const auto& [id, p] : map.map_points()) point_ids.push_back(id);
  std::sort(point_ids.begin(), point_ids.end());
  for (const uint64_t id : point_ids) {
    const MapPoint* p = map.map_point(id);
    const int pi = static_cast<int>(problem.points.size());
    problem.points.push_back({id, p->p_w});
    for (const auto& [kf_id, k] : p->observations) {
      const auto it = index.find(kf_id);
      if (it == index.end()) continue;
      const Keypoint& kp = map.keyframe(kf_id)->features.keypoints[k];
      BaObservation o;
      o.keyframe = it->second;
      o.point = pi;
      o.uv = kp.uv.cast<double>();
      o.depth = kp.depth;
      o.inv_sigma = scales.inv_scale[kp.octave];
      o.depth_sigma = keypoint_depth_sigma(kp.depth, kp.depth_slope, scales.scale[kp.octave],
                                           pose_params, kp.depth_sync_sigma);
      problem.observations.push_back(o);
    }
  }
  for (const uint64_t id : ids) {
    const KeyFrame* kf = map.keyframe(id);
    if (kf->odometry_from == kNoId || index.count(kf->odometry_from) == 0) continue;
    problem.odometry.push_back(
        {index.at(kf->odometry_from), index.at(id), kf->T_odometry, kf->odometry_information});
  }
  return problem;
}

}  // namespace dqo::tracking
