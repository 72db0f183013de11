// dqo_render_meshes: a contact sheet of meshes, one row each, seen from three sides (grey, lit), so
// that the object meshes of a run can be looked at without a 3D viewer (scripts/real_data writes
// one beside its meshes).
//
//   dqo_render_meshes --out SHEET.png [--size N] [--elevation DEG] MESH.ply[=LABEL] ...
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "dqo_map/io/image_io.h"
#include "dqo_map/io/mesh_io.h"
#include "dqo_map/sim/mesh_views.h"

namespace {

constexpr char kUsage[] =
    "usage: dqo_render_meshes --out SHEET.png [--size N] [--elevation DEG] MESH.ply[=LABEL] ...\n"
    "  --out SHEET.png  the contact sheet: a row per mesh, three views each (map z up)\n"
    "  --size N         pixels per view (default 320)\n"
    "  --elevation DEG  the cameras' height above the horizontal (default 30)\n"
    "  MESH.ply=LABEL   a mesh (PLY or OBJ) and the text over its row (default: the file name)\n"
    "A mesh that cannot be read or is empty gets a row that says so; the exit status is 1 when no\n"
    "mesh could be drawn.\n";

int usage_error(const std::string& message) {
  std::fprintf(stderr, "dqo_render_meshes: %s\n%s", message.c_str(), kUsage);
  return 2;
}

// Text on an RGB image in place (OpenCV draws into the buffer; the channel order is the caller's).
void put_label(dqo::ImageRgb8* image, int x, int y, const std::string& text) {
  cv::Mat mat(image->height, image->width, CV_8UC3, image->data.data());
  cv::putText(mat, text, cv::Point(x, y), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(255, 255, 255), 3, cv::LINE_AA);
  cv::putText(mat, text, cv::Point(x, y), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(20, 20, 20), 1, cv::LINE_AA);
}

}  // namespace

int main(int argc, char** argv) {
  std::string out;
  dqo::sim::MeshViewParams params;
  std::vector<std::pair<std::string, std::string>> meshes;  // path, label
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> const char* { return i + 1 < argc ? argv[++i] : nullptr; };
    if (a == "-h" || a == "--help") {
      std::printf("%s", kUsage);
      return 0;
    } else if (a == "--out") {
      const char* v = value();
      if (!v) return usage_error("--out needs a file");
      out = v;
    } else if (a == "--size") {
      const char* v = value();
      params.size = v ? std::atoi(v) : 0;
      if (params.size < 32 || params.size > 4096) return usage_error("--size must be 32..4096");
    } else if (a == "--elevation") {
      const char* v = value();
      if (!v) return usage_error("--elevation needs degrees");
      params.elevation_deg = std::atof(v);
    } else if (!a.empty() && a[0] == '-') {
      return usage_error("unknown option " + a);
    } else {
      const size_t eq = a.find('=');
      const std::string path = a.substr(0, eq);
      meshes.emplace_back(path, eq == std::string::npos ? std::filesystem::path(path).filename().string()
                                                        : a.substr(eq + 1));
    }
  }
  if (out.empty()) return usage_error("--out SHEET.png is required");
  if (meshes.empty()) return usage_error("no mesh given");

  const int columns = static_cast<int>(params.azimuth_deg.size());
  dqo::ImageRgb8 sheet(columns * params.size, static_cast<int>(meshes.size()) * params.size, 3, 255);
  int drawn = 0;
  for (size_t row = 0; row < meshes.size(); ++row) {
    const auto& [path, label] = meshes[row];
    std::string error, note;
    const std::optional<dqo::TriangleMesh> mesh = dqo::load_mesh(path, &error);
    std::vector<dqo::sim::MeshView> views;
    if (!mesh) {
      note = "cannot read: " + error;
    } else if (mesh->empty()) {
      note = "empty mesh";
    } else {
      views = dqo::sim::render_mesh_views(*mesh, params, 0);
      ++drawn;
    }
    for (size_t c = 0; c < views.size(); ++c) {
      for (int y = 0; y < params.size; ++y) {
        for (int x = 0; x < params.size; ++x) {
          for (int ch = 0; ch < 3; ++ch) {
            sheet.at(static_cast<int>(c) * params.size + x, static_cast<int>(row) * params.size + y, ch) =
                views[c].rgb.at(x, y, ch);
          }
        }
      }
    }
    // A thin line between rows.
    for (int x = 0; x < sheet.width && row > 0; ++x) {
      for (int ch = 0; ch < 3; ++ch) sheet.at(x, static_cast<int>(row) * params.size, ch) = 160;
    }
    put_label(&sheet, 8, static_cast<int>(row) * params.size + 20, label);
    if (!note.empty()) {
      put_label(&sheet, 8, static_cast<int>(row) * params.size + 44, note);
      std::fprintf(stderr, "dqo_render_meshes: %s: %s\n", path.c_str(), note.c_str());
    }
    std::printf("row %zu: %s (%s)%s%s\n", row + 1, label.c_str(), path.c_str(), note.empty() ? "" : ": ",
                note.c_str());
  }
  std::string error;
  if (!dqo::write_png(out, sheet, &error)) {
    std::fprintf(stderr, "dqo_render_meshes: cannot write %s: %s\n", out.c_str(), error.c_str());
    return 1;
  }
  std::printf("wrote %s (%d of %zu meshes drawn, %d views each)\n", out.c_str(), drawn, meshes.size(), columns);
  return drawn > 0 ? 0 : 1;
}
