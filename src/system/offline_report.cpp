#include "dqo_map/system/offline_report.h"

#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <vector>

#include "dqo_map/common/statistics.h"

namespace dqo::system {
namespace {

// Per-stage summary of a list of milliseconds.
std::string stage_json(const std::vector<double>& ms) {
  std::vector<double> sorted = ms;
  double total = 0.0, max = 0.0;
  for (const double m : ms) {
    total += m;
    max = std::max(max, m);
  }
  std::ostringstream o;
  o << "{\"count\": " << ms.size() << ", \"mean_ms\": " << (ms.empty() ? 0.0 : total / ms.size())
    << ", \"median_ms\": " << (ms.empty() ? 0.0 : median(sorted)) << ", \"max_ms\": " << max
    << ", \"total_s\": " << total / 1000.0 << ", \"per_item_ms\": [";
  for (size_t i = 0; i < ms.size(); ++i) o << (i ? ", " : "") << std::round(ms[i] * 100) / 100;
  o << "]}";
  return o.str();
}

// A distinct colour per object ID (0, the background, dark grey).
void id_colour(uint32_t id, uint8_t* rgb) {
  if (id == 0) {
    rgb[0] = rgb[1] = rgb[2] = 40;
    return;
  }
  uint32_t h = id * 2654435761u;  // Knuth's multiplicative hash: neighbouring IDs differ
  for (int c = 0; c < 3; ++c) {
    rgb[c] = static_cast<uint8_t>(80 + (h & 0xff) * 175 / 255);
    h >>= 8;
  }
}

}  // namespace

std::string json_quoted(const std::string& text) {
  std::string out = "\"";
  for (const char c : text) {
    if (c == '"' || c == '\\') out += '\\';
    if (static_cast<unsigned char>(c) >= 0x20) out += c;
  }
  return out + "\"";
}

double peak_memory_mb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;  // kilobytes on Linux
}

double mean_final_loss(const OfflineResult& run) {
  double sum = 0.0;
  for (const mapping::MappingReport& r : run.reports) sum += r.trainer.loss_last;
  return run.reports.empty() ? 0.0 : sum / static_cast<double>(run.reports.size());
}

std::string timings_json(const OfflineResult& run, const mapping::GaussianMapper& mapper,
                         const std::string& input, double mesh_seconds) {
  const double seconds = run.seconds;
  const PinholeCamera* camera = mapper.keyframe_poses().empty() ? nullptr
                                                                : &mapper.keyframe_poses()[0].camera;
  std::ostringstream t;
  t << "{\n  \"input\": " << json_quoted(input) << ",\n  \"width\": " << (camera ? camera->width : 0)
    << ", \"height\": " << (camera ? camera->height : 0) << ",\n  \"frames\": " << run.frames
    << ", \"keyframes\": " << run.keyframes << ", \"dropped_keyframes\": " << mapper.dropped()
    << ",\n  \"total_s\": " << seconds << ", \"frames_per_second\": "
    << (seconds > 0 ? run.frames / seconds : 0.0) << ", \"mesh_s\": " << mesh_seconds
    << ",\n  \"peak_memory_mb\": " << peak_memory_mb() << ", \"gaussians\": " << mapper.map_structure().size()
    << ", \"map_mb\": " << mapper.map_structure().bytes_used() / 1e6 << ", \"mean_final_loss\": " << mean_final_loss(run)
    << ",\n  \"stages\": {\n    \"read\": " << stage_json(run.timings.read_ms)
    << ",\n    \"pose\": " << stage_json(run.timings.pose_ms)
    << ",\n    \"objects\": " << stage_json(run.timings.objects_ms)
    << ",\n    \"mapping\": " << stage_json(run.timings.mapping_ms) << "\n  },\n  \"keyframes\": [";
  // One line per mapped keyframe: what the mapping stage did with it.
  for (size_t i = 0; i < run.reports.size(); ++i) {
    const mapping::MappingReport& r = run.reports[i];
    t << (i ? ",\n    " : "\n    ") << "{\"id\": " << r.keyframe_id << ", \"labelled\": "
      << (r.labelled ? "true" : "false") << ", \"ms\": " << std::round(r.total_ms * 10) / 10
      << ", \"added\": " << r.trainer.added_missing + r.trainer.added_error << ", \"pruned\": "
      << r.trainer.pruned_stale + r.trainer.pruned_oversized + r.trainer.pruned_invisible +
             r.trainer.pruned_budget
      << ", \"pruned_budget\": " << r.trainer.pruned_budget << ", \"loss_first\": " << r.trainer.loss_first
      << ", \"loss_last\": " << r.trainer.loss_last << ", \"label_ms\": " << std::round(r.label_ms * 10) / 10 << ", \"review_ms\": " << std::round(r.trainer.review_ms * 10) / 10
      << ", \"add_ms\": " << std::round(r.trainer.add_ms * 10) / 10 << ", \"train_ms\": "
      << std::round(r.trainer.train_ms * 10) / 10 << ", \"prune_ms\": " << std::round(r.trainer.prune_ms * 10) / 10
      << ", \"gaussians\": " << r.num_gaussians
      << ", \"bytes\": " << r.bytes << ", \"objects\": {";
    bool first_object = true;
    for (const auto& [id, n] : r.gaussians_per_object) {
      t << (first_object ? "" : ", ") << "\"" << id << "\": " << n;
      first_object = false;
    }
    t << "}}";
  }
  t << "\n  ]\n}\n";
  return t.str();
}

ImageRgb8 render_colour_image(const gs::RenderOutput& r) {
  ImageRgb8 out(r.width, r.height, 3, 0);
  for (size_t k = 0; k < out.data.size(); ++k) {
    out.data[k] = static_cast<uint8_t>(std::clamp(std::lround(r.rgb[k] * 255.f), 0L, 255L));
  }
  return out;
}

ImageRgb8 render_ids_image(const gs::RenderOutput& r) {
  ImageRgb8 out(r.width, r.height, 3, 0);
  for (size_t p = 0; p < r.alpha.size(); ++p) id_colour(r.alpha[p] > 0.5f ? r.dominant_id[p] : 0, &out.data[3 * p]);
  return out;
}

ImageRgb8 render_colour_and_ids(mapping::GaussianMapper& mapper, const mapping::KeyframePose& k) {
  gs::RenderOutput r;
  mapper.render(k.camera, k.T_wc, &r);
  const ImageRgb8 colour = render_colour_image(r), ids = render_ids_image(r);
  const int w = r.width, h = r.height;
  ImageRgb8 out(2 * w, h, 3, 0);
  for (int y = 0; y < h; ++y) {
    std::copy_n(&colour.at(0, y), 3 * w, &out.at(0, y));
    std::copy_n(&ids.at(0, y), 3 * w, &out.at(w, y));
  }
  return out;
}

}  // namespace dqo::system
