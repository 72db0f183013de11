#pragma once
// The object stage as one class (DESIGN.md "Layers"): the association node and the offline runner
// both feed it keyframes and read back objects and events, so a ROS run and an offline run give the
// same objects.
//
// Per keyframe (METHOD.md §2–3): filter detections; project the confirmed and candidate objects
// visible in the keyframe (occlusion: of two overlapping projections keep the nearer); associate
// detections one-to-one (coarse IoU, fine QD, or both); add observations and class votes; merge
// pieces of one occluded object; start candidates from unmatched detections (single-view depth
// ellipsoid until enough views for the box-plane initialisation); confirm and remove; refine the
// objects seen by the IoU loss over every keyframe that saw them, and fit their boxes
// (BoxFitParams: what the object list reports).
//
// Not thread-safe: one owner calls it (the node's callback thread, or the offline runner).
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>
#include "dqo_map/objects/object_params.h"
#include "dqo_map/objects/object_types.h"

namespace dqo::objects {

class ObjectMapper {
 public:
  // first_id: the next ID to give (1 for a fresh map; from the state file after a restart).
  explicit ObjectMapper(const ObjectMapperParams& params = ObjectMapperParams(),
                        ObjectId first_id = 1);
  ~ObjectMapper();
  ObjectMapper(const ObjectMapper&) = delete;
  ObjectMapper& operator=(const ObjectMapper&) = delete;

  // Processes one keyframe. Keyframe IDs must be new (a repeated ID is an error: *error set,
  // nothing changes, an empty result). Invalid detections are rejected with a verdict, never thrown.
  KeyFrameAssociation process_keyframe(const ObjectKeyFrame& keyframe, std::string* error = nullptr);

  // Corrected keyframe poses (after bundle adjustment): later refinements use them. Unknown IDs
  // are ignored; returns how many were known.
  int update_keyframe_poses(const std::map<KeyFrameId, SE3>& T_wc_by_id);

  // Confirmed objects (and candidates when asked), by ascending ID.
  std::vector<MapObject> objects(bool include_candidates = false) const;
  // nullptr for an unknown (or merged / removed) ID.
  const MapObject* find(ObjectId id) const;
  ObjectId next_id() const;
  // Class ID -> name, as the detections named them (for top_classes()).
  const std::map<int, std::string>& class_names() const;
  const ObjectMapperParams& params() const;

  // Persistence (DESIGN.md: IDs never reused across restarts): the objects (quadric, class votes,
  // observation counts; not the keyframes, which belong to one tracker run) and the next ID, written
  // atomically (temporary file + rename). load_state replaces the current map.
  bool save_state(const std::string& path, std::string* error) const;
  bool load_state(const std::string& path, std::string* error);

  // The map the objects' poses refer to (the tracker's map identity; "" = unknown), kept in the
  // state file: objects of one map mean nothing in another (another tracker run, another origin).
  void set_map_id(const std::string& map_id);
  const std::string& map_id() const;
  // Forgets every object (confirmed or candidate) and the keyframes, keeping the next ID so that no
  // ID is given twice: for a map that is not the objects' own. A REMOVED event per object dropped.
  std::vector<ObjectEvent> drop_objects();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dqo::objects
