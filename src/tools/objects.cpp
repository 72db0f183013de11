// dqo_objects: maps the objects of an RGB-D dataset folder from its 2D detections (the object
// stage of association_node, run offline through dqo::system::run_object_pipeline) and writes one
// line per confirmed object, `id class tx ty tz qx qy qz qw a1 a2 a3` (the RO-MAP / VOOM format:
// centre, rotation, semi-axes). The numbers are the object's fitted box (objects.box_fit) read as
// its inscribed ellipsoid (semi-axes = half extents, as the evaluation reads them); with
// box_fit.enabled false, the mapped ellipsoid itself. dqo_eval_objects compares the file with objects_gt.txt.
//
//   dqo_objects DATASET_DIR --out objects.txt [--poses gt|TRAJ.txt] [--strategy iou|qd|iou+qd]
//               [--config objects.yaml] [--frames N] [--no-anchor] [--no-depth]
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "dqo_map/common/object_list.h"
#include "dqo_map/common/progress.h"
#include "dqo_map/common/statistics.h"
#include "dqo_map/common/tum_trajectory.h"
#include "dqo_map/io/dataset_reader.h"
#include "dqo_map/objects/params_yaml.h"
#include "dqo_map/system/object_pipeline.h"
#include "dqo_map/tracking/rectified_frame_source.h"

namespace {

using dqo::median;

constexpr char kUsage[] =
    "usage: dqo_objects DATASET_DIR --out objects.txt [--poses gt|TRAJ.txt] [--strategy iou|qd|iou+qd]\n"
    "                   [--config objects.yaml] [--frames N] [--no-anchor] [--no-depth]\n"
    "  DATASET_DIR       own format (camera.yaml, rgb/, detections.txt), TUM RGB-D or Replica\n"
    "  --out FILE        confirmed objects, one per line: id class tx ty tz qx qy qz qw a1 a2 a3\n"
    "  --poses gt        the dataset's ground-truth poses (default)\n"
    "  --poses TRAJ.txt  a TUM trajectory (e.g. dqo_track's), matched to the frames by timestamp;\n"
    "                    moved so that it starts at the ground-truth pose where the dataset has one\n"
    "                    (--no-anchor: keep the trajectory's own frame, boxes not held upright)\n"
    "  --strategy S      association: iou, qd or iou+qd (default: the config's, iou+qd)\n"
    "  --config FILE     object parameters (default: the built-in ones, as config/objects.yaml)\n"
    "  --frames N        only the first N frames\n"
    "  --no-depth        no single-view depth initialisation (box planes only)\n";

int usage_error(const std::string& message) {
  std::fprintf(stderr, "dqo_objects: %s\n%s", message.c_str(), kUsage);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::string dataset, out, poses = "gt", strategy, config;
  int frames = -1;
  bool anchor = true, depth = true;
  int positional = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> const char* { return i + 1 < argc ? argv[++i] : nullptr; };
    if (a == "-h" || a == "--help") {
      std::fputs(kUsage, stdout);
      return 0;
    } else if (a == "--out" || a == "--poses" || a == "--strategy" || a == "--config" || a == "--frames") {
      const char* v = value();
      if (!v) return usage_error(a + " needs a value");
      if (a == "--out") out = v;
      if (a == "--poses") poses = v;
      if (a == "--strategy") strategy = v;
      if (a == "--config") config = v;
      if (a == "--frames") {
        char* end = nullptr;
        const long n = std::strtol(v, &end, 10);
        if (end == v || *end != '\0' || n < 1) return usage_error("--frames takes a whole number >= 1");
        frames = static_cast<int>(n);
      }
    } else if (a == "--no-anchor") {
      anchor = false;
    } else if (a == "--no-depth") {
      depth = false;
    } else if (!a.empty() && a[0] == '-') {
      return usage_error("unknown option " + a);
    } else if (positional++ == 0) {
      dataset = a;
    } else {
      return usage_error("unexpected argument " + a);
    }
  }
  if (dataset.empty()) return usage_error("no dataset folder given");
  if (out.empty()) return usage_error("--out is required");

