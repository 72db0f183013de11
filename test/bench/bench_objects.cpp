// bench_objects: the object stage (issue 5) on the shipped scenes and on a synthetic 50-object
// keyframe.
//
// 1. Accuracy: for each scene dataset folder DATA/<scene> (rendered once with
//      dqo_make_scene config/scenes/<scene>.yaml DATA/<scene>
//    so that every run reads the same frames and detections) and each association strategy,
//    runs dqo::system::run_object_pipeline (the code path of dqo_objects) with the ground-truth
//    poses, or with tracked poses from POSES/<scene>.txt (dqo_track's output, anchored to the
//    ground truth at the first frame), and evaluates with dqo::eval::evaluate_objects:
//    matched / ground truth, spurious, mean 3D IoU (over the ground truth), mean 2D IoU, CDE.
// 2. Speed: one keyframe with 50 objects in the map and 50 detections, association alone (filter,
//    visibility, coarse and fine association, merge, initialisation; refinement excluded), median
//    over keyframes; and the refinement's time per object from the scene runs.
//
//   bench_objects --data DIR [--scenes a,b,...] [--strategies iou,qd,iou+qd] [--poses-dir DIR]
//                 [--config objects.yaml] [--no-timing] [--timing-only] [--verbose]
//                 [--trace GT_ID,...]
// --trace: for each keyframe, the detections of those ground-truth objects (the simulated
// detector's gt_id), what became of each (verdict, object ID) and the events of those objects:
// where an object is lost, absorbed or never confirmed, and why.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <cstdio>
#include <filesystem>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "dqo_map/common/tum_trajectory.h"
#include "dqo_map/eval/object_metrics.h"
#include "dqo_map/geometry/conic.h"
#include "dqo_map/io/dataset_reader.h"
#include "dqo_map/objects/object_mapper.h"
#include "dqo_map/objects/params_yaml.h"
#include "dqo_map/system/object_pipeline.h"

namespace {

using dqo::objects::AssociationStrategy;

struct Options {
  std::string data;
  std::vector<std::string> scenes = {"tabletop", "tabletop_plain", "room", "occlusion", "tiny"};
  std::vector<std::string> strategies = {"iou", "qd", "iou+qd"};
  std::string poses_dir;
  std::string config;
  bool timing = true;
  bool accuracy = true;
  bool verbose = false;
  std::vector<uint32_t> trace;  // ground-truth IDs whose detections are followed keyframe by keyframe
};

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream in(s);
  std::string item;
  while (std::getline(in, item, ',')) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

double median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  return v[static_cast<size_t>(q * static_cast<double>(v.size() - 1))];
}

// CPU time of the calling thread: a loaded machine (other builds) does not inflate it.
double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}

