#include "dqo_map/sim/detections.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "dqo_map/sim/random.h"

namespace dqo::sim {
namespace {

// Portable draws from mt19937_64 (whose raw output the standard fixes, unlike its distributions).
struct Draw {
  std::mt19937_64 rng;
  double uniform() { return (static_cast<double>(rng() >> 11) + 0.5) * (1.0 / 9007199254740992.0); }
  double gaussian() {
    const double u1 = uniform(), u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
  }
  int index(int n) { return std::min(n - 1, static_cast<int>(uniform() * n)); }
};

std::string name_of(const DetectionContext& ctx, int class_id) {
  const auto it = ctx.class_names.find(class_id);
  return it != ctx.class_names.end() ? it->second : std::string();
}

}  // namespace

std::vector<Detection2d> simulate_detections(const Frame& frame, const DetectionContext& ctx,
                                             const DetectionNoiseParams& params, bool noise,
                                             uint64_t seed) {
  std::vector<FrameObject> objects = frame.objects;
  std::sort(objects.begin(), objects.end(),
            [](const FrameObject& a, const FrameObject& b) { return a.id < b.id; });
  std::vector<int> class_ids;
  for (const auto& [id, name] : ctx.class_names) class_ids.push_back(id);

  Draw draw{std::mt19937_64(
      hash_combine(hash_combine(seed, 0xde7ec7105ULL), static_cast<uint64_t>(frame.index)))};
  std::vector<Detection2d> out;
  for (const FrameObject& obj : objects) {
    const auto cls = ctx.class_of_object.find(obj.id);
    if (cls == ctx.class_of_object.end()) continue;
    if (obj.visible_fraction < params.min_visible_fraction) continue;
    if (std::min(obj.box.width(), obj.box.height()) < params.min_box_px) continue;
    Detection2d det;
    det.class_id = cls->second;
    det.gt_id = obj.id;
    det.box = obj.box;
    if (!noise) {
      det.class_name = name_of(ctx, det.class_id);
      out.push_back(det);
      continue;
    }
    // Every draw is made whatever the outcome, so one object's fate does not shift the random
    // stream of the next.
    const double u_miss = draw.uniform(), u_confuse = draw.uniform(), u_fp = draw.uniform();
    const int other = draw.index(std::max<int>(1, static_cast<int>(class_ids.size()) - 1));
    double jitter[4];
    for (double& j : jitter) j = params.box_jitter_px * draw.gaussian();
    const double score = 0.5 + 0.5 * draw.uniform();
    Detection2d fp;
    fp.class_id = class_ids.empty() ? det.class_id
                                    : class_ids[draw.index(static_cast<int>(class_ids.size()))];
    const double fw = 20.0 + draw.uniform() * 0.3 * ctx.width;
    const double fh = 20.0 + draw.uniform() * 0.3 * ctx.height;
    const double fx = draw.uniform() * std::max(1.0, ctx.width - fw);
    const double fy = draw.uniform() * std::max(1.0, ctx.height - fh);
    fp.score = static_cast<float>(0.3 + 0.5 * draw.uniform());

    if (u_miss >= params.miss_rate) {
      if (u_confuse < params.confusion_rate && class_ids.size() > 1) {
        // The other-th class that is not the true one.
        int k = 0;
        for (const int c : class_ids) {
          if (c == det.class_id) continue;
          if (k++ == other) {
            det.class_id = c;
            break;
          }
        }
      }
      Box2d b = obj.box;
      b.x_min += jitter[0];
      b.y_min += jitter[1];
      b.x_max += jitter[2];
      b.y_max += jitter[3];
      if (b.x_min > b.x_max) std::swap(b.x_min, b.x_max);
      if (b.y_min > b.y_max) std::swap(b.y_min, b.y_max);
      det.box = b.clip(ctx.width, ctx.height);
      det.score = static_cast<float>(score);
      det.class_name = name_of(ctx, det.class_id);
      if (det.box.valid()) out.push_back(det);
    }
    if (u_fp < params.false_positive_rate) {
      fp.box = Box2d{fx, fy, fx + fw, fy + fh}.clip(ctx.width, ctx.height);
      fp.class_name = name_of(ctx, fp.class_id);
      fp.gt_id = 0;
      if (fp.box.valid()) out.push_back(fp);
    }
  }
  // Boxes as a detector publishes them (DetectionArray holds float32 pixels): a dataset folder and
  // a bag of the same frames then carry the same numbers, and so map alike.
  for (Detection2d& d : out) {
    d.box.x_min = static_cast<float>(d.box.x_min), d.box.y_min = static_cast<float>(d.box.y_min);
    d.box.x_max = static_cast<float>(d.box.x_max), d.box.y_max = static_cast<float>(d.box.y_max);
  }
  return out;
}

}  // namespace dqo::sim
