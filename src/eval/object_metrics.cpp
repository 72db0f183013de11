#include "dqo_map/eval/object_metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "dqo_map/common/min_cost_assignment.h"
#include "dqo_map/geometry/conic.h"
#include "dqo_map/geometry/dual_quadric.h"

namespace dqo::eval {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Pairs (estimate index, ground-truth index) of one class: as many admissible pairs as possible,
// then the least total centre distance. Inadmissible pairs and padding cost more than every
// admissible pair together, so the optimum never trades a match for distance.
std::vector<std::pair<int, int>> match_class(const std::vector<ObjectEstimate>& est,
                                             const std::vector<int>& est_idx,
                                             const std::vector<ObjectEstimate>& gt,
                                             const std::vector<int>& gt_idx) {
  const int n = static_cast<int>(std::max(est_idx.size(), gt_idx.size()));
  std::vector<std::vector<double>> distance(est_idx.size(), std::vector<double>(gt_idx.size()));
  std::vector<std::vector<bool>> admissible(est_idx.size(),
                                            std::vector<bool>(gt_idx.size(), false));
  double total = 0.0;
  bool any = false;
  for (size_t a = 0; a < est_idx.size(); ++a) {
    for (size_t b = 0; b < gt_idx.size(); ++b) {
      const OrientedBox& g = gt[gt_idx[b]].box;
      const double d = centre_distance(est[est_idx[a]].box, g);
      distance[a][b] = d;
      admissible[a][b] = std::isfinite(d) && d <= match_radius(g);
      if (admissible[a][b]) {
        total += d;
        any = true;
      }
    }
  }
  if (!any) return {};
  const double kBig = 1.0 + 2.0 * total;
  Eigen::MatrixXd cost = Eigen::MatrixXd::Constant(n, n, kBig);
  for (size_t a = 0; a < est_idx.size(); ++a) {
    for (size_t b = 0; b < gt_idx.size(); ++b) {
      if (admissible[a][b]) cost(a, b) = distance[a][b];
    }
  }
  const std::vector<int> col_of_row = min_cost_assignment(cost);
  std::vector<std::pair<int, int>> pairs;
  for (size_t a = 0; a < est_idx.size(); ++a) {
    const int b = col_of_row[a];
    if (b < static_cast<int>(gt_idx.size()) && admissible[a][b]) {
      pairs.emplace_back(est_idx[a], gt_idx[b]);
    }
  }
  return pairs;
}

std::optional<Box2d> corner_box(const OrientedBox& box, const PinholeCamera& camera,
                                const SE3& T_cw, double near) {
  Box2d out{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
            -std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  // The box is convex, so its image is the hull of its corners' images as long as every corner is
  // in front of the camera; one behind makes the image unbounded.
  for (const Eigen::Vector3d& p_w : box_corners(box)) {
    const Eigen::Vector3d p_c = T_cw * p_w;
    if (!(p_c.z() > near)) return std::nullopt;
    const Eigen::Vector2d uv = camera.project(p_c);
    out.x_min = std::min(out.x_min, uv.x());
    out.y_min = std::min(out.y_min, uv.y());
    out.x_max = std::max(out.x_max, uv.x());
    out.y_max = std::max(out.y_max, uv.y());
  }
  return out.clip(camera.width, camera.height);
}

}  // namespace

double match_radius(const OrientedBox& gt_box) { return gt_box.half_extents.maxCoeff(); }

std::optional<Box2d> projected_image_box(const OrientedBox& box, const PinholeCamera& camera,
                                         const SE3& T_cw, Projection2d projection, double near) {
  if (projection == Projection2d::kBoxes) return corner_box(box, camera, T_cw, near);
  const DualQuadric q = DualQuadric::from_params(box.centre, box.rotation, box.half_extents);
  // A flat box has no ellipsoid to project.
  if (!q.is_valid()) return std::nullopt;
  const auto projected = projected_box(q, camera, T_cw, near);
  if (!projected) return std::nullopt;
  return projected->box;
}

ObjectMetrics evaluate_objects(const std::vector<ObjectEstimate>& estimated,
                               const std::vector<ObjectEstimate>& ground_truth,
                               const std::vector<EvalView>& views, const ObjectEvalParams& params) {
  ObjectMetrics m;
  m.num_gt = static_cast<int>(ground_truth.size());

  // Matching, per class.
  std::map<int, std::pair<std::vector<int>, std::vector<int>>> by_class;
  for (size_t i = 0; i < estimated.size(); ++i) {
    by_class[estimated[i].class_id].first.push_back(static_cast<int>(i));
  }
  for (size_t j = 0; j < ground_truth.size(); ++j) {
    by_class[ground_truth[j].class_id].second.push_back(static_cast<int>(j));
  }
  std::vector<int> est_of_gt(ground_truth.size(), -1);
  std::vector<bool> est_matched(estimated.size(), false);
  for (const auto& [class_id, members] : by_class) {
    for (const auto& [i, j] : match_class(estimated, members.first, ground_truth, members.second)) {
      est_of_gt[j] = i;
      est_matched[i] = true;
    }
  }

  // Views in camera-from-world form, once.
  std::vector<SE3> T_cw(views.size());
  for (size_t k = 0; k < views.size(); ++k) T_cw[k] = views[k].T_wc.inverse();

  double sum_iou_3d = 0.0, sum_iou_2d = 0.0, sum_cde = 0.0;
  for (size_t j = 0; j < ground_truth.size(); ++j) {
    const ObjectEstimate& g = ground_truth[j];
    const int i = est_of_gt[j];
    int views_seen = 0;
    double sum_view_iou = 0.0;
    for (size_t k = 0; k < views.size(); ++k) {
      const auto gt_box =
          projected_image_box(g.box, views[k].camera, T_cw[k], params.projection, params.near);
      if (!gt_box || !(gt_box->area() > 0.0)) continue;
      ++views_seen;
      if (i < 0) continue;
      const auto est_box = projected_image_box(estimated[i].box, views[k].camera, T_cw[k],
                                               params.projection, params.near);
      if (est_box) sum_view_iou += iou(*gt_box, *est_box);
    }
    if (views_seen > 0) ++m.num_gt_in_views;
    if (i < 0) {
      m.unmatched_gt.push_back(g.id);
      continue;
    }
    ObjectMatch match;
    match.est_id = estimated[i].id;
    match.gt_id = g.id;
    match.class_id = g.class_id;
    match.iou_3d = iou_3d(estimated[i].box, g.box);
    match.centre_distance = centre_distance(estimated[i].box, g.box);
    match.views_2d = views_seen;
    match.iou_2d = views_seen > 0 ? sum_view_iou / views_seen : kNaN;
    sum_iou_3d += match.iou_3d;
    sum_cde += match.centre_distance;
    if (views_seen > 0) sum_iou_2d += match.iou_2d;
    m.matches.push_back(match);
  }
  for (size_t i = 0; i < estimated.size(); ++i) {
    if (!est_matched[i]) m.spurious.push_back(estimated[i].id);
  }
  m.num_matched = static_cast<int>(m.matches.size());
  m.num_spurious = static_cast<int>(m.spurious.size());
  m.mean_iou_3d = m.num_gt > 0 ? sum_iou_3d / m.num_gt : 0.0;
  m.mean_iou_3d_matched = m.num_matched > 0 ? sum_iou_3d / m.num_matched : kNaN;
  m.mean_iou_2d = m.num_gt_in_views > 0 ? sum_iou_2d / m.num_gt_in_views : kNaN;
  m.mean_cde = m.num_matched > 0 ? sum_cde / m.num_matched : kNaN;
  return m;
}

}  // namespace dqo::eval
