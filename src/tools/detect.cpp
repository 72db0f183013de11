// dqo_detect: runs a YOLO model (ONNX, through OpenCV's DNN module) on the colour frames of a
// dataset folder (own format, TUM RGB-D or Replica) and writes its detections.txt, so that any
// dataset gets detections for dqo_objects and dqo_map_offline. One line per detection,
// `frame x1 y1 x2 y2 class_id score` (frame: the frame index; for TUM the colour image's
// timestamp, which the TUM reader matches to its frame), boxes in the pixels of the stored
// (possibly distorted) images, as a detector on the camera's raw images gives them. Beside it:
// classes.txt (`id name`: the model's names added; an existing entry must agree), and for -seg models
// detections_instance/NNNNNN.png (uint16, value k + 1 = the frame's k-th detection in the file).
// The file is written at the end (atomically): an interrupted run leaves none. A file that holds
// detections already is replaced only with --force.
//
//   dqo_detect DATASET --model M.onnx [--classes names.txt] [--out detections.txt] [--force] ...
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "detector_options.h"
#include "dqo_map/common/atomic_file.h"
#include "dqo_map/common/progress.h"
#include "dqo_map/detector/yolo_detector.h"
#include "dqo_map/io/class_list.h"
#include "dqo_map/io/dataset_reader.h"
#include "dqo_map/io/image_io.h"

namespace fs = std::filesystem;

namespace {

const std::string kUsage = std::string(
    "usage: dqo_detect DATASET --model M.onnx [--out FILE] [--force] [--frames N] [detector options]\n"
    "  DATASET            own format (camera.yaml, rgb/), TUM RGB-D (rgb.txt, depth.txt) or Replica\n"
    "  --out FILE         detections file (default DATASET/detections.txt); classes.txt and, for -seg\n"
    "                     models, detections_instance/ go beside it\n"
    "  --force            replace a detections file that holds detections\n"
    "  --frames N         only the first N frames\n") + dqo::tools::kDetectorUsage;

int usage_error(const std::string& message) {
  std::fprintf(stderr, "dqo_detect: %s\n%s", message.c_str(), kUsage.c_str());
  return 2;
}

int fail(const std::string& message) {
  std::fprintf(stderr, "dqo_detect: %s\n", message.c_str());
  return 1;
}

// classes.txt beside the output: the model's names added to it (written when absent). An existing
// entry that names one of the model's class IDs otherwise is an error: the detections' class IDs
// refer to this file.
bool merge_classes(const fs::path& path, const std::vector<std::string>& names, std::string* error) {
  std::map<int, std::string> have;
  if (!dqo::read_class_list(path.string(), &have, error)) return false;
  bool changed = false;
  for (size_t k = 0; k < names.size(); ++k) {
    const auto [it, added] = have.emplace(static_cast<int>(k), names[k]);
    changed = changed || added;
    if (it->second != names[k]) {
      *error = path.string() + " names class " + std::to_string(k) + " '" + it->second + "', the model '" + names[k] +
               "': write the detections elsewhere (--out)";
      return false;
    }
  }
  return !changed || dqo::write_class_list(path.string(), have, error);
}

// Whether a detections file holds any detection (the own format's writer leaves one with its header
// only where a dataset has none: replacing that loses nothing).
bool holds_detections(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    const size_t b = line.find_first_not_of(" \t\r");
    if (b != std::string::npos && line[b] != '#') return true;
  }
  return false;
}

}  // namespace

