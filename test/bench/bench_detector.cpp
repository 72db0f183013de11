// bench_detector: the YOLO detector's costs on this CPU (issue 13).
//   1. Decoding and NMS of a YOLOv8 output with 8400 candidates ([1, 84, 8400], 80 classes): 30
//      objects, each seen by 12 overlapping candidates above the threshold, the rest below it (as a
//      trained model's scores fall), and the same for YOLOv5's [1, 25200, 85]; median of 200. The
//      instance image of a -seg output with those 30 detections.
//   2. Full inference at 640x640 of a random-weight network of YOLOv8n's size (3.2 M parameters,
//      8.7 GFLOPs; test/bench/yolo_random_model.py exports it with Debian's python3-torch) on a
//      640x480 image: pre-processing, inference and decoding, median of --repeats after 3 warm-ups,
//      at each thread count of --threads. With --model, that model at --input-size (e.g. the real
//      YOLOX-Nano: --model ../shared/models/yolox_nano/yolox_nano.onnx --input-size 416x416); its
//      time on real frames: dqo_detect's per-frame figures.
//
//   bench_detector [--repeats 20] [--threads 1,2] [--model M.onnx (instead of exporting one)] [--input-size WxH]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "dqo_map/common/statistics.h"
#include "dqo_map/common/text_util.h"
#include "dqo_map/detector/yolo_decode.h"
#include "dqo_map/detector/yolo_detector.h"
#include "dqo_map/detector/yolo_layout.h"
#include "dqo_map/detector/yolo_masks.h"

