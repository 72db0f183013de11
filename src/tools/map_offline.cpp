// dqo_map_offline: the whole pipeline without ROS (the stage classes the three nodes call, wired
// in-process by system/) on a dataset folder (own format, TUM RGB-D, Replica) or a scene YAML
// rendered in memory. Writes into --out:
//   objects.txt                    the objects, one line each (RO-MAP / VOOM format)
//   map.dqomap                     the map file (Gaussians, objects, keyframe poses, next ID)
//   gaussians.ply                  the whole map in the 3DGS PLY layout with object_id
//   object_<id>_gaussians.ply      each object's Gaussians
//   object_<id>_mesh.ply           each object's TSDF mesh
//   timings.json                   per stage, per frame and total; frames per second; peak memory
//   metrics.json                   where ground truth exists: ATE, objects, reconstruction
//   trajectory.txt                 the poses of the run (TUM format; anchored like the map)
//   states.txt                     with --poses track: each frame's tracking state ("stamp state")
//   object_table.txt               the objects for a person: class shares, centre, box, observations
//   overlays/keyframe_<id>.png     with --overlays: each keyframe's detections and objects drawn
// The reduced build (no OpenCV, Ceres, Open3D: the GPU machine) takes scene YAMLs only, with
// ground-truth poses and instance labels, and writes neither meshes nor metrics.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "dqo_map/common/atomic_file.h"
#include "dqo_map/common/object_list.h"
#include "dqo_map/common/progress.h"
#include "dqo_map/common/tum_trajectory.h"
#include "dqo_map/gaussians/gaussian_ply.h"
#include "dqo_map/mapping/map_file.h"
#include "dqo_map/mapping/params_yaml.h"
#include "dqo_map/sim/scene_frame_source.h"
#include "dqo_map/sim/scene_loader.h"
#include "dqo_map/system/offline_mapping.h"
#include "dqo_map/system/offline_report.h"
#ifdef DQO_FULL_PIPELINE
#include "dqo_map/io/dataset_reader.h"
#include "dqo_map/io/image_io.h"
#include "dqo_map/io/mesh_io.h"
#include "dqo_map/io/trajectory_io.h"
#include "dqo_map/objects/params_yaml.h"
#include "dqo_map/system/keyframe_overlays.h"
#include "dqo_map/system/object_export.h"
#include "dqo_map/system/object_meshes.h"
#include "dqo_map/system/offline_metrics.h"
#include "dqo_map/system/offline_stages.h"
#include "dqo_map/tracking/rectified_frame_source.h"
#endif
#ifdef DQO_WITH_DETECTOR
#include "detector_options.h"
#endif

