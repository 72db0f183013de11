#include "object_factors.h"

#include <algorithm>
#include <cmath>

#include <ceres/loss_function.h>
#include <ceres/problem.h>

#include "object_box_cost.h"

namespace dqo::tracking {

void ObjectLandmarkStore::set_landmarks(const std::vector<ObjectLandmark>& landmarks) {
  landmarks_.clear();
  for (const ObjectLandmark& l : landmarks) landmarks_[l.id] = l;
}

void ObjectLandmarkStore::add_sightings(uint64_t keyframe, const SE3& T_kf_frame,
                                        const std::vector<ObjectSighting>& sightings) {
  if (sightings.empty()) return;
  by_keyframe_[keyframe].push_back({T_kf_frame, sightings});
}

void ObjectLandmarkStore::clear() {
  landmarks_.clear();
  by_keyframe_.clear();
}

size_t ObjectLandmarkStore::num_sightings() const {
  size_t n = 0;
  for (const auto& [kf, frames] : by_keyframe_)
    for (const FrameSightings& f : frames) n += f.sightings.size();
  return n;
}

bool object_box_at(const BaObjectObservation& o, const SE3& T_fw, const PinholeCamera& camera,
                   Box2d* box) {
  const Eigen::Vector3d mu_c = T_fw * o.centre_w;
  const Eigen::Matrix3d L_c = T_fw.rotation() * o.L_w;
  double b[4];
  if (!conic_box_in_camera(Intrinsics(camera), mu_c, L_c, b)) return false;
  *box = Box2d{b[0], b[1], b[2], b[3]};
  return true;
}

void ObjectLandmarkStore::observations(uint64_t keyframe_id, int index, const SE3& T_wc,
                                       const PinholeCamera& camera,
                                       const ObjectLandmarkParams& params,
                                       std::vector<BaObjectObservation>* out) const {
  const auto it = by_keyframe_.find(keyframe_id);
  if (it == by_keyframe_.end()) return;
  const double inv_sigma = 1.0 / std::max(1e-6, params.box_sigma_px);
  for (const FrameSightings& frame : it->second) {
    const SE3 T_frame_kf = frame.T_kf_frame.inverse();
    const SE3 T_fw = T_frame_kf * T_wc.inverse();
    for (const ObjectSighting& s : frame.sightings) {
      const auto l = landmarks_.find(s.object_id);
      if (l == landmarks_.end()) continue;
      const ObjectLandmark& object = l->second;
      if (!object.confirmed || object.confidence < params.min_confidence ||
          object.observations < params.min_observations || !object.quadric.is_valid() ||
          !s.box.valid())
        continue;
      BaObjectObservation o;
      o.keyframe = index;
      o.object_id = object.id;
      o.T_frame_kf = T_frame_kf;
      o.centre_w = object.quadric.centre();
      o.L_w = object.quadric.rotation() * object.quadric.semi_axes().asDiagonal();
      o.box = s.box;
      const std::array<bool, 4> border =
          s.box.edges_touching_border(camera.width, camera.height, params.border_px);
      // edges_touching_border's order is x_min, x_max, y_min, y_max; the cost's x_min, y_min, ...
      o.use_edge = {!border[0], !border[2], !border[1], !border[3]};
      if (std::none_of(o.use_edge.begin(), o.use_edge.end(), [](bool b) { return b; })) continue;
      Box2d projected;
      if (!object_box_at(o, T_fw, camera, &projected) || iou(projected, s.box) < params.min_iou)
        continue;
      o.scale = inv_sigma * std::sqrt(std::min(1.0, object.confidence));
      o.huber = params.huber;
      out->push_back(o);
    }
  }
}

int add_object_costs(const std::vector<BaObjectObservation>& observations, const PinholeCamera& camera,
                     const std::vector<std::pair<double*, double*>>& blocks, ceres::Problem* problem,
                     std::vector<std::unique_ptr<ceres::LossFunction>>* losses) {
  const Intrinsics K(camera);
  int added = 0;
  for (const BaObjectObservation& o : observations) {
    if (o.keyframe < 0 || o.keyframe >= static_cast<int>(blocks.size())) continue;
    const auto [q, t] = blocks[o.keyframe];
    if (q == nullptr || t == nullptr) continue;
    // The box must exist where the solver starts: a cost that cannot be evaluated there fails the
    // whole problem.
    const SE3 T_kw(Eigen::Quaterniond(q[3], q[0], q[1], q[2]), Eigen::Vector3d(t[0], t[1], t[2]));
    Box2d box;
    if (!object_box_at(o, o.T_frame_kf * T_kw, camera, &box)) continue;
    losses->push_back(std::make_unique<ceres::HuberLoss>(o.huber));
    problem->AddResidualBlock(
        ObjectBoxCost::Create(K, o.T_frame_kf, o.centre_w, o.L_w, o.box, o.use_edge, o.scale),
        losses->back().get(), q, t);
    ++added;
  }
  return added;
}

}  // namespace dqo::tracking
