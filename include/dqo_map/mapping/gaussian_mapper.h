#pragma once
// The mapping stage as one class (DESIGN.md "mapping nodelet", METHOD.md §4): the mapping nodelet
// and the offline runner both feed it what the other two stages publish and read back the map, so a
// ROS run and an offline run give the same Gaussians.
//
// Inputs mirror the messages: keyframes (KeyFrame), corrected poses (KeyFramePoses), each
// keyframe's detections and the objects they became (KeyFrameObjects), object events (ObjectEvent)
// and the current objects (ObjectArray). A keyframe waits until its objects arrive (either may come
// first, paired by keyframe ID); one whose objects do not come within `objects_timeout` seconds of
// keyframe time is mapped as background. Ready keyframes wait in a bounded queue (max_queue; the
// oldest are dropped and counted) until process_next() maps one:
//   1. pixel labels: the instance image mapped through the object IDs where the detector gave one,
//      otherwise depth points inside an object's (scaled) ellipsoid and detection box
//      (gaussians/pixel_labels.h); IDs that were merged since are followed to their survivor;
//   2. the trainer's incremental step (gaussians/trainer.h);
//   3. the Gaussian budget (max_gaussians, kept by the trainer's pruning): past it, the Gaussians
//      that contributed least to the views that last had them in sight go first.
// Events act at once: MERGED moves the Gaussians of one object to the other, REMOVED returns them
// to the background; none is lost.
//
// Not thread-safe: one owner calls it (the nodelet's worker, with its own lock, or the offline
// runner).

#include <atomic>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "dqo_map/gaussians/pixel_labels.h"
#include "dqo_map/gaussians/rasteriser.h"
#include "dqo_map/gaussians/trainer.h"
#include "dqo_map/mapping/map_file.h"
#include "dqo_map/mapping/mapping_types.h"

namespace dqo::mapping {

// Object IDs the map can hold (GaussianMap keeps 32 bits per Gaussian).
constexpr ObjectId kMaxObjectId = 0xffffffffu;

enum class Backend { kAuto, kCpu, kCuda };
bool parse_backend(const std::string& text, Backend* backend);
const char* to_string(Backend backend);

struct GaussianMapperParams {
  gs::GaussianTrainer::Params trainer;
  gs::ObjectLabelParams labels;  // the quadric ∩ box rule where there is no instance image
  Backend backend = Backend::kAuto;
  int threads = 0;  // CPU rasteriser threads; <= 0: all cores
  // Seconds of keyframe time a keyframe waits for its KeyFrameObjects before it is mapped as
  // background (the association node answers within one keyframe; a detector may lag).
  double objects_timeout = 2.0;
  int max_queue = 0;         // ready keyframes waiting; past it the oldest is dropped; 0 = unbounded
  int max_gaussians = 0;     // the budget; 0 = none
  // Renders for meshes: at most this many keyframes that saw the object, spread over its views.
  int mesh_views = 24;
  float mesh_min_alpha = 0.5f;  // rendered pixels less opaque than this are no surface
};

// Where the Gaussians of one object stand.
struct ObjectSummary {
  ObjectRecord object;     // id only (the rest default) for an ID the object stage never reported
  bool known = false;      // the object stage reported it (set_objects)
  size_t num_gaussians = 0;
};

// What one process_next() did.
struct MappingReport {
  KeyframeId keyframe_id = 0;
  bool labelled = false;          // its objects arrived; false: mapped as background (timeout)
  bool from_instance = false;     // labels from an instance image (else quadric ∩ box)
  double label_ms = 0.0, train_ms = 0.0, total_ms = 0.0;
  gs::KeyframeReport trainer;     // added, pruned (also to keep max_gaussians), loss, ...
  size_t num_gaussians = 0;
  size_t bytes = 0;               // the map's attribute arrays
  std::map<ObjectId, size_t> gaussians_per_object;  // 0 = background
  size_t queued = 0;              // keyframes still waiting after this one
  size_t dropped_total = 0;       // keyframes dropped by the bounded queue so far
};

// A view of one object's Gaussians rendered alone from a keyframe (for TSDF meshes).
struct ObjectView {
  KeyframeId keyframe_id = 0;
  PinholeCamera camera;
  SE3 T_wc;
  std::vector<float> rgb;    // 3 per pixel, [0, 1]
  std::vector<float> depth;  // metres; 0 where the render is less opaque than mesh_min_alpha
  // The whole map's surface depth from the same view (with_scene_depth), 0 where it has none:
  // around the object's silhouette, the surface it stands on.
  std::vector<float> scene_depth;
};

class GaussianMapper {
 public:
  // Throws std::invalid_argument for a backend this build does not have (cuda).
  explicit GaussianMapper(const GaussianMapperParams& params);
  ~GaussianMapper();
  GaussianMapper(const GaussianMapper&) = delete;
  GaussianMapper& operator=(const GaussianMapper&) = delete;