namespace {

namespace fs = std::filesystem;

constexpr char kUsage[] =
    "usage: dqo_map_offline INPUT --out DIR [--poses gt|track|FILE] [--labels masks|quadrics|none]\n"
    "                       [--backend auto|cpu|cuda] [--scale S] [--frames N] [--every K]\n"
    "                       [--config mapping.yaml] [--tracking-config tracking.yaml]\n"
    "                       [--objects-config objects.yaml] [--max-gaussians N] [--threads T]\n"
    "                       [--no-noise] [--no-meshes] [--background-mesh] [--map FILE] [--preload]\n"
    "                       [--one-thread] [--overlays DIR] [--quiet] [--detector-profile kind|real]\n"
    "                       [--camera camera.yaml]\n"
    "  INPUT              a dataset folder (own format, TUM RGB-D, Replica) or a scene YAML\n"
    "                     (rendered in memory, with its sensor noise unless --no-noise)\n"
    "  --detector-profile P  scene YAMLs: the simulated detector behaves as profile P whatever\n"
    "                     the scene says of its rates: kind (the default) or real (recall 40 %,\n"
    "                     30 % of labels flipped within the scene's confusion groups, 10 % false\n"
    "                     positives, half on fixed clutter spots); config/scenes/README.md\n"
    "  --out DIR          output folder (created)\n"
    "  --camera FILE      a TUM sequence's intrinsics, distortion and rolling shutter from FILE, not\n"
    "                     its camera.yaml (e.g. config/cameras/tum_fr1.yaml), as dqo_track takes it\n"
    "  --poses gt         the input's ground-truth poses (default where it has them)\n"
    "  --poses track      the tracker's (default without ground truth)\n"
    "  --poses FILE       a TUM trajectory matched by timestamp (e.g. dqo_track's)\n"
    "  --labels masks     pixel labels from the input's instance masks (default where it has them)\n"
    "  --labels quadrics  pixel labels from the objects' ellipsoids and detection boxes\n"
    "  --labels none      no objects: the whole map is background (inputs without detections)\n"
    "  --backend B        auto (the GPU when one is there), cpu or cuda (the GPU or an error)\n"
    "  --scale S          image size factor (e.g. 0.5: half width and height)\n"
    "  --frames N         at most N frames (after --every)\n"
    "  --every K          every K-th frame only\n"
    "  --config FILE      mapping parameters (config/mapping.yaml); --tracking-config and\n"
    "                     --objects-config for the other stages\n"
    "  --max-gaussians N  the Gaussian budget (overrides the config's)\n"
    "  --threads T        CPU threads of the rasteriser and the renderer (default: all)\n"
    "  --preload          read (render) every frame into memory before the clock starts: times the\n"
    "                     pipeline alone (memory: about 11 bytes per pixel and frame)\n"
    "  --one-thread       map on the frame loop's thread (default: a thread of its own, as the ROS\n"
    "                     system runs it; the same map either way)\n"
    "  --no-meshes        skip the per-object meshes (and the reconstruction metrics)\n"
    "  --background-mesh  also mesh the background (background_mesh.ply, 1 cm voxels)\n"
    "  --overlays DIR     one PNG per keyframe (keyframe_<id>.png; DIR relative to --out): the\n"
    "                     image with its detections (\"class score\") and the objects' projected\n"
    "                     ellipses (\"#ID class\"; candidates thin, dashed, \"?\") as they stood after it\n"
    "  --map FILE         no mapping: mesh and evaluate the map of a finished run (map.dqomap)\n";

#ifdef DQO_WITH_DETECTOR
// Detections from a YOLO model run on each keyframe instead of the input's (its masks label the
// pixels where it segments).
const std::string kModelUsage = std::string("  --model M.onnx     detect with a YOLO model (and the detector options below)\n") +
                                dqo::tools::kDetectorUsage;
#else
const std::string kModelUsage;
#endif

int usage_error(const std::string& message) {
  std::fprintf(stderr, "dqo_map_offline: %s\n%s%s", message.c_str(), kUsage, kModelUsage.c_str());
  return 2;
}

int fail(const std::string& message) {
  std::fprintf(stderr, "dqo_map_offline: %s\n", message.c_str());
  return 1;
}

struct Options {
  std::string input, out, poses, labels, backend, config, tracking_config, objects_config, map;
  std::string overlays;  // empty: none
  std::string camera;    // --camera: a TUM sequence's camera file in place of its camera.yaml
  double scale = 1.0;
  int frames = -1, every = 1, max_gaussians = -1, threads = 0;
  bool noise = true, meshes = true, background_mesh = false, quiet = false, preload = false;
  bool mapping_thread = true;
  dqo::sim::SceneOverrides scene_overrides;
#ifdef DQO_WITH_DETECTOR
  dqo::detector::YoloParams detector;  // detector.model empty: no detector
#endif
};

bool parse_int(const char* v, int lo, int* out) {
  char* end = nullptr;
  const long n = std::strtol(v, &end, 10);
  if (end == v || *end != '\0' || n < lo || n > 2000000000L) return false;
  *out = static_cast<int>(n);
  return true;
}

// PNG where io/ (OpenCV) is built, binary PPM otherwise (the GPU machine).
#ifdef DQO_FULL_PIPELINE
constexpr char kImageExtension[] = ".png";
bool write_image(const fs::path& path, const dqo::ImageRgb8& image, std::string* error) {
  return dqo::write_png(path.string(), image, error);
}
#else
constexpr char kImageExtension[] = ".ppm";
bool write_image(const fs::path& path, const dqo::ImageRgb8& image, std::string* error) {
  std::ofstream out(path, std::ios::binary);
  out << "P6\n" << image.width << " " << image.height << "\n255\n";
  out.write(reinterpret_cast<const char*>(image.data.data()),
            static_cast<std::streamsize>(image.data.size()));
  if (!out) *error = path.string() + ": cannot write";
  return static_cast<bool>(out);
}
#endif

bool is_scene_yaml(const std::string& input) {
  const std::string ext = fs::path(input).extension().string();
  return fs::is_regular_file(input) && (ext == ".yaml" || ext == ".yml");
}

// Fills *o from the command line; returns -1 to go on, else the exit code (help, usage errors).
int parse_options(int argc, char** argv, Options* out) {
  Options& o = *out;
  int positional = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> const char* { return i + 1 < argc ? argv[++i] : nullptr; };
#ifdef DQO_WITH_DETECTOR
    std::string detector_error;
    if (dqo::tools::parse_detector_option(argc, argv, &i, &o.detector, &detector_error)) {
      if (!detector_error.empty()) return usage_error(detector_error);
      continue;
    }
#endif
    if (a == "-h" || a == "--help") {
      std::fputs(kUsage, stdout);
      std::fputs(kModelUsage.c_str(), stdout);
      return 0;
    } else if (a == "--preload") {
      o.preload = true;
    } else if (a == "--one-thread") {
      o.mapping_thread = false;
    } else if (a == "--no-noise") {
      o.noise = false;
    } else if (a == "--no-meshes") {
      o.meshes = false;
    } else if (a == "--background-mesh") {
      o.background_mesh = true;
    } else if (a == "--quiet") {
      o.quiet = true;
    } else if (a.rfind("--", 0) == 0) {
      const char* v = value();
      if (!v) return usage_error(a + " needs a value");
      if (a == "--out") {
        o.out = v;
      } else if (a == "--poses") {
        o.poses = v;
      } else if (a == "--labels") {
        o.labels = v;
      } else if (a == "--backend") {
        o.backend = v;
      } else if (a == "--map") {
        o.map = v;
      } else if (a == "--overlays") {
        o.overlays = v;
      } else if (a == "--config") {
        o.config = v;
      } else if (a == "--tracking-config") {
        o.tracking_config = v;
      } else if (a == "--objects-config") {
        o.objects_config = v;
      } else if (a == "--camera") {
        o.camera = v;
      } else if (a == "--detector-profile") {
        o.scene_overrides.detector_profile = dqo::sim::detector_profile_from_name(v);
        if (!o.scene_overrides.detector_profile) {
          return usage_error(std::string("unknown detector profile '") + v + "' (" +
                             dqo::sim::kDetectorProfileNames + ")");
        }
      } else if (a == "--scale") {
        char* end = nullptr;
        o.scale = std::strtod(v, &end);
        if (end == v || *end != '\0' || !(o.scale > 0.0) || o.scale > 4.0) {
          return usage_error("--scale takes a number in (0, 4]");
        }
      } else if (a == "--frames") {
        if (!parse_int(v, 1, &o.frames)) return usage_error("--frames takes a whole number >= 1");
      } else if (a == "--every") {
        if (!parse_int(v, 1, &o.every)) return usage_error("--every takes a whole number >= 1");
      } else if (a == "--max-gaussians") {
        if (!parse_int(v, 0, &o.max_gaussians)) return usage_error("--max-gaussians takes a whole number >= 0");
      } else if (a == "--threads") {
        if (!parse_int(v, 0, &o.threads)) return usage_error("--threads takes a whole number >= 0");
      } else {
        return usage_error("unknown option " + a);
      }
    } else if (positional++ == 0) {
      o.input = a;
    } else {
      return usage_error("unexpected argument " + a);
    }
  }
  if (o.input.empty()) return usage_error("no INPUT given");
  if (o.out.empty()) return usage_error("--out is required");
  if (!o.labels.empty() && o.labels != "masks" && o.labels != "quadrics" && o.labels != "none") {
    return usage_error("--labels must be masks, quadrics or none, not '" + o.labels + "'");
  }
  if (!o.camera.empty() && is_scene_yaml(o.input)) {
    return usage_error("--camera is for TUM sequences (a scene YAML has its own camera)");
  }
  if (o.scene_overrides.detector_profile && !is_scene_yaml(o.input)) {
    return usage_error("--detector-profile is for scene YAMLs (the synthetic world's detector)");
  }
  return -1;
}

