#pragma once
// Objects as landmarks inside the tracker: the latest object set from the object stage, the
// sightings of registered frames filed under the tracker keyframe they follow, and the hand-over
// of both to local bundle adjustment (BaObjectObservation) and into a Ceres problem.
//
// Lives on the tracker's thread (like the map): the BA worker only sees the snapshot.

#include <cstdint>
#include <map>
#include <memory>
#include <utility>
#include <vector>

#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"
#include "dqo_map/tracking/object_landmarks.h"
#include "dqo_map/tracking/tracker_params.h"
#include "local_ba.h"

namespace ceres {
class Problem;
class LossFunction;
}  // namespace ceres

namespace dqo::tracking {

class ObjectLandmarkStore {
 public:
  // Replaces the whole set: the newest version of every object (see object_landmarks.h).
  void set_landmarks(const std::vector<ObjectLandmark>& landmarks);
  // The sightings of a frame that follows `keyframe` at T_kf_frame (a registered frame).
  void add_sightings(uint64_t keyframe, const SE3& T_kf_frame,
                     const std::vector<ObjectSighting>& sightings);
  void clear();

  // The usable sightings of `keyframe_id` (at T_wc, index `index` of the problem), appended to
  // `out`: the object is in the set, confirmed, confident and seen often enough (params), its box
  // exists at the keyframe's pose and overlaps the detection by params.min_iou (a sighting that
  // does not is a wrong association or a stale object: it would only pull the pose astray).
  void observations(uint64_t keyframe_id, int index, const SE3& T_wc, const PinholeCamera& camera,
                    const ObjectLandmarkParams& params, std::vector<BaObjectObservation>* out) const;

  size_t num_landmarks() const { return landmarks_.size(); }
  size_t num_sightings() const;

 private:
  struct FrameSightings {
    SE3 T_kf_frame;
    std::vector<ObjectSighting> sightings;
  };
  std::map<uint64_t, ObjectLandmark> landmarks_;                  // by object ID
  std::map<uint64_t, std::vector<FrameSightings>> by_keyframe_;   // by tracker keyframe ID
};

// The camera-frame box of an object seen from a frame at T_fw; false where it has none.
bool object_box_at(const BaObjectObservation& o, const SE3& T_fw, const PinholeCamera& camera,
                   Box2d* box);

// Adds ObjectBoxCost blocks to `problem` for the observations whose keyframe has pose blocks
// (blocks[k] = {q_cw, t_cw}, null where keyframe k is not in the problem: an object alone, four
// residuals per box, does not define a pose) and whose box exists at the current estimate. Losses
// are kept in `losses`. Returns the number of blocks added.
int add_object_costs(const std::vector<BaObjectObservation>& observations, const PinholeCamera& camera,
                     const std::vector<std::pair<double*, double*>>& blocks, ceres::Problem* problem,
                     std::vector<std::unique_ptr<ceres::LossFunction>>* losses);

}  // namespace dqo::tracking
