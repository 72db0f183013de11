// dqo_eval_objects: object pose metrics of an object list against ground truth (METHOD.md §6).
// Both files hold one object per line, `id class tx ty tz qx qy qz qw a1 a2 a3` (semi-axes for the
// estimate, half extents for the ground truth's boxes: the same box either way). Objects are
// matched one-to-one by class and centre distance; then 3D IoU (exact oriented boxes), CDE, and
// with --dataset the 2D IoU of the projected boxes in the dataset's frames. The last line is
// `mean_iou3d: X` (over ground-truth objects, unmatched ones counting 0), for scripts.
//
//   dqo_eval_objects objects.txt objects_gt.txt [--dataset DIR] [--stride K] [--iou2d MODE]
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include "dqo_map/common/object_list.h"
#include "dqo_map/eval/object_metrics.h"
#ifdef DQO_WITH_DATASET
#include "dqo_map/io/dataset_reader.h"
#endif

namespace {

constexpr char kUsage[] =
    "usage: dqo_eval_objects objects.txt objects_gt.txt [--dataset DIR] [--stride K]\n"
    "                        [--iou2d boxes|ellipsoids]\n"
    "  objects.txt     estimated objects: `id class tx ty tz qx qy qz qw a1 a2 a3` (semi-axes)\n"
    "  objects_gt.txt  ground truth, same columns with box half extents\n"
    "  --dataset DIR   also the 2D IoU of the projected boxes in the dataset's posed frames\n"
    "  --stride K      use every K-th frame of the dataset (default 10; frames are read whole)\n"
    "  --iou2d MODE    project both objects as boxes (8 corners, default) or as the ellipsoids\n"
    "                  inscribed in them (bounding box of the projected conic)\n"
    "A pair matches when the classes agree and the centres lie within half the ground-truth box's\n"
    "largest extent; the matching maximises the matches, then minimises total centre distance.\n"
    "Prints one line per match, matched / ground truth, spurious, mean 2D IoU, CDE and\n"
    "`mean_iou3d: X` last (over ground-truth objects: unmatched ones count 0).\n";

int usage_error(const std::string& message) {
  std::fprintf(stderr, "dqo_eval_objects: %s\n%s", message.c_str(), kUsage);
  return 2;
}

std::vector<dqo::eval::ObjectEstimate> to_estimates(
    const std::vector<dqo::ObjectListEntry>& entries) {
  std::vector<dqo::eval::ObjectEstimate> out;
  for (const dqo::ObjectListEntry& e : entries) {
    out.push_back({e.id, e.class_id, dqo::to_oriented_box(e)});
  }
  return out;
}

std::string ids_text(const std::vector<uint64_t>& ids) {
  std::string s;
  for (const uint64_t id : ids) s += ' ' + std::to_string(id);
  return s.empty() ? " none" : s;
}

}  // namespace

