#pragma once
// Test fixtures for the detector: YOLO outputs written from candidates the test chooses, and ONNX
// models whose outputs are those constants, built by test/detector/make_yolo_model.py with Debian's
// python3-onnx (the model computes them from the image with zero weights, so they hold for any image).

#include <gtest/gtest.h>
#include <stdlib.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace dqo::detector::test {

// A candidate as the network gives it: box centre and size in input pixels.
struct RawCandidate {
  float cx, cy, w, h;
  int cls;
  float score;             // the class score
  float objectness = 1.f;  // YOLOv5 only
  std::vector<float> mask_coeffs;
};

// The detection output of `candidates` (padded with low-score ones to `n`, spread over a 64x64
// input as a trained model's background candidates are, so that check_output takes them for boxes)
// in a layout: v5 rows [n, 5 + nc + nm] or v8 columns [4 + nc + nm, n]. Values row-major.
inline std::vector<float> make_output(const std::vector<RawCandidate>& candidates, int n, int nc, int nm, bool v5) {
  const int per = (v5 ? 5 : 4) + nc + nm;
  std::vector<float> out(static_cast<size_t>(per) * n, 0.f);
  for (int j = 0; j < n; ++j) {
    RawCandidate c = j < static_cast<int>(candidates.size())
                         ? candidates[j]
                         : RawCandidate{4.f + (j * 13) % 56, 4.f + (j * 23) % 56, 4.f, 4.f, j % nc, 0.01f, 0.02f, {}};
    std::vector<float> v(per, 0.f);
    v[0] = c.cx, v[1] = c.cy, v[2] = c.w, v[3] = c.h;
    const int first = v5 ? 5 : 4;
    if (v5) v[4] = c.objectness;
    for (int k = 0; k < nc; ++k) v[first + k] = k == c.cls ? c.score : 0.5f * c.score;  // the others lower
    for (int m = 0; m < nm && m < static_cast<int>(c.mask_coeffs.size()); ++m) v[first + nc + m] = c.mask_coeffs[m];
    for (int k = 0; k < per; ++k) {
      if (v5) out[static_cast<size_t>(j) * per + k] = v[k];
      else out[static_cast<size_t>(k) * n + j] = v[k];
    }
  }
  return out;
}

class TempDir {
 public:
  TempDir() {
    std::string pattern = (std::filesystem::temp_directory_path() / "dqo_detector_test_XXXXXX").string();
    if (!mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  std::filesystem::path path_;
};

inline void write_values(const std::string& path, const std::vector<float>& values) {
  std::ofstream f(path);
  f.precision(9);
  for (float v : values) f << v << '\n';
}

inline void write_text(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

// Builds OUT.onnx with input WxH and the given outputs (shape, values); false (and the tool's output
// in the test log) when python3-onnx or the script fails.
struct ModelOutput {
  std::vector<int> shape;
  std::vector<float> values;
};
inline bool make_model(const TempDir& dir, const std::string& name, int w, int h, const std::vector<ModelOutput>& outputs,
                       bool topk = false) {
  std::string cmd = "/usr/bin/python3 " DQO_SOURCE_DIR "/test/detector/make_yolo_model.py " + dir.file(name) +
                    " --input " + std::to_string(w) + "x" + std::to_string(h);
  if (topk) cmd += " --topk";
  for (size_t k = 0; k < outputs.size(); ++k) {
    const std::string values = dir.file(name + ".out" + std::to_string(k) + ".txt");
    write_values(values, outputs[k].values);
    std::string shape;
    for (size_t d = 0; d < outputs[k].shape.size(); ++d) shape += (d ? "," : "") + std::to_string(outputs[k].shape[d]);
    cmd += " --output " + shape + ":" + values;
  }
  const int rc = std::system((cmd + " 2>&1").c_str());
  if (rc != 0) ADD_FAILURE() << "building the test model failed (is Debian's python3-onnx installed? scripts/test "
                                "installs it): " << cmd;
  return rc == 0;
}

}  // namespace dqo::detector::test