// One scene with one strategy: returns false when the dataset cannot be read.
bool run_scene(const Options& o, const std::string& scene, const std::string& strategy,
               const dqo::objects::ObjectMapperParams& base, std::vector<double>* refinement_ms) {
  const std::string dir = o.data + "/" + scene;
  std::string error;
  dqo::DatasetReaderParams reader_params;
  reader_params.load_meshes = false;
  const auto reader = dqo::open_dataset(dir, reader_params, &error);
  if (!reader) {
    std::printf("| %s | %s | cannot read: %s (render it: dqo_make_scene config/scenes/%s.yaml %s) |\n",
                scene.c_str(), strategy.c_str(), error.c_str(), scene.c_str(), dir.c_str());
    return false;
  }
  dqo::system::ObjectPipelineParams params;
  params.mapper = base;
  dqo::objects::parse_association_strategy(strategy, &params.mapper.association.strategy);
  std::optional<dqo::Trajectory> trajectory;
  if (!o.poses_dir.empty()) {
    trajectory = dqo::read_tum_trajectory(o.poses_dir + "/" + scene + ".txt", &error);
    if (!trajectory) {
      std::printf("| %s | %s | no trajectory: %s |\n", scene.c_str(), strategy.c_str(), error.c_str());
      return false;
    }
    params.anchor_to_ground_truth = true;
  }
  if (!o.trace.empty()) {
    params.on_keyframe = [&o](const dqo::objects::ObjectKeyFrame& kf,
                              const dqo::objects::KeyFrameAssociation& r,
                              const dqo::objects::ObjectMapper& mapper) {
      std::vector<dqo::objects::ObjectId> followed;
      for (size_t d = 0; d < kf.detections.size(); ++d) {
        const dqo::Detection2d& det = kf.detections[d];
        if (std::find(o.trace.begin(), o.trace.end(), det.gt_id) == o.trace.end()) continue;
        const dqo::objects::ObjectId id = d < r.object_ids.size() ? r.object_ids[d] : 0;
        const dqo::objects::MapObject* obj = id ? mapper.find(id) : nullptr;
        std::printf("  trace kf %u gt %u class %d score %.2f box [%.0f %.0f %.0f %.0f] -> %s object %u%s",
                    static_cast<unsigned>(kf.id), det.gt_id, det.class_id, det.score, det.box.x_min,
                    det.box.y_min, det.box.x_max, det.box.y_max, dqo::objects::to_string(r.verdicts[d]),
                    static_cast<unsigned>(id), obj ? (obj->state == dqo::objects::ObjectState::kConfirmed ? " (confirmed" : " (candidate") : "");
        if (obj) {
          const Eigen::Vector3d c = obj->quadric.centre();
          std::printf(", P %.3f, centre %.2f %.2f %.2f, class %d)", dqo::objects::existence_probability(*obj), c.x(),
                      c.y(), c.z(), obj->class_id);
        }
        std::printf("\n");
        if (id) followed.push_back(id);
      }
      for (const auto& e : r.events) {
        const bool mine = std::find(followed.begin(), followed.end(), e.id) != followed.end() ||
                          std::find(followed.begin(), followed.end(), e.into_id) != followed.end();
        if (!mine) continue;
        static const char* kNames[] = {"created", "merged", "removed", "renamed"};
        std::printf("  trace kf %u event %s %u%s\n", static_cast<unsigned>(kf.id),
                    kNames[static_cast<int>(e.type)], static_cast<unsigned>(e.id),
                    e.type == dqo::objects::ObjectEvent::Type::kMerged
                        ? (" into " + std::to_string(e.into_id)).c_str() : "");
      }
    };
  }
  const dqo::system::ObjectPipelineResult r =
      dqo::system::run_object_pipeline(*reader, params, trajectory ? &*trajectory : nullptr);
  if (!r.ok) std::fprintf(stderr, "bench_objects: %s: %s\n", scene.c_str(), r.error.c_str());

  std::vector<dqo::eval::ObjectEstimate> est, gt;
  for (const auto& obj : r.objects) {
    est.push_back({obj.id, obj.class_id, obj.has_box ? obj.box : dqo::box_from_quadric(obj.quadric)});
  }
  for (const auto& g : reader->info().objects) gt.push_back({g.id, g.class_id, g.box});
  std::vector<dqo::eval::EvalView> views;
  for (const dqo::SE3& T : r.keyframe_T_wc) views.push_back({r.camera, T});
  const dqo::eval::ObjectMetrics m = dqo::eval::evaluate_objects(est, gt, views);
  int created = 0, merged = 0, removed = 0;
  for (const auto& e : r.events) {
    created += e.type == dqo::objects::ObjectEvent::Type::kCreated;
    merged += e.type == dqo::objects::ObjectEvent::Type::kMerged;
    removed += e.type == dqo::objects::ObjectEvent::Type::kRemoved;
  }
  std::printf("| %s | %s | %d / %d | %d | %.3f | %.3f | %.2f | %d | %d/%d/%d | %.2f | %.2f | %.1f |\n",
              scene.c_str(), strategy.c_str(), m.num_matched, m.num_gt, m.num_spurious, m.mean_iou_3d,
              m.mean_iou_2d, 100.0 * m.mean_cde, r.keyframes, created, merged, removed,
              median(r.association_ms), median(r.refinement_ms), r.seconds);
  std::fflush(stdout);
  if (o.verbose) {
    // Each box as its centre and the half extents of its world-axis-aligned bounds: where a box
    // is off (too thick, too tall, shifted) reads at a glance.
    auto box_text = [](const std::vector<dqo::eval::ObjectEstimate>& list, uint64_t id) {
      for (const auto& e : list) {
        if (e.id != id) continue;
        const Eigen::Vector3d h = e.box.rotation.cwiseAbs() * e.box.half_extents;
        char text[160];
        std::snprintf(text, sizeof text, "c %.2f %.2f %.2f h %.2f %.2f %.2f", e.box.centre.x(),
                      e.box.centre.y(), e.box.centre.z(), h.x(), h.y(), h.z());
        return std::string(text);
      }
      return std::string("?");
    };
    for (const auto& match : m.matches) {
      std::printf("    gt %llu est %llu class %d iou3d %.3f iou2d %.3f cde %.2f cm | est %s | gt %s\n",
                  static_cast<unsigned long long>(match.gt_id), static_cast<unsigned long long>(match.est_id),
                  match.class_id, match.iou_3d, match.iou_2d, 100.0 * match.centre_distance,
                  box_text(est, match.est_id).c_str(), box_text(gt, match.gt_id).c_str());
    }
    for (const auto id : m.unmatched_gt) std::printf("    unmatched gt %llu\n", static_cast<unsigned long long>(id));
    for (const auto id : m.spurious) {
      int cls = -1;
      for (const auto& e : est) cls = e.id == id ? e.class_id : cls;
      std::printf("    spurious est %llu class %d | est %s\n", static_cast<unsigned long long>(id), cls,
                  box_text(est, id).c_str());
    }
  }
  refinement_ms->insert(refinement_ms->end(), r.refinement_ms.begin(), r.refinement_ms.end());
  return true;
}