int main(int argc, char** argv) {
  std::string files[2];
  int positional = 0;
  std::string dataset_dir;
  int stride = 10;
  dqo::eval::ObjectEvalParams params;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has_value = i + 1 < argc;
    if (a == "-h" || a == "--help") {
      std::fputs(kUsage, stdout);
      return 0;
    } else if (a == "--dataset") {
      if (!has_value) return usage_error("--dataset takes a folder");
      dataset_dir = argv[++i];
    } else if (a == "--stride") {
      char* end = nullptr;
      const long v = has_value ? std::strtol(argv[i + 1], &end, 10) : 0;
      if (!has_value || end == argv[i + 1] || *end != '\0' || v < 1 || v > 1000000) {
        return usage_error("--stride takes an integer >= 1");
      }
      stride = static_cast<int>(v);
      ++i;
    } else if (a == "--iou2d") {
      const std::string mode = has_value ? argv[++i] : "";
      if (mode == "boxes") {
        params.projection = dqo::eval::Projection2d::kBoxes;
      } else if (mode == "ellipsoids") {
        params.projection = dqo::eval::Projection2d::kEllipsoids;
      } else {
        return usage_error("--iou2d takes boxes or ellipsoids");
      }
    } else if (!a.empty() && a[0] == '-') {
      return usage_error("unknown option " + a);
    } else if (positional < 2) {
      files[positional++] = a;
    } else {
      return usage_error("unexpected argument " + a);
    }
  }
  if (positional != 2) return usage_error("expected objects.txt and objects_gt.txt");

  std::string error;
  const auto estimated = dqo::read_object_list(files[0], &error);
  if (!estimated) {
    std::fprintf(stderr, "dqo_eval_objects: estimate: %s\n", error.c_str());
    return 2;
  }
  const auto ground_truth = dqo::read_object_list(files[1], &error);
  if (!ground_truth) {
    std::fprintf(stderr, "dqo_eval_objects: ground truth: %s\n", error.c_str());
    return 2;
  }
  if (ground_truth->empty()) {
    std::fprintf(stderr, "dqo_eval_objects: %s: no ground-truth objects\n", files[1].c_str());
    return 2;
  }

  std::vector<dqo::eval::EvalView> views;
  std::map<int, std::string> class_names;
  int frames_total = 0;
  if (!dataset_dir.empty()) {
#ifdef DQO_WITH_DATASET
    dqo::DatasetReaderParams reader_params;
    reader_params.load_meshes = false;  // only the camera and the poses are needed
    const auto reader = dqo::open_dataset(dataset_dir, reader_params, &error);
    if (!reader) {
      std::fprintf(stderr, "dqo_eval_objects: %s\n", error.c_str());
      return 2;
    }
    class_names = reader->info().class_names;
    frames_total = reader->num_frames();
    // The reader's interface reads frames whole (images included), hence the stride.
    for (int k = 0; k < frames_total; k += stride) {
      const auto frame = reader->read_frame(k, &error);
      if (!frame) {
        std::fprintf(stderr, "dqo_eval_objects: %s\n", error.c_str());
        return 2;
      }
      if (frame->has_pose) views.push_back({reader->info().camera, frame->T_wc});
    }
    if (views.empty()) {
      std::fprintf(stderr, "dqo_eval_objects: %s: no frame with a pose; 2D IoU needs poses\n",
                   dataset_dir.c_str());
      return 2;
    }
#else
    return usage_error("--dataset: this build has no dataset reader (io/ library)");
#endif
  }

  const dqo::eval::ObjectMetrics m = dqo::eval::evaluate_objects(
      to_estimates(*estimated), to_estimates(*ground_truth), views, params);

  std::printf("# est_id gt_id class iou3d iou2d cde_cm%s\n", views.empty() ? "" : " views");
  for (const dqo::eval::ObjectMatch& match : m.matches) {
    const auto name = class_names.find(match.class_id);
    const std::string cls = std::to_string(match.class_id) +
                            (name == class_names.end() ? "" : "(" + name->second + ")");
    std::printf("%llu %llu %s %.4f ", static_cast<unsigned long long>(match.est_id),
                static_cast<unsigned long long>(match.gt_id), cls.c_str(), match.iou_3d);
    if (views.empty() || match.views_2d == 0) {
      std::printf("- ");
    } else {
      std::printf("%.4f ", match.iou_2d);
    }
    std::printf("%.2f", 100.0 * match.centre_distance);
    if (!views.empty()) std::printf(" %d", match.views_2d);
    std::printf("\n");
  }
  std::printf("unmatched_gt:%s\n", ids_text(m.unmatched_gt).c_str());
  std::printf("spurious_ids:%s\n", ids_text(m.spurious).c_str());
  std::printf("matched: %d / %d ground truth\n", m.num_matched, m.num_gt);
  std::printf("spurious: %d of %zu estimated\n", m.num_spurious, estimated->size());
  if (!views.empty()) {
    std::printf("views: %zu of %d frames (stride %d)\n", views.size(), frames_total, stride);
    if (std::isnan(m.mean_iou_2d)) {
      std::printf("mean_iou2d: nan (no ground-truth object in view)\n");
    } else {
      std::printf("mean_iou2d: %.4f (%s, over %d ground-truth objects in view)\n", m.mean_iou_2d,
                  params.projection == dqo::eval::Projection2d::kBoxes ? "boxes" : "ellipsoids",
                  m.num_gt_in_views);
    }
  }
  if (m.num_matched > 0) {
    std::printf("mean_cde_cm: %.3f\n", 100.0 * m.mean_cde);
    std::printf("mean_cde_m: %.6f\n", m.mean_cde);
    std::printf("mean_iou3d_matched: %.4f\n", m.mean_iou_3d_matched);
  } else {
    std::printf("mean_cde_cm: nan (no match)\n");
  }
  std::printf("mean_iou3d: %.4f\n", m.mean_iou_3d);
  return 0;
}
