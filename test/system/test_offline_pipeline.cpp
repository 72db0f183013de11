// The offline pipeline end to end on the `tiny` scene rendered in memory, against its ground truth:
// objects (the object stage, the same as system::run_object_pipeline gives), poses (ground truth,
// and a trajectory file in another world frame anchored back onto it), the Gaussian map with its
// object IDs, and per-object meshes against the ground-truth meshes.

#include <gtest/gtest.h>

#include <stdlib.h>

#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <string>

#include "dqo_map/common/tum_trajectory.h"
#include "dqo_map/eval/object_metrics.h"
#include "dqo_map/io/mesh_io.h"
#include "dqo_map/mesh/object_recon.h"
#include "dqo_map/sim/scene_frame_source.h"
#include "dqo_map/sim/scene_loader.h"
#include "dqo_map/gaussians/gaussian_ply.h"
#include "dqo_map/system/object_export.h"
#include "dqo_map/system/object_meshes.h"
#include "dqo_map/system/object_pipeline.h"
#include "dqo_map/system/offline_metrics.h"
#include "dqo_map/system/offline_stages.h"

namespace dqo::system {
namespace {

std::shared_ptr<sim::SceneFrameSource> tiny_source() {
  std::string error;
  auto scene = sim::load_scene(std::string(DQO_SOURCE_DIR) + "/config/scenes/tiny.yaml",
                               &dqo::load_mesh, &error);
  EXPECT_TRUE(scene) << error;
  return std::make_shared<sim::SceneFrameSource>(std::move(*scene), 1.0, false, 2);
}

mapping::GaussianMapperParams mapper_params() {
  mapping::GaussianMapperParams p;
  p.trainer.iterations = 20;
  p.threads = 2;
  return p;
}

struct TinyRun {
  OfflineResult result;
  std::unique_ptr<mapping::GaussianMapper> mapper;
  std::shared_ptr<objects::ObjectMapper> objects;
};

TinyRun run_tiny(const FrameSource& source, OfflineStages stages, LabelSource labels, bool mapping_thread = true) {
  TinyRun run;
  run.mapper = std::make_unique<mapping::GaussianMapper>(mapper_params());
  run.objects = add_object_stage(objects::ObjectMapperParams(), DetectionSource::kDataset, labels,
                                 source.info(), &stages);
  OfflineMappingParams params;
  params.mapping_thread = mapping_thread;
  run.result = run_offline_mapping(source, stages, params, run.mapper.get());
  run.mapper->set_objects(to_object_records(run.objects->objects()));
  return run;
}

const TinyRun& ground_truth_run() {
  static const auto source = tiny_source();
  static const TinyRun run = run_tiny(*source, OfflineStages(), LabelSource::kMasks);
  return run;
}

TEST(OfflinePipeline, TinyObjectsPosesAndGaussians) {
  const auto source = tiny_source();
  const TinyRun& run = ground_truth_run();
  ASSERT_TRUE(run.result.ok) << run.result.error;
  EXPECT_EQ(run.result.frames, source->num_frames());
  EXPECT_EQ(run.result.frames_without_pose, 0);
  EXPECT_GT(run.result.keyframes, 5);
  EXPECT_EQ(static_cast<size_t>(run.result.keyframes), run.result.reports.size());
  for (const auto& r : run.result.reports) EXPECT_TRUE(r.labelled);

  // Objects against the ground truth: found, none spurious, centres within 3 cm.
  const auto records = to_object_records(run.objects->objects());
  const OfflineMetrics m = evaluate_offline_run(run.result, records, run.mapper->keyframe_poses(),
                                                source->info(), {});
  ASSERT_TRUE(m.objects);
  ASSERT_TRUE(m.ate);
  EXPECT_LT(m.ate->rmse_m, 1e-9);  // ground-truth poses
  EXPECT_GE(m.objects->num_matched, 3) << "of " << m.objects->num_gt;
  EXPECT_EQ(m.objects->num_spurious, 0);
  EXPECT_LT(m.objects->mean_cde, 0.03);

  // The Gaussians of each matched object lie on it: within 2 cm of the ground-truth box.
  const DatasetInfo& info = source->info();
  for (const eval::ObjectMatch& match : m.objects->matches) {
    const GtObject* gt = nullptr;
    for (const GtObject& g : info.objects) gt = g.id == match.gt_id ? &g : gt;
    ASSERT_NE(gt, nullptr);
    const gs::GaussianMap g = run.mapper->object_gaussians(match.est_id);
    ASSERT_GT(g.size(), 20u) << "object " << match.est_id;
    size_t inside = 0;
    for (size_t i = 0; i < g.size(); ++i) {
      const Eigen::Vector3d p(g.positions()[3 * i], g.positions()[3 * i + 1], g.positions()[3 * i + 2]);
      const Eigen::Vector3d local = gt->box.rotation.transpose() * (p - gt->box.centre);
      inside += (local.array().abs() <= gt->box.half_extents.array() + 0.02).all() ? 1 : 0;
    }
    EXPECT_GE(inside, g.size() * 95 / 100) << "object " << match.est_id << " (GT " << gt->id << ")";
  }
}

// Objects as landmarks offline: with tracker.object_landmarks on, each keyframe's object-stage
// output goes back to the tracker (the calls tracking_node makes), whose bundle adjustments then
// hold object costs; off (the default), nothing goes back.
TEST(OfflinePipeline, TheTrackerTakesTheObjectStagesObjectsBackWhenEnabled) {
  const auto source = tiny_source();
  std::map<bool, OfflineResult> results;
  for (const bool enabled : {false, true}) {
    tracking::TrackingConfig config;
    config.tracker.objects.enabled = enabled;
    OfflineStages stages;
    add_tracking_stage(config, source->info().camera, true, &stages);
    EXPECT_EQ(static_cast<bool>(stages.object_feedback), enabled);
    results[enabled] = run_tiny(*source, stages, LabelSource::kMasks, false).result;
    ASSERT_TRUE(results[enabled].ok) << results[enabled].error;
    EXPECT_EQ(results[enabled].states.size(), static_cast<size_t>(source->num_frames()));
  }
  EXPECT_EQ(results[false].object_costs, 0u);
  EXPECT_GT(results[true].object_costs, 0u);
  EXPECT_EQ(results[true].trajectory.size(), results[false].trajectory.size());
}

TEST(OfflinePipeline, ObjectLandmarksAreMovedIntoTheTrackersWorld) {
  mapping::ObjectRecord r;
  r.id = 4;
  r.quadric = DualQuadric::from_params(Eigen::Vector3d(1.0, 2.0, 3.0), Eigen::Matrix3d::Identity(),
                                       Eigen::Vector3d(0.3, 0.2, 0.1));
  r.confidence = 0.7;
  r.observations = 6;
  const SE3 T_tracker_world(Eigen::Quaterniond(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ())),
                            Eigen::Vector3d(-1.0, 0.0, 0.5));
  const auto landmarks = object_landmarks({r}, T_tracker_world);
  ASSERT_EQ(landmarks.size(), 1u);
  EXPECT_EQ(landmarks[0].id, 4u);
  EXPECT_TRUE(landmarks[0].confirmed);
  EXPECT_DOUBLE_EQ(landmarks[0].confidence, 0.7);
  EXPECT_EQ(landmarks[0].observations, 6);
  EXPECT_LT((landmarks[0].quadric.centre() - T_tracker_world * r.quadric.centre()).norm(), 1e-9);

