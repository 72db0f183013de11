// dqo_recon_table: the per-object reconstruction table of a finished run (the paper's object
// tables, METHOD.md §6). The run folder holds objects.txt (one object per line,
// `id class tx ty tz qx qy qz qw a1 a2 a3`) and object_<id>_mesh.ply per object, as
// dqo_map_offline writes them; the dataset (own format) holds the ground-truth boxes and meshes.
// Objects are matched one-to-one to ground truth as dqo_eval_objects does; each matched object's
// mesh is evaluated against its ground-truth mesh, cropped to the ground-truth box / 0.9. The last
// line is `comp_ratio_1cm: X`, the mean over objects with a mesh (percent), for scripts.
//
//   dqo_recon_table RUN_DIR DATASET_DIR [--samples N] [--seed S]
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "dqo_map/common/object_list.h"
#include "dqo_map/eval/object_metrics.h"
#include "dqo_map/io/dataset_reader.h"
#include "dqo_map/io/mesh_io.h"
#include "dqo_map/mesh/object_recon.h"
#include "recon_options.h"

namespace {

namespace fs = std::filesystem;

constexpr char kUsage[] =
    "usage: dqo_recon_table RUN_DIR DATASET_DIR [--samples N] [--seed S]\n"
    "  RUN_DIR       a finished run: objects.txt and object_<id>_mesh.ply per object\n"
    "  DATASET_DIR   the dataset it ran on (own format: objects_gt.txt and meshes_gt/)\n"
    "  --samples N   points sampled on each surface (default 10000, as vMAP)\n"
    "  --seed S      seed of the samplers (default 1)\n"
    "Objects are matched to ground truth by class and centre distance (as dqo_eval_objects);\n"
    "each match's mesh is evaluated against the ground-truth mesh inside the ground-truth box\n"
    "enlarged by 1/0.9. Prints one row per ground-truth object, the mean row, and\n"
    "`comp_ratio_1cm: X` (mean over objects with a mesh, percent) last.\n";

int usage_error(const std::string& message) {
  std::fprintf(stderr, "dqo_recon_table: %s\n%s", message.c_str(), kUsage);
  return 2;
}

std::string ids_text(const std::vector<uint64_t>& ids) {
  std::string s;
  for (const uint64_t id : ids) s += ' ' + std::to_string(id);
  return s.empty() ? " none" : s;
}

}  // namespace

int main(int argc, char** argv) {
  std::string dirs[2];
  int positional = 0;
  dqo::mesh::ReconParams params;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "-h" || a == "--help") {
      std::fputs(kUsage, stdout);
      return 0;
    } else if (std::string bad; dqo::tools::parse_recon_option(argc, argv, &i, &params, &bad)) {
      if (!bad.empty()) return usage_error(bad);
    } else if (!a.empty() && a[0] == '-') {
      return usage_error("unknown option " + a);
    } else if (positional < 2) {
      dirs[positional++] = a;
    } else {
      return usage_error("unexpected argument " + a);
    }
  }
  if (positional != 2) return usage_error("expected RUN_DIR and DATASET_DIR");
  const fs::path run_dir(dirs[0]);

  std::string error;
  const auto estimated = dqo::read_object_list((run_dir / "objects.txt").string(), &error);
  if (!estimated) {
    std::fprintf(stderr, "dqo_recon_table: run: %s\n", error.c_str());
    return 1;
  }
  const auto reader = dqo::open_dataset(dirs[1], &error);  // loads the ground-truth meshes
  if (!reader) {
    std::fprintf(stderr, "dqo_recon_table: %s\n", error.c_str());
    return 1;
  }
  const std::vector<dqo::GtObject>& ground_truth = reader->info().objects;
  if (ground_truth.empty()) {
    std::fprintf(stderr,
                 "dqo_recon_table: %s: no ground-truth objects (a %s dataset; object ground truth "
                 "comes with the own format's objects_gt.txt and meshes_gt/)\n",
                 dirs[1].c_str(), reader->format().c_str());
    return 1;
  }

  std::vector<dqo::eval::ObjectEstimate> est, gt;
  for (const dqo::ObjectListEntry& e : *estimated) {
    est.push_back({e.id, e.class_id, dqo::to_oriented_box(e)});
  }
  for (const dqo::GtObject& o : ground_truth) gt.push_back({o.id, o.class_id, o.box});
  const dqo::eval::ObjectMetrics matching = dqo::eval::evaluate_objects(est, gt);
  std::vector<dqo::mesh::ReconMatch> matches;
  for (const dqo::eval::ObjectMatch& m : matching.matches) matches.push_back({m.est_id, m.gt_id});

  // A missing mesh file is "no mesh" in the table; one that does not load is said on stderr too.
  const dqo::mesh::EstimatedMeshFn mesh_of =
      [&](uint64_t id) -> std::optional<dqo::TriangleMesh> {
    const fs::path path = run_dir / ("object_" + std::to_string(id) + "_mesh.ply");
    std::error_code ec;
    if (!fs::exists(path, ec)) return std::nullopt;
    std::string why;
    auto mesh = dqo::load_mesh(path.string(), &why);
    if (!mesh) std::fprintf(stderr, "dqo_recon_table: %s\n", why.c_str());
    return mesh;
  };
  const dqo::mesh::ObjectReconTable table =
      dqo::mesh::evaluate_object_reconstructions(ground_truth, matches, mesh_of, params);

  std::fputs(dqo::mesh::format_recon_table(table).c_str(), stdout);
  std::printf("matched: %d / %d ground truth, %d with a mesh\n", matching.num_matched,
              matching.num_gt, table.num_with_mesh);
  std::printf("spurious_ids:%s\n", ids_text(matching.spurious).c_str());
  if (table.num_with_mesh == 0) {
    std::printf("comp_ratio_1cm: nan (no matched object with a mesh)\n");
    return 0;
  }
  std::printf("accuracy_cm: %.4f\n", table.mean.accuracy_cm);
  std::printf("completion_cm: %.4f\n", table.mean.completion_cm);
  std::printf("comp_ratio_5cm: %.2f\n", table.mean.comp_ratio_5cm);
  std::printf("comp_ratio_1cm: %.2f\n", table.mean.comp_ratio_1cm);
  return 0;
}
