// dqo_eval_recon: reconstruction metrics of one mesh against a ground-truth mesh (METHOD.md §6):
// Accuracy and Completion (cm) and the completion ratios < 1 cm and < 5 cm, from points sampled
// uniformly by area on both surfaces, the reconstruction optionally cropped to a ground-truth box
// enlarged by 1/0.9 (vMAP's protocol). The last line is `comp_ratio_1cm: X` (percent), for scripts.
//
//   dqo_eval_recon MESH.ply GT_MESH.ply [--crop-box objects_gt.txt:ID] [--samples N] [--seed S]
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "dqo_map/common/object_list.h"
#include "dqo_map/io/mesh_io.h"
#include "dqo_map/mesh/recon_metrics.h"
#include "recon_options.h"

namespace {

constexpr char kUsage[] =
    "usage: dqo_eval_recon MESH.ply GT_MESH.ply [--crop-box objects_gt.txt:ID] [--samples N]\n"
    "                      [--seed S]\n"
    "  MESH.ply        the reconstruction (PLY or OBJ)\n"
    "  GT_MESH.ply     the ground-truth mesh\n"
    "  --crop-box F:ID sample the reconstruction only inside the box of object ID in F\n"
    "                  (`id class cx cy cz qx qy qz qw hx hy hz`, half extents), enlarged by 1/0.9\n"
    "  --samples N     points sampled on each surface (default 10000, as vMAP)\n"
    "  --seed S        seed of the samplers (default 1)\n"
    "Prints Accuracy and Completion (cm), the completion ratios < 1 cm and < 5 cm, and\n"
    "`comp_ratio_1cm: X` (percent) last.\n";

int usage_error(const std::string& message) {
  std::fprintf(stderr, "dqo_eval_recon: %s\n%s", message.c_str(), kUsage);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::string files[2];
  int positional = 0;
  std::string crop_spec;
  dqo::mesh::ReconParams params;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has_value = i + 1 < argc;
    if (a == "-h" || a == "--help") {
      std::fputs(kUsage, stdout);
      return 0;
    } else if (a == "--crop-box") {
      if (!has_value) return usage_error("--crop-box takes objects_gt.txt:ID");
      crop_spec = argv[++i];
    } else if (std::string bad; dqo::tools::parse_recon_option(argc, argv, &i, &params, &bad)) {
      if (!bad.empty()) return usage_error(bad);
    } else if (!a.empty() && a[0] == '-') {
      return usage_error("unknown option " + a);
    } else if (positional < 2) {
      files[positional++] = a;
    } else {
      return usage_error("unexpected argument " + a);
    }
  }
  if (positional != 2) return usage_error("expected MESH.ply and GT_MESH.ply");

  std::string error;
  if (!crop_spec.empty()) {
    // The ID follows the last ':' so that paths with colons still work.
    const size_t colon = crop_spec.rfind(':');
    unsigned long long id = 0;
    if (colon == std::string::npos || colon == 0 ||
        !dqo::tools::parse_u64(crop_spec.c_str() + colon + 1, &id) || id == 0) {
      return usage_error("--crop-box takes objects_gt.txt:ID with an ID >= 1");
    }
    const std::string path = crop_spec.substr(0, colon);
    const auto objects = dqo::read_object_list(path, &error);
    if (!objects) {
      std::fprintf(stderr, "dqo_eval_recon: crop box: %s\n", error.c_str());
      return 1;
    }
    for (const dqo::ObjectListEntry& e : *objects) {
      if (e.id == id) params.crop_box = dqo::to_oriented_box(e);
    }
    if (!params.crop_box) {
      std::fprintf(stderr, "dqo_eval_recon: %s: no object with ID %llu\n", path.c_str(), id);
      return 1;
    }
  }

  const auto rec = dqo::load_mesh(files[0], &error);
  if (!rec) {
    std::fprintf(stderr, "dqo_eval_recon: reconstruction: %s\n", error.c_str());
    return 1;
  }
  const auto gt = dqo::load_mesh(files[1], &error);
  if (!gt) {
    std::fprintf(stderr, "dqo_eval_recon: ground truth: %s\n", error.c_str());
    return 1;
  }
  const auto m = dqo::mesh::evaluate_reconstruction(*rec, *gt, params, &error);
  if (!m) {
    std::fprintf(stderr, "dqo_eval_recon: %s\n", error.c_str());
    return 1;
  }
  std::printf("reconstruction: %s (%zu triangles, %d points%s)\n", files[0].c_str(),
              rec->triangles.size(), m->rec_points,
              params.crop_box ? ", cropped to the ground-truth box / 0.9" : "");
  std::printf("ground truth:   %s (%zu triangles, %d points)\n", files[1].c_str(),
              gt->triangles.size(), m->gt_points);
  std::printf("accuracy_cm: %.4f\n", m->accuracy_cm);
  std::printf("completion_cm: %.4f\n", m->completion_cm);
  std::printf("comp_ratio_5cm: %.2f\n", m->comp_ratio_5cm);
  std::printf("comp_ratio_1cm: %.2f\n", m->comp_ratio_1cm);
  return 0;
}