  mapping::KeyframeObjects kfo;
  kfo.keyframe_id = 3;
  kfo.detections.resize(3);
  kfo.detections[1].box = Box2d{10, 20, 30, 40};
  kfo.object_ids = {0, 9, 0};  // only the second became an object
  const auto sightings = object_sightings(kfo);
  ASSERT_EQ(sightings.size(), 1u);
  EXPECT_EQ(sightings[0].object_id, 9u);
  EXPECT_EQ(sightings[0].box.x_max, 30.0);
}

// The mapping stage on its own thread (the default) sees the same calls in the same order as on
// the frame loop's: the same keyframes, reports and map, to the bit.
TEST(OfflinePipeline, TheMappingThreadGivesTheSameMapAsOneThread) {
  const auto source = tiny_source();
  const TinyRun& threaded = ground_truth_run();
  const TinyRun one = run_tiny(*source, OfflineStages(), LabelSource::kMasks, false);
  ASSERT_TRUE(threaded.result.ok && one.result.ok);
  EXPECT_EQ(threaded.result.keyframes, one.result.keyframes);
  ASSERT_EQ(threaded.result.reports.size(), one.result.reports.size());
  for (size_t k = 0; k < one.result.reports.size(); ++k) {
    EXPECT_EQ(threaded.result.reports[k].keyframe_id, one.result.reports[k].keyframe_id);
    EXPECT_EQ(threaded.result.reports[k].trainer.losses, one.result.reports[k].trainer.losses) << "keyframe " << k;
  }
  const gs::GaussianMap& a = threaded.mapper->map();
  const gs::GaussianMap& b = one.mapper->map();
  ASSERT_GT(b.size(), 0u);
  EXPECT_EQ(a.positions(), b.positions());
  EXPECT_EQ(a.colours(), b.colours());
  EXPECT_EQ(a.object_ids_per_gaussian(), b.object_ids_per_gaussian());
}

TEST(OfflinePipeline, ADetectorInPlaceOfTheDatasetsDetectionsGivesTheSameMap) {
  // DetectionSource::kDetector (dqo_map_offline --model): a detector that gives exactly the dataset's
  // detections and, as a segmenting model does, their masks (value k + 1 = detection k, from the
  // ground-truth instance image through each detection's gt_id) must give the ground-truth run's
  // objects and map; its masks label the pixels, never the dataset's own.
  const auto source = tiny_source();
  int calls = 0;
  FrameDetector detector = [&calls](const Frame& frame) {
    ++calls;
    FrameDetections d;
    d.detections = frame.detections;
    d.instance = InstanceImage(frame.instance.width, frame.instance.height, 1, 0);
    for (size_t i = 0; i < frame.instance.data.size(); ++i) {
      for (size_t k = 0; k < frame.detections.size(); ++k) {
        if (frame.instance.data[i] != 0 && frame.detections[k].gt_id == frame.instance.data[i]) {
          d.instance.data[i] = static_cast<uint16_t>(k + 1);
          break;
        }
      }
    }
    return d;
  };
  OfflineStages stages;
  auto mapper = std::make_unique<mapping::GaussianMapper>(mapper_params());
  auto objects = add_object_stage(objects::ObjectMapperParams(), DetectionSource::kDetector, LabelSource::kMasks,
                                  source->info(), &stages, detector);
  const OfflineResult result = run_offline_mapping(*source, stages, OfflineMappingParams(), mapper.get());
  ASSERT_TRUE(result.ok) << result.error;
  const TinyRun& gt = ground_truth_run();
  EXPECT_EQ(calls, gt.result.keyframes) << "the detector runs once per keyframe";
  const auto a = to_object_records(gt.objects->objects()), b = to_object_records(objects->objects());
  ASSERT_EQ(a.size(), b.size());
  for (size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(a[k].id, b[k].id);
    EXPECT_LT((a[k].box.centre - b[k].box.centre).norm(), 1e-9) << "object " << a[k].id;
  }
  EXPECT_EQ(mapper->map().size(), gt.mapper->map().size());
  for (const auto& r : a) {
    EXPECT_EQ(mapper->object_gaussians(r.id).size(), gt.mapper->object_gaussians(r.id).size()) << "object " << r.id;
  }
  EXPECT_THROW(add_object_stage(objects::ObjectMapperParams(), DetectionSource::kDetector, LabelSource::kMasks,
                                source->info(), &stages),
               std::invalid_argument)
      << "kDetector without a detector";
}

TEST(OfflinePipeline, SameObjectsAsTheObjectPipeline) {
  // The object stage inside the offline pipeline is run_object_pipeline's (dqo_objects): the same
  // keyframes (the same selector over the same ground-truth poses) give the same objects.
  const auto source = tiny_source();
  const TinyRun& run = ground_truth_run();
  ObjectPipelineParams params;
  const ObjectPipelineResult alone = run_object_pipeline(*source, params);
  ASSERT_TRUE(alone.ok) << alone.error;
  EXPECT_EQ(alone.keyframes, run.result.keyframes);
  const auto ours = run.objects->objects();
  ASSERT_EQ(alone.objects.size(), ours.size());
  for (size_t i = 0; i < ours.size(); ++i) {
    EXPECT_EQ(alone.objects[i].id, ours[i].id);
    EXPECT_EQ(alone.objects[i].class_id, ours[i].class_id);
    EXPECT_LT((alone.objects[i].quadric.centre() - ours[i].quadric.centre()).norm(), 1e-9);
    EXPECT_LT((alone.objects[i].quadric.semi_axes() - ours[i].quadric.semi_axes()).norm(), 1e-9);
  }
}

// An object confirmed in the run's last keyframes (the cup, seen in 3 of 20 with the depth's
// shape as evidence) has few labelled views: its mesh is partial by construction, so the bounds
// below hold for the objects seen in at least this many keyframes.
constexpr int kWellSeen = 5;

// The run's meshes against the ground truth; `closure` on or off. `closed` counts the well-seen
// objects whose mesh was closed on a support, `well_seen` receives their IDs.
OfflineMetrics mesh_metrics(const TinyRun& run, const FrameSource& source, bool closure,
                            int* closed, std::set<uint64_t>* well_seen = nullptr) {
  const auto records = to_object_records(run.objects->objects());
  std::map<uint64_t, TriangleMesh> meshes;
  ObjectMeshParams params;
  params.closure.enabled = closure;
  *closed = 0;
  for (const auto& r : records) {
    std::string error;
    mesh::SupportClosureInfo info;
    auto m = object_mesh(*run.mapper, r.id, params, &error, &info);
    EXPECT_TRUE(m) << error;
    if (!m) continue;
    EXPECT_GT(m->triangles.size(), 50u);
    if (r.observations < kWellSeen) {
      std::printf("object %llu (%s): seen in %d keyframes only, its mesh not held to the bounds\n",
                  static_cast<unsigned long long>(r.id), r.class_name.c_str(), r.observations);
    } else {
      if (well_seen) well_seen->insert(r.id);
      *closed += info.closed ? 1 : 0;
    }
    if (info.closed) {
      // tiny's table top is the plane z = 0.75 (config/scenes/tiny.yaml).
      EXPECT_GT(info.normal.z(), 0.99) << "object " << r.id;
      EXPECT_NEAR(info.offset, 0.75, 0.005) << "object " << r.id;
    }
    meshes[r.id] = std::move(*m);
  }
  return evaluate_offline_run(
      run.result, records, run.mapper->keyframe_poses(), source.info(),
      [&](uint64_t id) -> std::optional<TriangleMesh> {
        const auto it = meshes.find(id);
        return it == meshes.end() ? std::nullopt : std::optional<TriangleMesh>(it->second);
      });
}

TEST(OfflinePipeline, MeshesMatchTheGroundTruthMeshes) {
  const auto source = tiny_source();
  const TinyRun& run = ground_truth_run();
  int closed = 0, closed_off = 0;
  std::set<uint64_t> well_seen;
  const OfflineMetrics m = mesh_metrics(run, *source, true, &closed, &well_seen);
  const OfflineMetrics open = mesh_metrics(run, *source, false, &closed_off);
  ASSERT_TRUE(m.recon && open.recon);
  ASSERT_GE(m.recon->num_with_mesh, 3);
  ASSERT_GE(well_seen.size(), 3u);
  EXPECT_EQ(closed_off, 0);
  EXPECT_EQ(closed, static_cast<int>(well_seen.size())) << "every object of tiny stands on the table";
  // 160x120 noise-free views: every mesh within a few millimetres of the truth on average, most
  // of the truth within a centimetre once the faces on the table are closed.
  for (const auto& row : m.recon->rows) {
    if (!row.has_mesh || !well_seen.count(row.est_id)) continue;
    std::printf("object %llu (GT %llu): acc %.3f cm, comp %.3f cm, ratio<1cm %.2f %%\n",
                static_cast<unsigned long long>(row.est_id), static_cast<unsigned long long>(row.gt_id),
                row.metrics.accuracy_cm, row.metrics.completion_cm, row.metrics.comp_ratio_1cm);
    EXPECT_LT(row.metrics.accuracy_cm, 1.0) << "object " << row.est_id;
    EXPECT_GT(row.metrics.comp_ratio_5cm, 95.0) << "object " << row.est_id;
  }
  std::printf("mean: closed %.2f %% < 1 cm, open %.2f %%\n", m.recon->mean.comp_ratio_1cm,
              open.recon->mean.comp_ratio_1cm);
  EXPECT_GT(m.recon->mean.comp_ratio_1cm, open.recon->mean.comp_ratio_1cm + 3.0);
  EXPECT_LT(m.recon->mean.completion_cm, open.recon->mean.completion_cm);
  // metrics.json names every part.
  const std::string json = metrics_json(m);
  for (const char* key : {"\"ate\"", "\"objects\"", "\"reconstruction\"", "\"comp_ratio_1cm\""}) {
    EXPECT_NE(json.find(key), std::string::npos) << key;
  }
  // Unknown objects are errors, not crashes.
  std::string error;
  EXPECT_FALSE(object_mesh(*run.mapper, 9999, ObjectMeshParams(), &error));
  EXPECT_NE(error.find("no such object"), std::string::npos);
}

TEST(OfflinePipeline, TrajectoryFileInAnotherFrameIsAnchoredOntoTheGroundTruth) {
  const auto source = tiny_source();
  // The ground truth seen from another world frame, as a tracker starting at the origin reports.
  const SE3 T_other_world(Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized())),
                          Eigen::Vector3d(1.0, -2.0, 0.5));
  Trajectory trajectory;
  for (int i = 0; i < source->num_frames(); ++i) {
    const Frame f = *source->read_frame(i);
    trajectory.emplace_back(f.timestamp, T_other_world * f.T_wc);
  }
  OfflineStages stages;
  add_trajectory_stage(trajectory, PoseLookupParams(), KeyframeSelectorParams(), true, &stages);
  const TinyRun run = run_tiny(*source, stages, LabelSource::kQuadrics);
  ASSERT_TRUE(run.result.ok) << run.result.error;
  ASSERT_EQ(run.result.trajectory.size(), run.result.ground_truth.size());
  for (size_t i = 0; i < run.result.trajectory.size(); ++i) {
    EXPECT_LT((run.result.trajectory[i].second.translation() -
               run.result.ground_truth[i].second.translation()).norm(), 1e-9);
  }
  // The same objects as with the ground truth's own poses.
  const auto a = ground_truth_run().objects->objects(), b = run.objects->objects();
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_LT((a[i].quadric.centre() - b[i].quadric.centre()).norm(), 1e-6);
  }
  // Quadric labels (no instance image) still give each object Gaussians.
  for (const auto& s : run.mapper->list_objects()) {
    if (s.known) {
      EXPECT_GT(s.num_gaussians, 0u) << "object " << s.object.id;
    }
  }
}

