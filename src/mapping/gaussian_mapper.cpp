#include "dqo_map/mapping/gaussian_mapper.h"

#ifdef DQO_MAPPING_CUDA
#include "dqo_map/cuda/cuda_backend.h"
#include "dqo_map/cuda/device_info.h"
#endif

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "dqo_map/common/stopwatch.h"
#include "dqo_map/mapping/params_yaml.h"

namespace dqo::mapping {
namespace {

bool fail(std::string* error, const std::string& message) {
  if (error) *error = message;
  return false;
}

// The backend the parameters ask for: the rasteriser, and on the GPU the training engine too.
struct TrainerBackend {
  std::unique_ptr<gs::Rasteriser> rasteriser;
  std::unique_ptr<gs::TrainingEngine> engine;
};

bool use_gpu(Backend backend) {
  switch (backend) {
    case Backend::kCuda:
#ifdef DQO_MAPPING_CUDA
      // No silent CPU run when the GPU was asked for: it would be far slower than expected.
      if (!cuda::gpu_available()) throw std::invalid_argument("mapping backend 'cuda': no usable GPU");
      return true;
#else
      throw std::invalid_argument("mapping backend 'cuda' is not available in this build (no CUDA ring)");
#endif
    case Backend::kAuto:
#ifdef DQO_MAPPING_CUDA
      return cuda::gpu_available();
#else
      return false;
#endif
    case Backend::kCpu:
      break;
  }
  return false;
}

TrainerBackend make_backend(const GaussianMapperParams& p) {
  TrainerBackend b;
#ifdef DQO_MAPPING_CUDA
  if (use_gpu(p.backend)) {
    cuda::CudaBackend gpu = cuda::make_cuda_backend();  // rasteriser and engine share the map
    b.rasteriser = std::move(gpu.rasteriser);
    b.engine = std::move(gpu.engine);
    return b;
  }
#else
  use_gpu(p.backend);  // throws for `cuda`
#endif
  b.rasteriser = gs::make_cpu_rasteriser(p.threads);
  return b;
}

// The hash of what shapes a map: not the thread count, which changes no result (the CPU
// rasteriser's is the same bit for bit on any), so a map saved on one machine resumes on another
// without a warning.
uint64_t hash_of_shaping(GaussianMapperParams params) {
  params.threads = 0;
  return params_hash(mapping_params_to_yaml(params));
}

}  // namespace

bool parse_backend(const std::string& text, Backend* backend) {
  if (text == "auto") {
    *backend = Backend::kAuto;
  } else if (text == "cpu") {
    *backend = Backend::kCpu;
  } else if (text == "cuda") {
    *backend = Backend::kCuda;
  } else {
    return false;
  }
  return true;
}

const char* to_string(Backend backend) {
  switch (backend) {
    case Backend::kAuto:
      return "auto";
    case Backend::kCpu:
      return "cpu";
    case Backend::kCuda:
      return "cuda";
  }
  return "?";
}

GaussianMapper::GaussianMapper(const GaussianMapperParams& params)
    : params_(params), params_hash_(hash_of_shaping(params)) {
  gs::GaussianTrainer::Params trainer = params_.trainer;
  trainer.max_gaussians = params_.max_gaussians;
  TrainerBackend backend = make_backend(params_);
  trainer_ = std::make_unique<gs::GaussianTrainer>(trainer, std::move(backend.rasteriser), std::move(backend.engine));
}

GaussianMapper::~GaussianMapper() = default;

bool GaussianMapper::add_keyframe(MappingKeyframe keyframe, std::string* error) {
  const int w = keyframe.camera.width, h = keyframe.camera.height;
  const std::string name = "keyframe " + std::to_string(keyframe.id);
  if (w <= 0 || h <= 0 || !(keyframe.camera.fx > 0.0) || !(keyframe.camera.fy > 0.0)) {
    return fail(error, name + ": invalid camera");
  }
  if (!keyframe.rgb.same_size(w, h) || keyframe.rgb.channels != 3) {
    return fail(error, name + ": colour image is not " + std::to_string(w) + "x" +
                           std::to_string(h) + " RGB");
  }
  if (!keyframe.depth.same_size(w, h) || keyframe.depth.channels != 1) {
    return fail(error, name + ": depth image is not " + std::to_string(w) + "x" +
                           std::to_string(h) + " single-channel");
  }
  if (!keyframe.T_wc.translation().allFinite() || !keyframe.T_wc.quaternion().coeffs().allFinite() ||
      !std::isfinite(keyframe.stamp)) {
    return fail(error, name + ": pose or stamp is not finite");
  }
  if (!seen_ids_.insert(keyframe.id).second) {
    return fail(error, name + ": repeated keyframe ID (ignored)");
  }
  const double stamp = keyframe.stamp;
  Pending p;
  p.keyframe = std::move(keyframe);
  const auto early = early_objects_.find(p.keyframe.id);
  if (early != early_objects_.end()) {
    p.objects = std::move(early->second);
    early_objects_.erase(early);
    make_ready(std::move(p));
  } else {
    waiting_.emplace(p.keyframe.id, std::move(p));
  }
  release_expired(stamp);
  return true;
}

bool GaussianMapper::add_keyframe_objects(KeyframeObjects objects, std::string* error) {
  const std::string name = "objects of keyframe " + std::to_string(objects.keyframe_id);
  if (objects.object_ids.size() != objects.detections.size()) {
    return fail(error, name + ": " + std::to_string(objects.detections.size()) +
                           " detections but " + std::to_string(objects.object_ids.size()) +
                           " object IDs");
  }
  for (const ObjectId id : objects.object_ids) {
    // The map stores object IDs in 32 bits (GaussianMap); the object stage counts from 1 and
    // would need four billion objects to get there, so a larger ID is a corrupt message.
    if (id > kMaxObjectId) {
      return fail(error, name + ": object ID " + std::to_string(id) + " is beyond " +
                             std::to_string(kMaxObjectId));
    }
  }
  const auto it = waiting_.find(objects.keyframe_id);
  if (it == waiting_.end()) {
    if (seen_ids_.count(objects.keyframe_id)) {
      // Its keyframe was already mapped as background (timeout) or dropped: too late to use.
      return fail(error, name + " came after the keyframe was mapped (ignored)");
    }
    early_objects_[objects.keyframe_id] = std::move(objects);
    return true;
  }
  const auto& k = it->second.keyframe;
  if (!objects.instance.empty() &&
      (!objects.instance.same_size(k.camera.width, k.camera.height) ||
       objects.instance.channels != 1)) {
    return fail(error, name + ": instance image is not of the keyframe's size");
  }
  it->second.objects = std::move(objects);
  Pending p = std::move(it->second);
  waiting_.erase(it);
  make_ready(std::move(p));
  return true;
}

void GaussianMapper::make_ready(Pending p) {
  ready_.push_back(std::move(p));
  if (params_.max_queue > 0) {
    while (ready_.size() > static_cast<size_t>(params_.max_queue)) {
      ready_.pop_front();
      ++dropped_;
    }
  }
}

void GaussianMapper::release_expired(double newest_stamp) {
  // Keyframes in ID order are in time order; the objects of an old one are given up once a
  // keyframe objects_timeout seconds newer has come. A looping bag (time going back) releases
  // nothing here; flush() or later keyframes do.
  for (auto it = waiting_.begin(); it != waiting_.end();) {
    if (newest_stamp - it->second.keyframe.stamp > params_.objects_timeout) {
      Pending p = std::move(it->second);
      it = waiting_.erase(it);
      make_ready(std::move(p));
    } else {
      ++it;
    }
  }
}

void GaussianMapper::flush() {
  for (auto& [id, p] : waiting_) make_ready(std::move(p));
  waiting_.clear();
}

int GaussianMapper::set_keyframe_poses(const std::map<KeyframeId, SE3>& T_wc_by_id) {
  int known = 0;
  for (const auto& [id, T_wc] : T_wc_by_id) {
    bool found = false;
    if (auto it = waiting_.find(id); it != waiting_.end()) {
      it->second.keyframe.T_wc = T_wc;
      found = true;
    }
    for (Pending& p : ready_) {
      if (p.keyframe.id == id) {
        p.keyframe.T_wc = T_wc;
        found = true;
      }
    }
    for (KeyframePose& k : keyframes_) {
      if (k.id == id) {
        k.T_wc = T_wc;
        found = true;
      }
    }
    trainer_->set_keyframe_pose(static_cast<uint32_t>(id), T_wc);
    known += found ? 1 : 0;
  }
  return known;
}

ObjectId GaussianMapper::resolve(ObjectId id) const {
  // Chains are short (a merge of a merge); the bound guards against a cycle from bad events.
  for (int hops = 0; hops < 64 && id != 0; ++hops) {
    const auto it = merged_into_.find(id);
    if (it == merged_into_.end()) return id;
    id = it->second;
  }
  return id;
}

size_t GaussianMapper::apply_event(const MappingEvent& event) {
  if (event.id > kMaxObjectId || event.into_id > kMaxObjectId) return 0;  // see add_keyframe_objects
  switch (event.type) {
    case MappingEvent::Type::kCreated:
      return 0;
    case MappingEvent::Type::kMerged: {
      const ObjectId into = resolve(event.into_id);
      if (event.id == 0 || into == event.id) return 0;
      merged_into_[event.id] = into;
      objects_.erase(event.id);
      for (auto& [kf, ids] : keyframe_objects_) {
        for (ObjectId& o : ids) o = o == event.id ? into : o;
      }
      return trainer_->relabel(static_cast<uint32_t>(event.id), static_cast<uint32_t>(into));
    }
    case MappingEvent::Type::kRemoved: {
      if (event.id == 0) return 0;
      merged_into_[event.id] = 0;
      objects_.erase(event.id);
      for (auto& [kf, ids] : keyframe_objects_) {
        ids.erase(std::remove(ids.begin(), ids.end(), event.id), ids.end());
      }
      return trainer_->relabel(static_cast<uint32_t>(event.id), 0);
    }
  }
  return 0;
}

void GaussianMapper::set_objects(std::vector<ObjectRecord> objects) {
  objects_.clear();
  for (ObjectRecord& o : objects) {
    if (o.id != 0) objects_[o.id] = std::move(o);
  }
}

gs::LabelImage GaussianMapper::make_labels(const Pending& p, bool* from_instance) const {
  *from_instance = false;
  const KeyframeObjects& o = *p.objects;
  const MappingKeyframe& k = p.keyframe;
  if (!o.instance.empty()) {
    // Instance value j + 1 is detection j, which became object_ids[j] (0: rejected).
    std::vector<uint32_t> table(o.detections.size() + 1, 0);
    for (size_t j = 0; j < o.object_ids.size(); ++j) {
      table[j + 1] = static_cast<uint32_t>(resolve(o.object_ids[j]));
    }
    *from_instance = true;
    return gs::labels_from_instance(o.instance, table);
  }
  std::vector<gs::LabelledObject> labelled;
  for (size_t j = 0; j < o.detections.size(); ++j) {
    const ObjectId id = resolve(o.object_ids[j]);
    const auto it = objects_.find(id);
    if (id == 0 || it == objects_.end()) continue;  // rejected, or no quadric known yet
    gs::LabelledObject l;
    l.object_id = static_cast<uint32_t>(id);
    l.quadric = it->second.quadric;
    l.box = o.detections[j].box;
    l.score = o.detections[j].score;
    labelled.push_back(l);
  }
  if (labelled.empty()) return {};
  return gs::labels_from_objects(k.depth, k.camera, k.T_wc, labelled, params_.labels);
}

std::optional<MappingReport> GaussianMapper::process_next() {
  if (ready_.empty()) return std::nullopt;
  const auto t0 = std::chrono::steady_clock::now();
  Pending p = std::move(ready_.front());
  ready_.pop_front();

  MappingReport report;
  report.keyframe_id = p.keyframe.id;
  report.labelled = p.objects.has_value();
  gs::TrainingKeyframe t;
  t.id = static_cast<uint32_t>(p.keyframe.id);
  t.camera = p.keyframe.camera;
  t.T_wc = p.keyframe.T_wc;
  std::vector<ObjectId> seen;
  if (p.objects) {
    t.labels = make_labels(p, &report.from_instance);
    for (const ObjectId id : p.objects->object_ids) {
      const ObjectId r = resolve(id);
      if (r != 0 && std::find(seen.begin(), seen.end(), r) == seen.end()) seen.push_back(r);
    }
  }
  report.label_ms = ms_since(t0);
  KeyframePose pose;
  pose.id = p.keyframe.id;
  pose.stamp = p.keyframe.stamp;
  pose.camera = p.keyframe.camera;
  pose.T_wc = p.keyframe.T_wc;
  t.rgb = std::move(p.keyframe.rgb);
  t.depth = std::move(p.keyframe.depth);

  const auto t1 = std::chrono::steady_clock::now();
  report.trainer = trainer_->add_keyframe(std::move(t));
  report.train_ms = ms_since(t1);
  keyframes_.push_back(pose);
  std::sort(seen.begin(), seen.end());
  keyframe_objects_[pose.id] = std::move(seen);

  const gs::GaussianMap& map = trainer_->structure();  // counts: no copy of the attributes
  report.num_gaussians = map.size();
  report.bytes = map.bytes_used();
  const std::map<uint32_t, size_t> counts = map.counts_by_object();
  report.gaussians_per_object.insert(counts.begin(), counts.end());
  report.queued = ready_.size() + waiting_.size();
  report.dropped_total = dropped_;
  report.total_ms = ms_since(t0);
  return report;
}

std::vector<ObjectSummary> GaussianMapper::list_objects() const {
  std::map<ObjectId, ObjectSummary> out;
  for (const auto& [id, o] : objects_) {
    out[id].object = o;
    out[id].known = true;
  }
  for (const auto& [id, count] : trainer_->structure().counts_by_object()) {
    if (id == 0) continue;
    ObjectSummary& s = out[id];
    s.object.id = id;
    s.num_gaussians = count;
  }
  std::vector<ObjectSummary> list;
  for (auto& [id, s] : out) list.push_back(std::move(s));
  return list;
}

const ObjectRecord* GaussianMapper::find_object(ObjectId id) const {
  const auto it = objects_.find(id);
  return it == objects_.end() ? nullptr : &it->second;
}

gs::GaussianMap GaussianMapper::object_gaussians(ObjectId id) const {
  const gs::GaussianMap& map = trainer_->map();
  return map.subset(map.indices_of(static_cast<uint32_t>(id)));
}

void GaussianMapper::render(const PinholeCamera& camera, const SE3& T_wc, gs::RenderOutput* out) {
  trainer_->render(camera, T_wc, out);
}

std::vector<ObjectView> GaussianMapper::object_views(ObjectId id, bool with_scene_depth) {
  std::vector<const KeyframePose*> candidates;
  for (const KeyframePose& k : keyframes_) {
    const auto it = keyframe_objects_.find(k.id);
    const bool saw = id == 0 || (it != keyframe_objects_.end() &&
                                 std::binary_search(it->second.begin(), it->second.end(), id));
    if (saw) candidates.push_back(&k);
  }
  // At most mesh_views, spread evenly over the views (first and last included).
  std::vector<const KeyframePose*> chosen;
  const size_t n = candidates.size(), m = static_cast<size_t>(std::max(1, params_.mesh_views));
  if (n <= m) {
    chosen = candidates;
  } else {
    for (size_t k = 0; k < m; ++k) chosen.push_back(candidates[m == 1 ? 0 : k * (n - 1) / (m - 1)]);
  }
  std::vector<ObjectView> views;
  const gs::GaussianMap object = object_gaussians(id);
  if (object.empty()) return views;
  gs::RenderSettings settings;
  settings.surface_depth = true;
  settings.surface_gap = params_.trainer.surface_gap;
  settings.surface_gap_relative = params_.trainer.surface_gap_relative;
  for (const KeyframePose* k : chosen) {
    gs::RenderOutput r;
    trainer_->rasteriser().forward(object, k->camera, k->T_wc.inverse(), settings, &r, nullptr);
    ObjectView v;
    v.keyframe_id = k->id;
    v.camera = k->camera;
    v.T_wc = k->T_wc;
    v.depth.assign(r.depth.size(), 0.f);
    v.rgb.assign(r.rgb.size(), 0.f);
    size_t surface = 0;
    for (size_t p = 0; p < r.depth.size(); ++p) {
      if (!(r.alpha[p] >= params_.mesh_min_alpha) || !std::isfinite(r.depth[p])) continue;
      v.depth[p] = r.depth[p];
      // Colour normalised by alpha: the surface's own colour, not darkened by the black behind.
      for (int c = 0; c < 3; ++c) v.rgb[3 * p + c] = r.rgb[3 * p + c] / r.alpha[p];
      ++surface;
    }
    if (surface == 0) continue;
    if (with_scene_depth) {
      gs::RenderOutput scene;
      trainer_->rasteriser().forward(trainer_->map(), k->camera, k->T_wc.inverse(), settings,
                                     &scene, nullptr);
      v.scene_depth.assign(scene.depth.size(), 0.f);
      for (size_t p = 0; p < scene.depth.size(); ++p) {
        if (scene.alpha[p] >= params_.mesh_min_alpha && std::isfinite(scene.depth[p])) {
          v.scene_depth[p] = scene.depth[p];
        }
      }
    }
    views.push_back(std::move(v));
  }
  return views;
}

MapFileContents GaussianMapper::snapshot(ObjectId next_object_id) const {
  MapFileContents c;
  c.gaussians = trainer_->map();
  for (const auto& [id, o] : objects_) c.objects.push_back(o);
  c.keyframes = keyframes_;
  c.next_object_id = next_object_id;
  c.params_hash = params_hash_;
  return c;
}

void GaussianMapper::restore(MapFileContents contents, std::string* warning) {
  if (warning) {
    warning->clear();
    if (contents.params_hash != params_hash_) {
      *warning = "the map was made with other mapping parameters";
    }
  }
  trainer_->set_map(std::move(contents.gaussians));
  set_objects(std::move(contents.objects));
  keyframes_ = std::move(contents.keyframes);
  keyframe_objects_.clear();
  // Which keyframes saw which object is not stored: a keyframe saw an object when the object's
  // ellipsoid centre projects into its image in front of the camera. Enough for mesh views.
  for (const KeyframePose& k : keyframes_) {
    seen_ids_.insert(k.id);
    std::vector<ObjectId> seen;
    const SE3 T_cw = k.T_wc.inverse();
    for (const auto& [id, o] : objects_) {
      const Eigen::Vector3d p_c = T_cw * o.quadric.centre();
      if (p_c.z() <= 0.0) continue;
      const Eigen::Vector2d uv = k.camera.project(p_c);
      if (uv.x() >= 0 && uv.y() >= 0 && uv.x() < k.camera.width && uv.y() < k.camera.height) {
        seen.push_back(id);
      }
    }
    keyframe_objects_[k.id] = std::move(seen);
  }
  merged_into_.clear();
}

}  // namespace dqo::mapping