int main(int argc, char** argv) {
  std::string dataset, out;
  bool force = false;
  int frames = -1;
  dqo::detector::YoloParams params;
  params.classes = dqo::tools::default_class_names();
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    std::string error;
    if (dqo::tools::parse_detector_option(argc, argv, &i, &params, &error)) {
      if (!error.empty()) return usage_error(error);
    } else if (a == "-h" || a == "--help") {
      std::fputs(kUsage.c_str(), stdout);
      return 0;
    } else if (a == "--out" || a == "--frames") {
      if (i + 1 >= argc) return usage_error(a + " needs a value");
      const char* v = argv[++i];
      if (a == "--out") out = v;
      if (a == "--frames") {
        char* end = nullptr;
        const long n = std::strtol(v, &end, 10);
        if (end == v || *end != '\0' || n < 1) return usage_error("--frames takes a whole number >= 1");
        frames = static_cast<int>(n);
      }
    } else if (a == "--force") {
      force = true;
    } else if (!a.empty() && a[0] == '-') {
      return usage_error("unknown option " + a);
    } else if (dataset.empty()) {
      dataset = a;
    } else {
      return usage_error("unexpected argument " + a);
    }
  }
  if (dataset.empty()) return usage_error("no dataset folder given");
  if (params.model.empty()) return usage_error("--model is required");
  if (out.empty()) out = (fs::path(dataset) / "detections.txt").string();

  // Everything that can fail is checked before the long part.
  std::string error;
  dqo::DatasetReaderParams reader_params;
  reader_params.load_meshes = false;
  reader_params.tum.load_meshes = false;
  const auto source = dqo::open_dataset(dataset, reader_params, &error);
  if (!source) return fail(error);
  auto detector = dqo::detector::YoloDetector::create(params, &error);
  if (!detector) return fail(error);
  std::error_code ec;
  if (fs::exists(out, ec) && holds_detections(out) && !force) {
    return fail(out + " holds detections already: give --force to replace them, or --out elsewhere");
  }
  const fs::path out_dir = fs::absolute(out).parent_path();
  fs::create_directories(out_dir, ec);
  if (!fs::is_directory(out_dir, ec)) return fail("cannot create " + out_dir.string());
  if (!merge_classes(out_dir / "classes.txt", detector->class_names(), &error)) return fail(error);
  const fs::path masks_dir = out_dir / "detections_instance";
  if (detector->segments()) {
    fs::create_directories(masks_dir, ec);
    if (!fs::is_directory(masks_dir, ec)) return fail("cannot create " + masks_dir.string());
  }
  const bool by_stamp = source->format() == "tum";  // the TUM reader drops unpaired images: stamps are stable
  const int total = frames > 0 ? std::min(frames, source->num_frames()) : source->num_frames();
  std::fprintf(stderr, "dqo_detect: %s (%s, %d frames); %s: %s\n", dataset.c_str(), source->format().c_str(), total,
               params.model.c_str(), detector->layout().describe().c_str());

  std::ostringstream lines;
  lines << "# dqo_detect " << params.model << ": frame x1 y1 x2 y2 class_id score\n";
  std::map<std::string, int> per_class;
  size_t count = 0;
  double pre_ms = 0, infer_ms = 0, decode_ms = 0;
  dqo::ProgressBar bar("detecting", total);
  for (int f = 0; f < total; ++f) {
    const auto frame = source->read_frame(f, &error);
    if (!frame) return fail("frame " + std::to_string(f) + ": " + error);
    const dqo::detector::YoloDetections r = detector->detect(frame->rgb);
    pre_ms += r.preprocess_ms, infer_ms += r.inference_ms, decode_ms += r.decode_ms;
    char key[64];
    if (by_stamp) std::snprintf(key, sizeof key, "%.6f", frame->timestamp);
    else std::snprintf(key, sizeof key, "%d", frame->index);
    for (const dqo::Detection2d& d : r.detections) {
      char line[256];
      std::snprintf(line, sizeof line, "%s %.2f %.2f %.2f %.2f %d %.6g\n", key, d.box.x_min, d.box.y_min, d.box.x_max,
                    d.box.y_max, d.class_id, d.score);
      lines << line;
      ++per_class[d.class_name];
      ++count;
    }
    if (detector->segments()) {
      char name[32];
      std::snprintf(name, sizeof name, "%06d.png", frame->index);
      if (!dqo::write_png((masks_dir / name).string(), r.instance, &error)) return fail(error);
    }
    bar.update(f + 1);
  }
  if (!dqo::write_file_atomically(out, lines.str(), &error)) return fail(error);
  std::ostringstream classes;
  for (const auto& [name, n] : per_class) classes << ' ' << name << ':' << n;
  std::fprintf(stderr, "dqo_detect: %zu detections in %d frames (%s) -> %s\n", count, total,
               classes.str().empty() ? "none" : classes.str().c_str() + 1, out.c_str());
  if (total > 0) {
    std::fprintf(stderr, "dqo_detect: ms per frame: pre-processing %.1f, inference %.1f, decoding %.1f\n",
                 pre_ms / total, infer_ms / total, decode_ms / total);
  }
  return 0;
}