TEST(OfflinePipeline, ExportObjectWritesUnderTheOutputFolderOnly) {
  const TinyRun& run = ground_truth_run();
  const auto records = to_object_records(run.objects->objects());
  ASSERT_FALSE(records.empty());
  const uint64_t id = records.front().id;
  char pattern[] = "/tmp/dqo_test_export_XXXXXX";
  ASSERT_NE(::mkdtemp(pattern), nullptr);
  const std::filesystem::path root = std::filesystem::path(pattern) / "out";
  auto files = [&root] {
    size_t n = 0;
    std::error_code ec;
    for (auto it = std::filesystem::recursive_directory_iterator(root.parent_path(), ec);
         it != std::filesystem::recursive_directory_iterator(); ++it) {
      n += it->is_regular_file() ? 1 : 0;
    }
    return n;
  };
  // Refused: an unknown ID (the message names the known ones), a sub-folder leading out.
  ObjectExport e = export_object(*run.mapper, 9999, root.string(), "");
  EXPECT_FALSE(e.success);
  EXPECT_NE(e.message.find("no such object"), std::string::npos) << e.message;
  EXPECT_NE(e.message.find(std::to_string(id)), std::string::npos) << e.message;
  e = export_object(*run.mapper, id, root.string(), "../escape");
  EXPECT_FALSE(e.success);
  EXPECT_NE(e.message.find("outside the output folder"), std::string::npos) << e.message;
  e = export_object(*run.mapper, id, root.string(), "/tmp");
  EXPECT_FALSE(e.success);
  EXPECT_EQ(files(), 0u) << "nothing written";
  // Written: the object's Gaussians (read back equal to the map's) and its mesh, in the sub-folder.
  e = export_object(*run.mapper, id, root.string(), "extracted/run1");
  ASSERT_TRUE(e.success) << e.message;
  EXPECT_EQ(std::filesystem::path(e.gaussians_path).parent_path(),
            std::filesystem::weakly_canonical(root / "extracted/run1"));
  std::string error;
  const auto back = gs::load_gaussians_ply(e.gaussians_path, &error);
  ASSERT_TRUE(back) << error;
  const gs::GaussianMap own = run.mapper->object_gaussians(id);
  ASSERT_EQ(back->size(), own.size());
  EXPECT_EQ(back->positions(), own.positions());
  EXPECT_EQ(back->object_ids_per_gaussian(), own.object_ids_per_gaussian());
  const auto mesh = load_mesh(e.mesh_path, &error);
  ASSERT_TRUE(mesh) << error;
  EXPECT_GT(mesh->triangles.size(), 50u);
  EXPECT_EQ(files(), 2u);
  std::filesystem::remove_all(pattern);
}

}  // namespace
}  // namespace dqo::system