namespace {

using namespace dqo::detector;
using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

// A YOLO output with `objects` objects of `per_object` candidates each above 0.25, the rest at
// scores a trained model gives background (< 0.05).
std::vector<float> synthetic_output(const OutputLayout& l, int objects, int per_object, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  const int n = l.num_candidates, per = l.values_per_candidate(), first = l.objectness() ? 5 : 4;
  std::vector<float> out(static_cast<size_t>(n) * per);
  auto set = [&](int j, int v, float x) {
    out[l.channels_first() ? static_cast<size_t>(v) * n + j : static_cast<size_t>(j) * per + v] = x;
  };
  for (int j = 0; j < n; ++j) {
    const int obj = j < objects * per_object ? j / per_object : -1;
    float cx = 640 * u(rng), cy = 640 * u(rng), w = 10 + 200 * u(rng), h = 10 + 200 * u(rng);
    if (obj >= 0) {  // candidates of one object: boxes a few pixels apart
      std::mt19937 orng(obj);
      std::uniform_real_distribution<float> ou(0.f, 1.f);
      cx = 640 * ou(orng) + 4 * u(rng), cy = 640 * ou(orng) + 4 * u(rng);
      w = 40 + 100 * ou(orng), h = 40 + 100 * ou(orng);
    }
    set(j, 0, cx), set(j, 1, cy), set(j, 2, w), set(j, 3, h);
    if (l.objectness()) set(j, 4, obj >= 0 ? 0.9f : 0.05f * u(rng));
    for (int c = 0; c < l.num_classes; ++c) set(j, first + c, 0.05f * u(rng));
    if (obj >= 0) set(j, first + obj % l.num_classes, 0.5f + 0.4f * u(rng));
    for (int m = 0; m < l.mask_dim; ++m) set(j, first + l.num_classes + m, 2.f * u(rng) - 1.f);  // -seg
  }
  return out;
}

void bench_decode(const char* name, const std::vector<std::vector<int>>& shapes, int input = 640) {
  OutputLayout l;
  std::string error;
  if (!identify_layout(shapes, YoloLayout::kAuto, 80, input, input, &l, &error)) {
    std::fprintf(stderr, "bench_detector: %s\n", error.c_str());
    std::exit(1);
  }
  const std::vector<float> out = synthetic_output(l, 30, 12, 1);
  DecodeParams p;
  std::vector<double> decode, nms;
  size_t candidates = 0, kept = 0;
  for (int r = 0; r < 220; ++r) {
    auto t = Clock::now();
    const std::vector<Candidate> c = decode_candidates(out.data(), l, p);
    const double d = ms_since(t);
    t = Clock::now();
    const std::vector<Candidate> k = non_max_suppression(c, p);
    const double s = ms_since(t);
    if (r >= 20) decode.push_back(d), nms.push_back(s);
    candidates = c.size(), kept = k.size();
  }
  std::printf("decode %-22s %5d candidates: decoding %.3f ms, NMS %.3f ms (%zu above 0.25 -> %zu kept); median of 200\n",
              name, l.num_candidates, dqo::median(decode), dqo::median(nms), candidates, kept);
}

// The instance image of a -seg model: 30 detections (boxes of 40-140 pixels) with 32 coefficients on
// 160x160 prototypes, into a 640x480 image.
void bench_masks() {
  OutputLayout l;
  std::string error;
  if (!identify_layout({{1, 116, 8400}, {1, 32, 160, 160}}, YoloLayout::kAuto, 80, 640, 640, &l, &error)) std::exit(1);
  const std::vector<float> out = synthetic_output(l, 30, 12, 2);
  std::mt19937 rng(5);
  std::normal_distribution<float> n(0.f, 1.f);
  std::vector<float> protos(32 * 160 * 160);
  for (float& p : protos) p = n(rng);
  DecodeParams p;
  const std::vector<Candidate> kept = non_max_suppression(decode_candidates(out.data(), l, p), p);
  const Letterbox lb = Letterbox::make(640, 480, 640, 640);
  std::vector<double> ms;
  size_t pixels = 0;
  for (int r = 0; r < 55; ++r) {
    const auto t = Clock::now();
    const dqo::InstanceImage inst = instance_from_masks(out.data(), protos.data(), l, kept, lb, 0.5f);
    if (r >= 5) ms.push_back(ms_since(t));
    pixels = 0;
    for (uint16_t v : inst.data) pixels += v != 0;
  }
  std::printf("masks  YOLOv8-seg, %zu detections, 32 x 160x160 prototypes -> 640x480: %.2f ms (%zu pixels labelled); "
              "median of 50\n",
              kept.size(), dqo::median(ms), pixels);
}

std::vector<int> parse_list(const char* s) {
  std::vector<int> out;
  for (const std::string& item : dqo::text::split_list(s)) out.push_back(std::atoi(item.c_str()));
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  int repeats = 20;
  std::vector<int> threads = {1, 2};
  std::string model;
  int input_w = 640, input_h = 640;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--repeats")) repeats = std::max(1, std::atoi(argv[i + 1]));
    else if (!std::strcmp(argv[i], "--threads")) threads = parse_list(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--model")) model = argv[i + 1];
    else if (!std::strcmp(argv[i], "--input-size") && std::sscanf(argv[i + 1], "%dx%d", &input_w, &input_h) == 2) continue;
    else {
      std::fprintf(stderr, "usage: bench_detector [--repeats N] [--threads 1,2] [--model M.onnx] [--input-size WxH]\n");
      return 2;
    }
  }
  bench_decode("YOLOv8 [1, 84, 8400]", {{1, 84, 8400}});
  bench_decode("YOLOv5 [1, 25200, 85]", {{1, 25200, 85}});
  bench_decode("YOLOX [1, 3549, 85] @416", {{1, 3549, 85}}, 416);
  bench_masks();

  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "dqo_bench_detector";
  std::filesystem::create_directories(dir);
  if (model.empty()) {
    model = (dir / "yolov8n_random.onnx").string();
    const std::string cmd = "/usr/bin/python3 " DQO_SOURCE_DIR "/test/bench/yolo_random_model.py " + model +
                            " 2>" + (dir / "export.log").string();
    std::printf("exporting a random-weight YOLOv8n-sized network: ");
    std::fflush(stdout);
    if (std::system(cmd.c_str()) != 0) {
      std::printf("failed (needs Debian's python3-torch and python3-onnx: apt install python3-torch python3-onnx; log "
                  "%s)\ninference: not measured\n",
                  (dir / "export.log").string().c_str());
      return 0;
    }
  }
  YoloParams params;
  params.model = model;
  params.classes = DQO_SOURCE_DIR "/config/coco.names";
  params.input_width = input_w, params.input_height = input_h;
  std::string error;
  auto detector = YoloDetector::create(params, &error);
  if (!detector) {
    std::fprintf(stderr, "bench_detector: %s\n", error.c_str());
    return 1;
  }
  dqo::ImageRgb8 image(640, 480, 3);
  std::mt19937 rng(3);
  for (auto& v : image.data) v = static_cast<uint8_t>(rng());
  for (const int t : threads) {
    cv::setNumThreads(t);
    std::vector<double> pre, infer, decode, total;
    size_t detections = 0;
    for (int r = 0; r < repeats + 3; ++r) {
      const auto t0 = Clock::now();
      const YoloDetections d = detector->detect(image);
      const double all = ms_since(t0);
      if (r < 3) continue;
      pre.push_back(d.preprocess_ms), infer.push_back(d.inference_ms), decode.push_back(d.decode_ms);
      total.push_back(all);
      detections = d.detections.size();
    }
    std::printf("inference %dx%d (%s; %s) on a 640x480 image, %d thread%s: pre-processing %.2f ms, inference %.1f ms, decoding %.2f ms, "
                "all %.1f ms per frame (%.1f frames/s), %zu detections; median of %d\n",
                input_w, input_h, detector->layout().describe().c_str(),
                detector->input_convention().describe().c_str(), t, t == 1 ? "" : "s", dqo::median(pre), dqo::median(infer),
                dqo::median(decode), dqo::median(total), 1000.0 / dqo::median(total), detections, repeats);
  }
  return 0;
}