  // Everything that can fail is checked before the long part.
  std::string error;
  dqo::system::ObjectPipelineParams params;
  if (!config.empty()) {
    const auto loaded = dqo::objects::load_object_params(config, &error);
    if (!loaded) {
      std::fprintf(stderr, "dqo_objects: %s\n", error.c_str());
      return 1;
    }
    params.mapper = *loaded;
  }
  if (!strategy.empty() &&
      !dqo::objects::parse_association_strategy(strategy, &params.mapper.association.strategy)) {
    return usage_error("--strategy must be iou, qd or iou+qd, not '" + strategy + "'");
  }
  params.use_depth = depth;
  params.max_frames = frames;
  params.anchor_to_ground_truth = anchor;
  // A tracker's own frame (the first camera's) has no known up: boxes turn freely there.
  if (poses != "gt" && !anchor) params.mapper.box_fit.upright = false;
  const std::filesystem::path out_dir = std::filesystem::absolute(out).parent_path();
  if (!std::filesystem::is_directory(out_dir)) {
    std::fprintf(stderr, "dqo_objects: the folder of --out (%s) does not exist\n", out_dir.c_str());
    return 1;
  }
  std::optional<dqo::Trajectory> trajectory;
  if (poses != "gt") {
    trajectory = dqo::read_tum_trajectory(poses, &error);
    if (!trajectory) {
      std::fprintf(stderr, "dqo_objects: %s\n", error.c_str());
      return 1;
    }
    if (trajectory->empty()) {
      std::fprintf(stderr, "dqo_objects: %s holds no poses\n", poses.c_str());
      return 1;
    }
  }
  dqo::DatasetReaderParams reader_params;
  reader_params.load_meshes = false;
  const std::shared_ptr<const dqo::DatasetReader> reader =
      dqo::open_dataset(dataset, reader_params, &error);
  if (!reader) {
    std::fprintf(stderr, "dqo_objects: %s\n", error.c_str());
    return 1;
  }
  // Lens distortion comes off first (images, masks and boxes), as the ROS path does it.
  const std::shared_ptr<const dqo::FrameSource> source = dqo::tracking::rectified(reader, &error);
  if (!source) {
    std::fprintf(stderr, "dqo_objects: %s\n", error.c_str());
    return 1;
  }
  const int total = frames > 0 ? std::min(frames, reader->num_frames()) : reader->num_frames();
  if (total < 1) {
    std::fprintf(stderr, "dqo_objects: %s holds no frames\n", dataset.c_str());
    return 1;
  }
  std::fprintf(stderr, "dqo_objects: %s dataset %s, %d frames, poses %s, strategy %s\n",
               reader->format().c_str(), dataset.c_str(), total, poses.c_str(),
               dqo::objects::to_string(params.mapper.association.strategy));

  dqo::ProgressBar bar("objects", total);
  const dqo::system::ObjectPipelineResult r = dqo::system::run_object_pipeline(
      *source, params, trajectory ? &*trajectory : nullptr, [&bar](int done, int) { bar.update(done); });
  if (!r.ok) std::fprintf(stderr, "\ndqo_objects: stopped: %s\n", r.error.c_str());
  if (r.keyframes == 0) {
    std::fprintf(stderr, "dqo_objects: no keyframe had a pose (%d frames without one)\n", r.frames_without_pose);
    return 1;
  }
  if (r.detections == 0) {
    std::fprintf(stderr, "dqo_objects: warning: the dataset's keyframes hold no detections\n");
  }
  if (trajectory && anchor && !r.anchored) {
    std::fprintf(stderr, "dqo_objects: note: no ground truth to anchor the trajectory to; objects are "
                         "in the trajectory's frame\n");
  }

  std::vector<dqo::ObjectListEntry> entries;
  for (const auto& o : r.objects) {
    // The fitted box where there is one (its inscribed ellipsoid: semi-axes = half extents, the
    // reading of METHOD.md §6), else the mapped ellipsoid.
    const dqo::OrientedBox box = o.has_box ? o.box : dqo::box_from_quadric(o.quadric);
    entries.push_back(dqo::make_object_list_entry(o.id, o.class_id, box));
  }
  if (!dqo::write_object_list(out, entries, &error)) {
    std::fprintf(stderr, "dqo_objects: %s\n", error.c_str());
    return 1;
  }
  int created = 0, merged = 0, removed = 0, renamed = 0;
  for (const auto& e : r.events) {
    created += e.type == dqo::objects::ObjectEvent::Type::kCreated;
    merged += e.type == dqo::objects::ObjectEvent::Type::kMerged;
    removed += e.type == dqo::objects::ObjectEvent::Type::kRemoved;
    renamed += e.type == dqo::objects::ObjectEvent::Type::kRenamed;
  }
  std::printf("frames: %d (without pose %d), keyframes: %d\n", r.frames, r.frames_without_pose, r.keyframes);
  std::printf("detections: %d (rejected %d)\n", r.detections, r.rejected_detections);
  std::printf("events: %d created, %d merged, %d removed, %d renamed\n", created, merged, removed, renamed);
  std::printf("association_ms_median: %.3f (max %.3f)\n", median(r.association_ms),
              r.association_ms.empty() ? 0.0 : *std::max_element(r.association_ms.begin(), r.association_ms.end()));
  std::printf("refinement_ms_per_object_median: %.3f (%zu runs)\n", median(r.refinement_ms), r.refinement_ms.size());
  std::printf("wrote: %s\n", out.c_str());
  std::printf("objects: %zu\n", r.objects.size());
  return r.ok ? 0 : 1;
}
