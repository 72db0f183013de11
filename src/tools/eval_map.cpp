// dqo_eval_map: a saved map (the mapping nodelet's save_map / autosave, or dqo_map_offline's
// map.dqomap) and its extracted meshes against a dataset's ground truth — how scripts/demo scores
// a ROS run. The map's frame is the tracker's; it is moved rigidly onto the ground truth at the
// first keyframe that has a ground-truth pose (the drift after it still counts), then the objects
// (3D IoU, CDE), the keyframe trajectory (ATE) and each object's mesh (Accuracy, Completion,
// Completion ratios) are evaluated as dqo_map_offline evaluates its own runs. Prints one line per
// object of the map, then the paper-style reconstruction table.
//
//   dqo_eval_map MAP.dqomap DATASET_DIR [--meshes DIR] [--stamp-offset S] [--json FILE]

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "dqo_map/common/atomic_file.h"
#include "dqo_map/common/tum_trajectory.h"
#include "dqo_map/io/dataset_reader.h"
#include "dqo_map/io/mesh_io.h"
#include "dqo_map/io/trajectory_io.h"
#include "dqo_map/mapping/map_file.h"
#include "dqo_map/mesh/object_recon.h"
#include "dqo_map/system/offline_metrics.h"

namespace {

namespace fs = std::filesystem;

constexpr char kUsage[] =
    "usage: dqo_eval_map MAP.dqomap DATASET_DIR [--meshes DIR] [--stamp-offset S] [--json FILE]\n"
    "  MAP.dqomap        a map file (save_map, the autosave, dqo_map_offline's map.dqomap)\n"
    "  DATASET_DIR       the dataset the map was made of (groundtruth.txt, objects_gt.txt, meshes_gt/)\n"
    "  --meshes DIR      where object_<id>_mesh.ply are (extract_object's folder); default: beside the map\n"
    "  --stamp-offset S  keyframe stamp − dataset timestamp (a bag from dqo_make_scene: 1000; default 0)\n"
    "  --json FILE       also write the metrics as JSON (dqo_map_offline's metrics.json layout)\n";

int fail(const std::string& message) {
  std::fprintf(stderr, "dqo_eval_map: %s\n", message.c_str());
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> positional;
  std::string meshes_dir, json_path;
  double offset = 0.0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "-h" || a == "--help") {
      std::fputs(kUsage, stdout);
      return 0;
    }
    if (a == "--meshes" || a == "--stamp-offset" || a == "--json") {
      if (i + 1 >= argc) return fail(a + " needs a value\n" + kUsage);
      const std::string v = argv[++i];
      if (a == "--meshes") meshes_dir = v;
      if (a == "--json") json_path = v;
      if (a == "--stamp-offset") {
        char* end = nullptr;
        offset = std::strtod(v.c_str(), &end);
        if (end == v.c_str() || *end != '\0' || !std::isfinite(offset)) return fail("--stamp-offset takes seconds, not '" + v + "'");
      }
    } else if (!a.empty() && a[0] == '-') {
      return fail("unknown option " + a + "\n" + kUsage);
    } else {
      positional.push_back(a);
    }
  }
  if (positional.size() != 2) return fail(std::string("needs a map file and a dataset folder\n") + kUsage);
  const std::string map_path = positional[0], dataset_dir = positional[1];
  if (meshes_dir.empty()) meshes_dir = fs::path(map_path).parent_path().string();

  std::string error;
  auto map = dqo::mapping::load_map_file(map_path, &error);
  if (!map) return fail(error);
  auto dataset = dqo::open_dataset(dataset_dir, &error);
  if (!dataset) return fail(error);
  const dqo::DatasetInfo& info = dataset->info();
  const fs::path gt_path = fs::path(dataset_dir) / "groundtruth.txt";
  std::optional<dqo::Trajectory> gt;
  if (fs::exists(gt_path)) {
    gt = dqo::read_tum_trajectory(gt_path.string(), &error);
    if (!gt) return fail(error);
  }
  if (!gt || map->keyframes.empty()) return fail("needs ground-truth poses (groundtruth.txt) and a map with keyframes");

  // The anchor: the first keyframe (by time) with a ground-truth pose.
  std::vector<dqo::mapping::KeyframePose> keyframes = map->keyframes;
  std::sort(keyframes.begin(), keyframes.end(), [](const auto& a, const auto& b) { return a.stamp < b.stamp; });
  std::optional<dqo::SE3> T_gt_map;
  dqo::system::OfflineResult run;
  for (const auto& k : keyframes) {
    const auto T = dqo::pose_at(*gt, k.stamp - offset);
    if (!T) continue;
    if (!T_gt_map) T_gt_map = *T * k.T_wc.inverse();
    run.trajectory.emplace_back(k.stamp - offset, *T_gt_map * k.T_wc);
    run.ground_truth.emplace_back(k.stamp - offset, *T);
  }
  if (!T_gt_map) {
    return fail("no keyframe stamp (minus --stamp-offset " + std::to_string(offset) +
                " s) has a ground-truth pose: is the offset right? (a dqo_make_scene bag starts at 1000 s)");
  }
  std::vector<dqo::mapping::KeyframePose> views = keyframes;
  for (auto& v : views) v.T_wc = *T_gt_map * v.T_wc;
  std::vector<dqo::mapping::ObjectRecord> objects = map->objects;
  for (auto& o : objects) {
    o.quadric = o.quadric.transformed(*T_gt_map);
    o.box.centre = *T_gt_map * o.box.centre;
    o.box.rotation = T_gt_map->rotation() * o.box.rotation;
  }
  std::map<uint64_t, size_t> gaussians;
  for (uint32_t id : map->gaussians.object_ids_per_gaussian()) ++gaussians[id];
  std::map<uint64_t, std::string> mesh_paths;
  for (const auto& o : map->objects) {
    const fs::path p = fs::path(meshes_dir) / ("object_" + std::to_string(o.id) + "_mesh.ply");
    if (fs::exists(p)) mesh_paths[o.id] = fs::absolute(p).string();
  }
  const auto metrics = dqo::system::evaluate_offline_run(
      run, objects, views, info, [&](uint64_t id) -> std::optional<dqo::TriangleMesh> {
        const auto it = mesh_paths.find(id);
        if (it == mesh_paths.end()) return std::nullopt;
        auto mesh = dqo::load_mesh(it->second);
        if (mesh) {
          for (auto& v : mesh->vertices) v = *T_gt_map * v;
        }
        return mesh;
      });

  // One line per object of the map, in the map's frame, with its ground truth's figures.
  std::map<uint64_t, const dqo::eval::ObjectMatch*> match_of;
  if (metrics.objects) {
    for (const auto& m : metrics.objects->matches) match_of[m.est_id] = &m;
  }
  std::map<uint64_t, const dqo::mesh::ObjectReconRow*> recon_of;
  if (metrics.recon) {
    for (const auto& r : metrics.recon->rows) {
      if (r.est_id != 0) recon_of[r.est_id] = &r;
    }
  }
  std::printf("%4s %-12s %-24s %-20s %9s %5s %6s %7s %7s %8s  %s\n", "ID", "class", "centre (m, map)",
              "semi-axes (m)", "Gaussians", "GT", "IoU3D", "CDE cm", "Acc cm", "Comp<1cm", "mesh");
  for (const auto& o : map->objects) {
    const Eigen::Vector3d c = o.quadric.centre(), a = o.quadric.semi_axes();
    char centre[64], axes[64];
    std::snprintf(centre, sizeof centre, "%.3f %.3f %.3f", c.x(), c.y(), c.z());
    std::snprintf(axes, sizeof axes, "%.3f %.3f %.3f", a.x(), a.y(), a.z());
    const auto m = match_of.find(o.id);
    const auto r = recon_of.find(o.id);
    char gt_id[16] = "-", iou[16] = "-", cde[16] = "-", acc[16] = "-", comp[16] = "-";
    if (m != match_of.end()) {
      std::snprintf(gt_id, sizeof gt_id, "%llu", static_cast<unsigned long long>(m->second->gt_id));
      std::snprintf(iou, sizeof iou, "%.3f", m->second->iou_3d);
      std::snprintf(cde, sizeof cde, "%.1f", 100.0 * m->second->centre_distance);
    }
    if (r != recon_of.end() && r->second->has_mesh) {
      std::snprintf(acc, sizeof acc, "%.2f", r->second->metrics.accuracy_cm);
      std::snprintf(comp, sizeof comp, "%.1f %%", r->second->metrics.comp_ratio_1cm);
    }
    const auto mp = mesh_paths.find(o.id);
    std::printf("%4llu %-12s %-24s %-20s %9zu %5s %6s %7s %7s %8s  %s\n", static_cast<unsigned long long>(o.id),
                o.class_name.c_str(), centre, axes, gaussians[o.id], gt_id, iou, cde, acc, comp,
                mp == mesh_paths.end() ? "(no mesh)" : mp->second.c_str());
  }
  std::printf("background: %zu Gaussians; %zu keyframes\n", gaussians[0], map->keyframes.size());
  if (metrics.ate) std::printf("keyframe ATE RMSE: %.2f cm over %d keyframes\n", 100 * metrics.ate->rmse_m, metrics.ate->matched);
  if (metrics.objects) {
    std::printf("objects: %d of %d found, %d spurious; mean 3D IoU %.3f, CDE %.1f cm\n", metrics.objects->num_matched,
                metrics.objects->num_gt, metrics.objects->num_spurious, metrics.objects->mean_iou_3d,
                100 * metrics.objects->mean_cde);
  }
  if (metrics.recon) std::printf("\n%s", dqo::mesh::format_recon_table(*metrics.recon).c_str());
  for (const std::string& n : metrics.notes) std::printf("note: %s\n", n.c_str());
  if (!json_path.empty() && !dqo::write_file_atomically(json_path, dqo::system::metrics_json(metrics), &error)) {
    return fail(error);
  }
  return 0;
}