// 50 ellipsoids on a 10 x 5 grid, seen by a camera sliding past: build the map from a few
// keyframes, then time the next ones. `depth`: keyframes carry a depth image (a wall 0.3 m behind
// the grid), so the depth steps run too (depth ellipsoids, surface samples, stand-out, the misses'
// depth evidence); `whole`: refinement, box fit and surface boxes on as well (the whole keyframe).
void run_timing(const dqo::objects::ObjectMapperParams& base, bool depth, bool whole) {
  dqo::PinholeCamera camera;
  camera.width = 1280;
  camera.height = 720;
  camera.fx = camera.fy = 900.0;
  camera.cx = 639.5;
  camera.cy = 359.5;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> angle(-3.14159, 3.14159), size(0.05, 0.09);
  std::vector<dqo::DualQuadric> objects;
  for (int k = 0; k < 50; ++k) {
    const Eigen::Vector3d centre(-1.35 + 0.3 * (k % 10), -0.45 + 0.225 * (k / 10), 0.0);
    const Eigen::Matrix3d R = Eigen::AngleAxisd(angle(rng), Eigen::Vector3d(0.3, 0.5, 1.0).normalized()).toRotationMatrix();
    objects.push_back(dqo::DualQuadric::from_params(centre, R, Eigen::Vector3d(size(rng), size(rng), size(rng))));
  }
  // Camera on a circle of 0.25 m at z = −2.6, looking along +z at the grid.
  auto pose = [](int k) {
    const double x = 0.25 * std::cos(0.25 * k), y = 0.25 * std::sin(0.25 * k);
    const Eigen::Vector3d eye(x, y, -2.6);
    const Eigen::Vector3d z = (Eigen::Vector3d(0.5 * x, 0.5 * y, 0.0) - eye).normalized();
    const Eigen::Vector3d xa = Eigen::Vector3d::UnitY().cross(z).normalized();
    Eigen::Matrix3d Rwc;
    Rwc.col(0) = xa;
    Rwc.col(1) = z.cross(xa);
    Rwc.col(2) = z;
    return dqo::SE3::from_rotation_translation(Rwc, eye);
  };
  dqo::objects::ObjectMapperParams params = base;
  params.refine = whole;          // otherwise timed apart (the scene runs)
  params.box_fit.enabled = whole;  // likewise, so that the thread CPU time is the association's
  dqo::DepthImage wall(camera.width, camera.height, 1, 2.9f);
  std::vector<double> ms, cpu_ms;
  int associated = 0, total = 0;
  dqo::objects::ObjectMapper mapper(params);
  for (int k = 0; k < 60; ++k) {
    dqo::objects::ObjectKeyFrame kf;
    kf.id = static_cast<dqo::objects::KeyFrameId>(k + 1);
    kf.camera = camera;
    kf.T_wc = pose(k);
    if (depth) {
      kf.depth.data = wall.data.data();
      kf.depth.width = wall.width;
      kf.depth.height = wall.height;
    }
    for (const auto& q : objects) {
      const auto p = dqo::projected_box(q, camera, kf.T_wc.inverse(), 0.05);
      if (!p) continue;
      dqo::Detection2d d;
      d.box = p->box;
      d.class_id = 1;
      d.score = 0.9f;
      kf.detections.push_back(d);
    }
    const double cpu0 = thread_cpu_ms();
    const auto r = mapper.process_keyframe(kf);
    const double cpu = thread_cpu_ms() - cpu0;
    if (k >= 10) {
      ms.push_back(r.association_ms + (whole ? r.refinement_ms + r.box_fit_ms : 0.0));
      cpu_ms.push_back(cpu);
      for (const auto v : r.verdicts) {
        associated += v == dqo::objects::DetectionVerdict::kAssociated;
        ++total;
      }
    }
  }
  std::printf("%s, 50 objects x %.0f detections per keyframe (%zu keyframes after 10 to build "
              "the map): wall median %.3f ms, p90 %.3f ms; thread CPU median %.3f ms, p90 %.3f ms; %d of %d "
              "detections associated; %zu objects\n",
              whole ? "whole keyframe (association, refinement, box fit, surface; with depth)"
                    : depth ? "association with depth" : "association",
              static_cast<double>(total) / std::max<size_t>(1, ms.size()), ms.size(), median(ms),
              percentile(ms, 0.9), median(cpu_ms), percentile(cpu_ms, 0.9), associated, total,
              mapper.objects().size());
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "bench_objects: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--data") {
      o.data = value();
    } else if (a == "--scenes") {
      o.scenes = split(value());
    } else if (a == "--strategies") {
      o.strategies = split(value());
    } else if (a == "--poses-dir") {
      o.poses_dir = value();
    } else if (a == "--config") {
      o.config = value();
    } else if (a == "--no-timing") {
      o.timing = false;
    } else if (a == "--timing-only") {
      o.accuracy = false;
    } else if (a == "--verbose") {
      o.verbose = true;
    } else if (a == "--trace") {
      for (const std::string& id : split(value())) o.trace.push_back(static_cast<uint32_t>(std::stoul(id)));
    } else {
      std::fprintf(stderr,
                   "usage: bench_objects --data DIR [--scenes a,b] [--strategies iou,qd,iou+qd] "
                   "[--poses-dir DIR] [--config FILE] [--no-timing] [--timing-only] [--verbose] [--trace GT_ID,...]\n");
      return 2;
    }
  }
  for (const std::string& s : o.strategies) {
    if (!dqo::objects::parse_association_strategy(s, nullptr)) {
      std::fprintf(stderr, "bench_objects: unknown strategy '%s'\n", s.c_str());
      return 2;
    }
  }
  dqo::objects::ObjectMapperParams base;
  if (!o.config.empty()) {
    std::string error;
    const auto loaded = dqo::objects::load_object_params(o.config, &error);
    if (!loaded) {
      std::fprintf(stderr, "bench_objects: %s\n", error.c_str());
      return 1;
    }
    base = *loaded;
  }
  std::vector<double> refinement_ms;
  if (o.accuracy) {
    if (o.data.empty()) {
      std::fprintf(stderr, "bench_objects: --data DIR (scene datasets, see the header) is required\n");
      return 2;
    }
    std::printf("poses: %s\n", o.poses_dir.empty() ? "ground truth" : ("tracked, " + o.poses_dir).c_str());
    std::printf("| scene | strategy | matched / GT | spurious | mean 3D IoU | mean 2D IoU | CDE cm | keyframes | "
                "created/merged/removed | assoc ms p50 | refine ms/object p50 | run s |\n");
    std::printf("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n");
    for (const std::string& scene : o.scenes) {
      for (const std::string& strategy : o.strategies) run_scene(o, scene, strategy, base, &refinement_ms);
    }
    if (!refinement_ms.empty()) {
      std::printf("refinement per object: median %.3f ms, p90 %.3f ms over %zu runs\n", median(refinement_ms),
                  percentile(refinement_ms, 0.9), refinement_ms.size());
    }
  }
  if (o.timing) {
    run_timing(base, false, false);
    run_timing(base, true, false);
    run_timing(base, true, true);
  }
  return 0;
}