  // Inputs. add_keyframe returns false (and *error) for images that do not match the camera, an
  // empty image or a repeated ID; add_keyframe_objects for detections and IDs that disagree in
  // number, an instance image of another size, an ID beyond kMaxObjectId, or objects of a keyframe
  // already mapped; nothing changes then. Events with IDs beyond kMaxObjectId are ignored.
  bool add_keyframe(MappingKeyframe keyframe, std::string* error = nullptr);
  bool add_keyframe_objects(KeyframeObjects objects, std::string* error = nullptr);
  // Corrected poses: keyframes waiting, those in the trainer's window and the stored poses move.
  // Returns how many IDs were known.
  int set_keyframe_poses(const std::map<KeyframeId, SE3>& T_wc_by_id);
  // Returns the number of Gaussians relabelled.
  size_t apply_event(const MappingEvent& event);
  void set_objects(std::vector<ObjectRecord> objects);

  // Maps the oldest ready keyframe; nullopt when none is ready. Keyframes whose objects are late
  // become ready when a keyframe objects_timeout seconds newer arrives, or at flush().
  std::optional<MappingReport> process_next();
  // The end of the input: every waiting keyframe becomes ready (as background when its objects
  // never came).
  void flush();
  size_t ready() const { return ready_.size(); }
  size_t waiting() const { return waiting_.size(); }
  size_t dropped() const { return dropped_; }
  // A flag another thread sets to cut the training of the step in progress short (a shutdown):
  // GaussianTrainer::set_stop_flag. The keyframe still counts as mapped, with fewer iterations.
  void set_stop_flag(const std::atomic<bool>* stop) { trainer_->set_stop_flag(stop); }

  // Queries.
  std::vector<ObjectSummary> list_objects() const;  // by ID; objects reported or with Gaussians
  const ObjectRecord* find_object(ObjectId id) const;
  // The Gaussians of one object (0: the background) as a map of their own.
  gs::GaussianMap object_gaussians(ObjectId id) const;
  // The map (its trained attributes fetched from the GPU first where they are kept there).
  const gs::GaussianMap& map() const { return trainer_->map(); }
  // Its size, object IDs and flags, without that fetch (GaussianTrainer::structure()): for counts.
  const gs::GaussianMap& map_structure() const { return trainer_->structure(); }
  void render(const PinholeCamera& camera, const SE3& T_wc, gs::RenderOutput* out);
  // Renders of the object's Gaussians alone from (at most mesh_views of) the mapped keyframes that
  // saw it; for the background (0), from every mapped keyframe (at most mesh_views).
  std::vector<ObjectView> object_views(ObjectId id, bool with_scene_depth = false);
  const std::vector<KeyframePose>& keyframe_poses() const { return keyframes_; }
  size_t keyframes_mapped() const { return keyframes_.size(); }

  // Persistence: the map, objects, keyframe poses, next object ID and the parameters' hash.
  MapFileContents snapshot(ObjectId next_object_id) const;
  // Replaces the map by a loaded one. A file made with other parameters loads with a warning in
  // *warning (the hash differs). The trainer's window starts empty.
  void restore(MapFileContents contents, std::string* warning = nullptr);
  uint64_t params_hash() const { return params_hash_; }
  const GaussianMapperParams& params() const { return params_; }

 private:
  struct Pending {
    MappingKeyframe keyframe;
    std::optional<KeyframeObjects> objects;
  };
  ObjectId resolve(ObjectId id) const;  // follows merges; 0 for removed objects
  gs::LabelImage make_labels(const Pending& p, bool* from_instance) const;
  void release_expired(double newest_stamp);
  void make_ready(Pending p);

  GaussianMapperParams params_;
  uint64_t params_hash_ = 0;
  std::unique_ptr<gs::GaussianTrainer> trainer_;
  std::map<KeyframeId, Pending> waiting_;               // keyframes without their objects yet
  std::map<KeyframeId, KeyframeObjects> early_objects_;  // objects of keyframes not yet here
  std::deque<Pending> ready_;
  std::map<ObjectId, ObjectRecord> objects_;
  std::map<ObjectId, ObjectId> merged_into_;  // merged or removed (-> 0) IDs
  std::vector<KeyframePose> keyframes_;       // mapped keyframes, in order
  std::map<KeyframeId, std::vector<ObjectId>> keyframe_objects_;  // objects each mapped one saw
  std::set<KeyframeId> seen_ids_;             // every keyframe ID accepted (repeats refused)
  size_t dropped_ = 0;
};

}  // namespace dqo::mapping