// The frames: a scene YAML rendered in memory, or (full build) a dataset folder. nullptr and
// *error when it cannot be opened.
std::shared_ptr<const dqo::FrameSource> open_input(const Options& o, std::string* kind,
                                                   std::string* error) {
  if (is_scene_yaml(o.input)) {
    dqo::sim::MeshLoader loader;
#ifdef DQO_FULL_PIPELINE
    loader = &dqo::load_mesh;
#endif
    auto scene = dqo::sim::load_scene(o.input, loader, error, o.scene_overrides);
    if (!scene) return nullptr;
    const bool noisy = o.noise && scene->noise.enabled;
    *kind = std::string("scene, ") +
            (noisy ? std::string("with sensor noise, detector ") +
                         dqo::sim::detector_profile_name(scene->noise.detection.profile)
                   : std::string("noise-free"));
    return std::make_shared<dqo::sim::SceneFrameSource>(std::move(*scene), o.scale, o.noise,
                                                        o.threads);
  }
#ifdef DQO_FULL_PIPELINE
  dqo::DatasetReaderParams reader_params;
  reader_params.tum.camera_file = o.camera;
  auto reader = dqo::open_dataset(o.input, reader_params, error);
  if (!reader) return nullptr;
  if (!o.camera.empty() && reader->format() != "tum") {
    *error = "--camera applies to TUM sequences only (" + o.input + " is " + reader->format() + ")";
    return nullptr;
  }
  *kind = reader->format() + " dataset";
  if (!reader->info().distortion_model.empty()) *kind += ", " + reader->info().distortion_model + " undistorted";
  // Lens distortion comes off first, as tracking_node does it: the rest assumes a pinhole camera.
  std::shared_ptr<const dqo::FrameSource> r =
      dqo::tracking::rectified(std::shared_ptr<const dqo::FrameSource>(std::move(reader)), error);
  if (!r) return nullptr;
  return o.scale == 1.0 ? r : std::make_shared<dqo::ScaledFrameSource>(r, o.scale);
#else
  *error = o.input + ": this build reads scene YAML files only (datasets need io/: OpenCV, Open3D)";
  return nullptr;
#endif
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  if (const int rc = parse_options(argc, argv, &o); rc >= 0) return rc;

  // Parameters.
  std::string error;
  dqo::mapping::GaussianMapperParams params;
  if (!o.config.empty()) {
    auto loaded = dqo::mapping::load_mapping_params(o.config, &error);
    if (!loaded) return fail(error);
    params = *loaded;
  }
  if (!o.backend.empty() && !dqo::mapping::parse_backend(o.backend, &params.backend)) {
    return usage_error("--backend must be auto, cpu or cuda, not '" + o.backend + "'");
  }
  if (o.max_gaussians >= 0) params.max_gaussians = o.max_gaussians;
  if (o.threads > 0) params.threads = o.threads;

  // Input.
  std::string input_kind;
  std::shared_ptr<const dqo::FrameSource> source = open_input(o, &input_kind, &error);
  if (!source) return fail(error);
  if (o.preload) {
    const int count = std::min(o.frames > 0 ? o.frames : source->num_frames(),
                               (source->num_frames() + o.every - 1) / o.every);
    std::vector<int> indices;
    for (int k = 0; k < count; ++k) indices.push_back(k * o.every);
    const auto t0 = std::chrono::steady_clock::now();
    try {
      auto preloaded = std::make_shared<dqo::PreloadedFrameSource>(source, indices, o.threads);
      if (!o.quiet)
        std::fprintf(stderr, "dqo_map_offline: %d frames read into memory (%.0f MB) in %.1f s, before the clock\n",
                     count, preloaded->bytes() / 1e6,
                     std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      source = std::move(preloaded);
    } catch (const std::exception& e) {
      return fail(std::string("--preload: ") + e.what());
    }
  }
  const dqo::DatasetInfo& info = source->info();
  if (source->num_frames() < 1) return fail(o.input + " holds no frames");

  // What the input has: read the first frame to know.
  auto first = source->read_frame(0, &error);
  if (!first) return fail("frame 0: " + error);
  const bool has_gt_poses = first->has_pose;
  const bool has_masks = !first->instance.empty();
  std::string poses = o.poses.empty() ? (has_gt_poses ? "gt" : "track") : o.poses;
#ifdef DQO_WITH_DETECTOR
  // A YOLO model in place of the input's detections: checked before the long part.
  std::shared_ptr<dqo::detector::YoloDetector> yolo;
  if (!o.detector.model.empty()) {
    if (o.detector.classes.empty()) o.detector.classes = dqo::tools::default_class_names();
    yolo = dqo::detector::YoloDetector::create(o.detector, &error);
    if (!yolo) return fail(error);
    std::fprintf(stderr, "dqo_map_offline: detections from %s (%s)\n", o.detector.model.c_str(),
                 yolo->layout().describe().c_str());
  }
  const bool detector = yolo != nullptr;
  const bool masks_available = detector ? yolo->segments() : has_masks;
#else
  const bool detector = false;
  const bool masks_available = has_masks;
#endif
  std::string labels = o.labels.empty() ? (masks_available ? "masks" : "quadrics") : o.labels;
  if (poses == "gt" && !has_gt_poses) return fail(o.input + " has no ground-truth poses: use --poses track or FILE");
  if (labels == "masks" && !masks_available) {
    return fail(detector ? o.input + ": the model gives no masks (not a -seg model): use --labels quadrics"
                         : o.input + " has no instance masks: use --labels quadrics");
  }

  std::error_code ec;
  fs::create_directories(o.out, ec);
  if (ec || !fs::is_directory(o.out)) return fail("cannot create the output folder " + o.out);
  const fs::path out(o.out);

  // Stages.
  dqo::system::OfflineStages stages;
  dqo::system::OfflineMappingParams run_params;
  run_params.max_frames = o.frames;
  run_params.every = o.every;
  run_params.mapping_thread = o.mapping_thread;
#ifdef DQO_FULL_PIPELINE
  dqo::tracking::TrackingConfig tracking_config;
  if (!o.tracking_config.empty()) {
    auto loaded = dqo::tracking::load_tracking_config(o.tracking_config, &error);
    if (!loaded) return fail(error);
    tracking_config = *loaded;
  }
  // The camera's rolling shutter is a property of the sensor: its file's value wins (as dqo_track).
  if (info.rolling_shutter_s > 0.0)
    tracking_config.tracker.rolling_shutter.readout_s = info.rolling_shutter_s;
  run_params.keyframes = tracking_config.mapping_keyframes;
  if (poses == "track") {
    dqo::system::add_tracking_stage(tracking_config, info.camera, has_gt_poses, &stages);
  } else if (poses != "gt") {
    auto trajectory = dqo::read_tum_trajectory(poses, &error);
    if (!trajectory) return fail(error);
    dqo::system::add_trajectory_stage(std::move(*trajectory), dqo::PoseLookupParams(),
                                      tracking_config.mapping_keyframes, has_gt_poses, &stages);
  }
  dqo::objects::ObjectMapperParams object_params;
  if (!o.objects_config.empty()) {
    auto loaded = dqo::objects::load_object_params(o.objects_config, &error);
    if (!loaded) return fail(error);
    object_params = *loaded;
  }
  if (o.scale != 1.0) {
    // The detection filter's pixel thresholds describe boxes of the input's own resolution: a box
    // too small to trust there is as untrustworthy scaled down with the image.
    object_params.filter.min_area_px *= o.scale * o.scale;
    object_params.filter.border_margin_px *= o.scale;
  }
  const bool has_detections_file = input_kind.rfind("scene", 0) == 0 ||
                                   fs::is_regular_file(fs::path(o.input) / "detections.txt");
  if (labels != "none" && !detector && !has_detections_file && !has_masks) {
    return fail(o.input + " has neither detections (detections.txt) nor instance masks: no objects "
                "can be found (give it a detections.txt, e.g. from a detector, or map it without "
                "objects with --labels none)");
  }
  const auto detection_source = detector              ? dqo::system::DetectionSource::kDetector
                                : has_detections_file ? dqo::system::DetectionSource::kDataset
                                                      : dqo::system::DetectionSource::kMasks;
  dqo::system::FrameDetector detect;
#ifdef DQO_WITH_DETECTOR
  if (yolo) {
    // On each keyframe's colour image (the object stage's frame: undistorted and scaled like the rest).
    detect = [yolo](const dqo::Frame& frame) {
      dqo::detector::YoloDetections r = yolo->detect(frame.rgb);
      return dqo::system::FrameDetections{std::move(r.detections), std::move(r.instance)};
    };
  }
#endif
  // Watching the object stage: the class names its detections use (for the object table) and,
  // with --overlays, each keyframe drawn.
  auto class_names = std::make_shared<std::map<int, std::string>>();
  auto overlay_log = std::make_shared<dqo::system::OverlayLog>();
  fs::path overlay_dir;
  dqo::system::ObjectStageObserver write_overlay;
  if (!o.overlays.empty()) {
    if (labels == "none") return fail("--overlays draws the objects: not with --labels none");
    if (!o.map.empty()) return fail("--overlays draws a run's keyframes: not with --map");
    overlay_dir = out / o.overlays;
    write_overlay = dqo::system::overlay_writer(overlay_dir.string(), overlay_log, &error);
    if (!write_overlay) return fail(error);
  }
  const dqo::system::ObjectStageObserver collect_names = dqo::system::class_name_collector(class_names);
  const dqo::system::ObjectStageObserver observe = [collect_names, write_overlay](
                                                       const dqo::system::ObjectStageView& view) {
    collect_names(view);
    if (write_overlay) write_overlay(view);
  };
  std::shared_ptr<dqo::objects::ObjectMapper> object_mapper;
  std::string objects_from = "nowhere";
  if (labels != "none") {
    object_mapper = dqo::system::add_object_stage(
        object_params, detection_source,
        labels == "masks" ? dqo::system::LabelSource::kMasks : dqo::system::LabelSource::kQuadrics,
        info, &stages, detect, observe);
    objects_from = detection_source == dqo::system::DetectionSource::kDetector ? "the model's detections"
                   : detection_source == dqo::system::DetectionSource::kDataset ? "detections"
                                                                                 : "instance masks";
  }
#else
  if (!o.overlays.empty()) return fail("--overlays needs the full build (OpenCV: io/ and the object stage)");
  if (poses != "gt") return fail("this build maps with ground-truth poses only (--poses gt)");
  if (labels == "quadrics") return fail("this build labels pixels from instance masks only (--labels masks)");
  const std::string objects_from = labels == "none" ? "nowhere" : "ground truth";
#endif
  if (labels == "none") {
    stages.objects = [](const dqo::mapping::MappingKeyframe&, const dqo::Frame&) {
      return dqo::system::ObjectStageOutput();
    };
  }

  std::fprintf(stderr,
               "dqo_map_offline: %s (%s), %d frames of %dx%d, every %d; poses %s, labels %s, objects "
               "from %s, backend %s, budget %d Gaussians\n",
               o.input.c_str(), input_kind.c_str(), source->num_frames(), info.camera.width,
               info.camera.height, o.every, poses.c_str(), labels.c_str(), objects_from.c_str(),
               dqo::mapping::to_string(params.backend), params.max_gaussians);

  std::unique_ptr<dqo::mapping::GaussianMapper> mapper;
  try {
    mapper = std::make_unique<dqo::mapping::GaussianMapper>(params);
  } catch (const std::exception& e) {
    return fail(e.what());
  }
  const int total = std::min(o.frames > 0 ? o.frames : source->num_frames(),
                             (source->num_frames() + o.every - 1) / o.every);
  dqo::ProgressBar bar("mapping", total);
  dqo::system::OfflineResult run;
  std::optional<dqo::mapping::MapFileContents> loaded_map;
  if (o.map.empty()) {
    run = dqo::system::run_offline_mapping(*source, stages, run_params, mapper.get(),
                                           [&](int done, int) {
                                             if (!o.quiet) bar.update(done);
                                           });
  } else {
    loaded_map = dqo::mapping::load_map_file(o.map, &error);
    if (!loaded_map) return fail(error);
    std::string warning;
    mapper->restore(*loaded_map, &warning);
    if (!warning.empty()) std::fprintf(stderr, "dqo_map_offline: %s: %s\n", o.map.c_str(), warning.c_str());
    run.ok = true;
  }
  for (const std::string& w : run.warnings) std::fprintf(stderr, "dqo_map_offline: %s\n", w.c_str());
  if (!run.ok) std::fprintf(stderr, "dqo_map_offline: stopped early: %s\n", run.error.c_str());

  // Objects.
  std::vector<dqo::mapping::ObjectRecord> objects;
  dqo::mapping::ObjectId next_id = 1;
#ifdef DQO_FULL_PIPELINE
  if (loaded_map) {
    objects = loaded_map->objects;
    next_id = loaded_map->next_object_id;
  } else if (object_mapper) {
    objects = dqo::system::to_object_records(object_mapper->objects());
    next_id = object_mapper->next_id();
  }
#else
  for (const dqo::GtObject& g : info.objects) {
    if (labels == "none") break;
    objects.push_back(dqo::system::object_record_from_box(g.id, g.class_id, g.class_name, g.box));
    next_id = std::max<dqo::mapping::ObjectId>(next_id, g.id + 1);
  }
#endif
  mapper->set_objects(objects);
  std::vector<dqo::ObjectListEntry> entries;
  for (const auto& r : objects) entries.push_back(dqo::make_object_list_entry(r.id, r.class_id, r.box));
  if (!dqo::write_object_list((out / "objects.txt").string(), entries, &error)) return fail(error);
#ifdef DQO_FULL_PIPELINE
  if (object_mapper && !loaded_map) {
    std::string text = dqo::system::object_table(object_mapper->objects(), *class_names);
    std::string candidates;
    for (const auto& c : object_mapper->objects(true)) {
      if (c.state != dqo::objects::ObjectState::kConfirmed) candidates += " #" + std::to_string(c.id);
    }
    if (!candidates.empty()) text += "# candidates never confirmed:" + candidates + "\n";
    if (!dqo::write_file_atomically((out / "object_table.txt").string(), text, &error)) return fail(error);
  }
  if (!o.overlays.empty()) {
    if (!overlay_log->error.empty()) std::fprintf(stderr, "dqo_map_offline: overlays: %s\n", overlay_log->error.c_str());
    std::printf("overlays: %d keyframe images in %s\n", overlay_log->written, fs::absolute(overlay_dir).c_str());
  }
#endif

  // The map and the Gaussians.
  if (!dqo::mapping::save_map_file((out / "map.dqomap").string(), mapper->snapshot(next_id), &error)) {
    return fail(error);
  }
  if (!dqo::gs::save_gaussians_ply((out / "gaussians.ply").string(), mapper->map(), nullptr, &error)) {
    return fail(error);
  }
  const std::vector<dqo::mapping::ObjectSummary> summaries = mapper->list_objects();
#ifdef DQO_FULL_PIPELINE
  const bool exporting = o.meshes;  // export_object below writes the reported objects' Gaussians
#else
  const bool exporting = false;
#endif
  for (const auto& s : summaries) {
    if (exporting && s.known) continue;
    const std::vector<uint32_t> idx = mapper->map().indices_of(static_cast<uint32_t>(s.object.id));
    const fs::path p = out / ("object_" + std::to_string(s.object.id) + "_gaussians.ply");
    if (!dqo::gs::save_gaussians_ply(p.string(), mapper->map(), &idx, &error)) return fail(error);
  }

  // Renders of the map from four keyframes spread over the run: what the map looks like.
  const auto& poses_mapped = mapper->keyframe_poses();
  for (int k = 0; k < 4 && !poses_mapped.empty(); ++k) {
    const auto& pose = poses_mapped[k * (poses_mapped.size() - 1) / 3];
    const fs::path p = out / ("render_keyframe_" + std::to_string(pose.id) + kImageExtension);
    if (!write_image(p, dqo::system::render_colour_and_ids(*mapper, pose), &error)) return fail(error);
  }

  // Meshes and metrics.
  std::string metrics_text;
  std::string table;
  double mesh_seconds = 0.0;
#ifdef DQO_FULL_PIPELINE
  std::map<uint64_t, std::string> mesh_paths;
  if (o.meshes) {
    const auto t0 = std::chrono::steady_clock::now();
    dqo::ProgressBar mesh_bar("meshes", static_cast<int>(objects.size()));
    int done = 0;
    for (const auto& r : objects) {
      const dqo::system::ObjectExport e = dqo::system::export_object(*mapper, r.id, o.out, "");
      if (!e.success) {
        std::fprintf(stderr, "\ndqo_map_offline: %s\n", e.message.c_str());
      } else {
        mesh_paths[r.id] = e.mesh_path;
        if (!e.closure.closed) {
          std::fprintf(stderr,
                       "\ndqo_map_offline: object %llu: contact face left open: %s (plane "
                       "inliers %d, contact points %d, %.1f %% of the surface beyond the plane)\n",
                       static_cast<unsigned long long>(r.id), e.closure.reason,
                       e.closure.plane_inliers, e.closure.contact_points,
                       100 * e.closure.penetrating_fraction);
        }
      }
      if (!o.quiet) mesh_bar.update(++done);
    }
    mesh_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  if (o.background_mesh) {
    dqo::mesh::TsdfParams tsdf;
    auto m = dqo::system::background_mesh(*mapper, 0.01, tsdf, &error);
    if (!m) {
      std::fprintf(stderr, "dqo_map_offline: no background mesh: %s\n", error.c_str());
    } else if (!dqo::save_mesh_ply((out / "background_mesh.ply").string(), *m, &error)) {
      return fail(error);
    }
  }
  const bool has_gt = !info.objects.empty() || !run.ground_truth.empty();
  if (has_gt) {
    const auto metrics = dqo::system::evaluate_offline_run(
        run, objects, mapper->keyframe_poses(), info,
        [&mesh_paths](uint64_t id) -> std::optional<dqo::TriangleMesh> {
          const auto it = mesh_paths.find(id);
          if (it == mesh_paths.end()) return std::nullopt;
          return dqo::load_mesh(it->second);  // evaluated as written, like dqo_recon_table
        });
    metrics_text = dqo::system::metrics_json(metrics);
    if (metrics.recon && o.meshes) table = dqo::mesh::format_recon_table(*metrics.recon);
    if (metrics.ate) std::printf("ATE RMSE: %.2f cm over %d frames\n", 100 * metrics.ate->rmse_m, metrics.ate->matched);
    if (run.object_costs > 0)
      std::printf("objects as landmarks: %llu keyframe-object costs in the tracker's bundle adjustments\n",
                  static_cast<unsigned long long>(run.object_costs));
    if (metrics.objects) {
      std::printf("objects: %d of %d found, %d spurious; mean 3D IoU %.3f, 2D IoU %.3f, CDE %.1f cm\n",
                  metrics.objects->num_matched, metrics.objects->num_gt, metrics.objects->num_spurious,
                  metrics.objects->mean_iou_3d, metrics.objects->mean_iou_2d,
                  100 * metrics.objects->mean_cde);
    }
  }
#endif
  if (!metrics_text.empty() && !dqo::write_file_atomically((out / "metrics.json").string(), metrics_text, &error)) {
    return fail(error);
  }

  if (!dqo::write_tum_trajectory((out / "trajectory.txt").string(), run.trajectory, &error)) return fail(error);
  if (!run.states.empty()) {
    std::string states;
    char line[64];
    for (const auto& [stamp, state] : run.states) {
      std::snprintf(line, sizeof(line), "%.6f ", stamp);
      states += line + state + "\n";
    }
    if (!dqo::write_file_atomically((out / "states.txt").string(), states, &error)) return fail(error);
  }

  // Timings.
  if (!dqo::write_file_atomically((out / "timings.json").string(),
                                  dqo::system::timings_json(run, *mapper, o.input, mesh_seconds),
                                  &error)) {
    return fail(error);
  }
  const double seconds = run.seconds;
  const size_t gaussians = mapper->map_structure().size();

  std::printf("%d frames, %d keyframes in %.1f s (%.2f frames/s, %.0f ms per keyframe mapping); %zu Gaussians "
              "(%.1f MB), peak memory %.0f MB\n",
              run.frames, run.keyframes, seconds, seconds > 0 ? run.frames / seconds : 0.0,
              run.timings.mapping_ms.empty() ? 0.0
                                             : [&] {
                                                 double s = 0;
                                                 for (double m : run.timings.mapping_ms) s += m;
                                                 return s / run.timings.mapping_ms.size();
                                               }(),
              gaussians, mapper->map_structure().bytes_used() / 1e6, dqo::system::peak_memory_mb());
  std::printf("mapping: %.2f ms per input frame amortised, mean final training loss %.5f\n",
              run.frames > 0 ? [&] {
                double s = 0;
                for (double m : run.timings.mapping_ms) s += m;
                return s / run.frames;
              }() : 0.0,
              dqo::system::mean_final_loss(run));
  for (const auto& s : summaries) {
    std::printf("  object %llu %s: %zu Gaussians\n", static_cast<unsigned long long>(s.object.id),
                s.known ? s.object.class_name.c_str() : "(not reported)", s.num_gaussians);
  }
  if (!table.empty()) std::printf("%s", table.c_str());
  std::printf("output: %s\n", fs::absolute(out).c_str());
  return run.ok ? 0 : 1;
}
