#include "dqo_map/sim/renderer.h"

#include <algorithm>
#include <atomic>
#include <climits>
#include <cmath>
#include <thread>
#include <vector>

#include "dqo_map/sim/clutter.h"

namespace dqo::sim {
namespace {

constexpr int kTile = 16;

// One scene object as seen from this frame's camera: everything per ray is a 3x3 product away.
struct View {
  const SceneObject* object = nullptr;
  int stat = -1;         // index into the per-object counters; -1 for the background
  Eigen::Matrix3d M;     // ray direction in the object frame = M * d_c (rotation / scale)
  Eigen::Vector3d o;     // camera centre in the object frame (the same for every ray)
  Eigen::Matrix3d R_wo;  // normals back to the world
  Aabb bounds;           // object frame, slightly padded
  int x0 = 0, y0 = 0, x1 = -1, y1 = -1;  // pixels it can cover (inclusive)
};

struct Stats {
  int64_t visible = 0;
  int64_t covered = 0;
  int min_x = INT_MAX, min_y = INT_MAX, max_x = -1, max_y = -1;
};

// Objects first: they are usually in front of the room, so the walls are then culled by depth.
std::vector<View> make_views(const Scene& scene, const SE3& T_wc) {
  const PinholeCamera& cam = scene.camera;
  const SE3 T_cw = T_wc.inverse();
  const Eigen::Matrix3d R_wc = T_wc.rotation();
  std::vector<View> views;
  auto add = [&](const SceneObject& obj, int stat) {
    View v;
    v.object = &obj;
    v.stat = stat;
    v.R_wo = obj.T_wo.rotation();
    const Eigen::Matrix3d R_ow = v.R_wo.transpose();
    const double inv_s = 1.0 / obj.scale;
    v.o = inv_s * (R_ow * (T_wc.translation() - obj.T_wo.translation()));
    v.M = inv_s * (R_ow * R_wc);
    v.bounds = obj.shape->bounds();
    if (v.bounds.empty()) return;
    // Padding keeps flat bounds (a quad's) from rejecting their own hits by rounding.
    const Eigen::Vector3d pad =
        Eigen::Vector3d::Constant(1e-9 * v.bounds.extent().maxCoeff() + 1e-12);
    v.bounds.min -= pad;
    v.bounds.max += pad;
    // The pixel rectangle of the part of the box in front of the near plane: its corners there,
    // and where its edges cross the plane. Conservative, and tight even for a wall that reaches
    // behind the camera (the floor seen from above covers only the lower part of the image).
    Eigen::Vector3d p_c[8];
    bool front[8];
    int n_front = 0;
    for (int k = 0; k < 8; ++k) {
      const Eigen::Vector3d c((k & 1) ? v.bounds.max.x() : v.bounds.min.x(),
                              (k & 2) ? v.bounds.max.y() : v.bounds.min.y(),
                              (k & 4) ? v.bounds.max.z() : v.bounds.min.z());
      p_c[k] = T_cw * (obj.T_wo * (obj.scale * c));
      front[k] = p_c[k].z() >= scene.near;
      n_front += front[k];
    }
    if (n_front == 0) return;
    double u0 = kInfinity, v0 = kInfinity, u1 = -kInfinity, v1 = -kInfinity;
    auto extend = [&](const Eigen::Vector3d& p) {
      const Eigen::Vector2d uv = cam.project(p);
      u0 = std::min(u0, uv.x());
      u1 = std::max(u1, uv.x());
      v0 = std::min(v0, uv.y());
      v1 = std::max(v1, uv.y());
    };
    for (int k = 0; k < 8; ++k) {
      if (front[k]) extend(p_c[k]);
      for (int axis = 0; axis < 3; ++axis) {
        const int j = k ^ (1 << axis);
        if (j < k || front[j] == front[k]) continue;
        const double s = (scene.near - p_c[k].z()) / (p_c[j].z() - p_c[k].z());
        Eigen::Vector3d p = p_c[k] + s * (p_c[j] - p_c[k]);
        p.z() = scene.near;
        extend(p);
      }
    }
    const double lim = 1e7;  // keeps the casts below defined for points near the near plane
    v.x0 = std::max(0, static_cast<int>(std::floor(std::max(u0, -lim))) - 1);
    v.y0 = std::max(0, static_cast<int>(std::floor(std::max(v0, -lim))) - 1);
    v.x1 = std::min(cam.width - 1, static_cast<int>(std::ceil(std::min(u1, lim))) + 1);
    v.y1 = std::min(cam.height - 1, static_cast<int>(std::ceil(std::min(v1, lim))) + 1);
    if (v.x0 > v.x1 || v.y0 > v.y1) return;
    views.push_back(v);
  };
  for (size_t i = 0; i < scene.objects.size(); ++i) add(scene.objects[i], static_cast<int>(i));
  for (const auto& obj : scene.background) add(obj, -1);
  return views;
}

uint8_t to_byte(float c) { return static_cast<uint8_t>(std::clamp(c, 0.0f, 1.0f) * 255.0f + 0.5f); }

class TileRenderer {
 public:
  TileRenderer(const Scene& scene, const SE3& T_wc, const std::vector<View>& views, Frame* frame)
      : scene_(scene),
        cam_(scene.camera),
        views_(views),
        frame_(frame),
        R_wc_(T_wc.rotation()),
        c_w_(T_wc.translation()) {}

  void run(std::atomic<int>* next_tile, std::vector<Stats>* stats) const {
    const int tiles_x = (cam_.width + kTile - 1) / kTile;
    const int tiles_y = (cam_.height + kTile - 1) / kTile;
    std::vector<int> candidates;
    candidates.reserve(views_.size());
    for (int tile = next_tile->fetch_add(1); tile < tiles_x * tiles_y;
         tile = next_tile->fetch_add(1)) {
      const int tx0 = (tile % tiles_x) * kTile, ty0 = (tile / tiles_x) * kTile;
      const int tx1 = std::min(cam_.width, tx0 + kTile) - 1;
      const int ty1 = std::min(cam_.height, ty0 + kTile) - 1;
      candidates.clear();
      for (size_t k = 0; k < views_.size(); ++k) {
        const View& v = views_[k];
        if (v.x0 <= tx1 && v.x1 >= tx0 && v.y0 <= ty1 && v.y1 >= ty0) {
          candidates.push_back(static_cast<int>(k));
        }
      }
      for (int y = ty0; y <= ty1; ++y) {
        for (int x = tx0; x <= tx1; ++x) pixel(x, y, candidates, stats);
      }
    }
  }

 private:
  void pixel(int x, int y, const std::vector<int>& candidates, std::vector<Stats>* stats) const {
    // d_c.z = 1: the ray parameter of a hit is its depth.
    const Eigen::Vector3d d_c((x - cam_.cx) / cam_.fx, (y - cam_.cy) / cam_.fy, 1.0);
    const double near = scene_.near;
    double best_t = kInfinity;
    int best = -1;
    Hit best_hit;
    for (const int k : candidates) {
      const View& v = views_[k];
      Ray ray;
      ray.origin = v.o;
      ray.direction = v.M * d_c;
      const Eigen::Vector3d inv = ray.direction.cwiseInverse();
      double t_enter;
      Hit hit;
      if (v.stat >= 0) {
        // Coverage counts every ray that meets the object, occluded or not, so objects are not
        // cut short by depth: their nearest hit is found whatever lies in front, and then
        // competes for the pixel. (Objects come before the background, so little is wasted.)
        if (!v.bounds.intersect(ray.origin, inv, near, kInfinity, &t_enter)) continue;
        if (!v.object->shape->intersect(ray, near, kInfinity, &hit)) continue;
        ++(*stats)[v.stat].covered;
        if (hit.t < best_t) {
          best_t = hit.t;
          best = k;
          best_hit = hit;
        }
      } else {
        if (!v.bounds.intersect(ray.origin, inv, near, best_t, &t_enter)) continue;
        if (v.object->shape->intersect(ray, near, best_t, &hit)) {
          best_t = hit.t;
          best = k;
          best_hit = hit;
        }
      }
    }
    const size_t idx = frame_->depth.index(x, y);
    if (best < 0) {
      frame_->depth.data[idx] = 0.0f;
      frame_->instance.data[idx] = 0;
      for (int c = 0; c < 3; ++c)
        frame_->rgb.data[3 * idx + c] = to_byte(scene_.background_colour[c]);
      return;
    }
    const View& v = views_[best];
    frame_->depth.data[idx] = static_cast<float>(best_t);
    if (v.stat >= 0) {
      Stats& s = (*stats)[v.stat];
      ++s.visible;
      s.min_x = std::min(s.min_x, x);
      s.max_x = std::max(s.max_x, x);
      s.min_y = std::min(s.min_y, y);
      s.max_y = std::max(s.max_y, y);
      frame_->instance.data[idx] = static_cast<uint16_t>(v.object->id);
    } else {
      frame_->instance.data[idx] = 0;
    }
    // Two-sided Lambertian shading in the world frame.
    const Eigen::Vector3d d_w = R_wc_ * d_c;
    Eigen::Vector3d n_w = v.R_wo * best_hit.normal;
    const double d_norm = d_w.norm();
    double cos_view = n_w.dot(d_w) / d_norm;
    if (cos_view > 0.0) {
      n_w = -n_w;
    } else {
      cos_view = -cos_view;
    }
    const Eigen::Vector3d p_w = c_w_ + best_t * d_w;
    // The pixel's size on the surface (in the texture's units), stretched at grazing angles.
    const double footprint = best_t * d_norm / cam_.fx / std::max(cos_view, 0.25) / v.object->scale;
    const Eigen::Vector3f albedo = evaluate_texture(
        v.object->material_of(best_hit.part), best_hit.tex_point, best_hit.tex_normal, footprint);
    const Eigen::Vector3f colour = albedo.cwiseProduct(irradiance(scene_.lighting, p_w, n_w));
    for (int c = 0; c < 3; ++c) frame_->rgb.data[3 * idx + c] = to_byte(colour[c]);
  }

  const Scene& scene_;
  const PinholeCamera& cam_;
  const std::vector<View>& views_;
  Frame* frame_;
  Eigen::Matrix3d R_wc_;
  Eigen::Vector3d c_w_;
};

}  // namespace

Renderer::Renderer(const Scene& scene, int threads)
    : scene_(scene),
      threads_(threads > 0 ? threads : std::max(1u, std::thread::hardware_concurrency())) {
  detection_context_.width = scene.camera.width;
  detection_context_.height = scene.camera.height;
  detection_context_.class_names = scene.classes;
  for (const auto& obj : scene.objects) detection_context_.class_of_object[obj.id] = obj.class_id;
  detection_context_.camera = scene.camera;
  const DetectionNoiseParams& det = scene.noise.detection;
  if (scene.noise.enabled && det.false_positive_rate > 0.0 && det.false_positive_recurring > 0.0) {
    detection_context_.clutter = place_clutter_spots(scene, det.clutter_spots, scene.seed);
  }
}

Frame Renderer::render(int frame_index, bool noise) const {
  const TrajectoryPose& pose = scene_.trajectory.at(static_cast<size_t>(frame_index));
  return render_view(pose.T_wc, frame_index, pose.timestamp, noise);
}

Frame Renderer::render_view(const SE3& T_wc, int frame_index, double timestamp, bool noise) const {
  const PinholeCamera& cam = scene_.camera;
  Frame frame;
  frame.index = frame_index;
  frame.timestamp = timestamp;
  frame.T_wc = T_wc;
  frame.has_pose = true;
  frame.rgb = ImageRgb8(cam.width, cam.height, 3);
  frame.depth = DepthImage(cam.width, cam.height, 1);
  frame.instance = InstanceImage(cam.width, cam.height, 1);

  const std::vector<View> views = make_views(scene_, T_wc);
  const TileRenderer tiles(scene_, T_wc, views, &frame);
  std::atomic<int> next_tile{0};
  const int n_threads = std::max(1, threads_);
  std::vector<std::vector<Stats>> stats(n_threads, std::vector<Stats>(scene_.objects.size()));
  std::vector<std::thread> workers;
  for (int i = 1; i < n_threads; ++i) {
    workers.emplace_back([&, i] { tiles.run(&next_tile, &stats[i]); });
  }
  tiles.run(&next_tile, &stats[0]);
  for (auto& w : workers) w.join();

  // Counts, minima and maxima merge the same way whatever tile went to which thread.
  for (size_t i = 0; i < scene_.objects.size(); ++i) {
    Stats total;
    for (const auto& s : stats) {
      total.visible += s[i].visible;
      total.covered += s[i].covered;
      total.min_x = std::min(total.min_x, s[i].min_x);
      total.min_y = std::min(total.min_y, s[i].min_y);
      total.max_x = std::max(total.max_x, s[i].max_x);
      total.max_y = std::max(total.max_y, s[i].max_y);
    }
    if (total.visible == 0) continue;
    FrameObject fo;
    fo.id = scene_.objects[i].id;
    fo.box = Box2d{total.min_x - 0.5, total.min_y - 0.5, total.max_x + 0.5, total.max_y + 0.5}.clip(
        cam.width, cam.height);
    fo.visible_fraction = static_cast<double>(total.visible) / static_cast<double>(total.covered);
    frame.objects.push_back(fo);
  }
  std::sort(frame.objects.begin(), frame.objects.end(),
            [](const FrameObject& a, const FrameObject& b) { return a.id < b.id; });

  const bool noisy = noise && scene_.noise.enabled;
  if (noisy) {
    apply_sensor_noise(scene_.noise.sensor, scene_.seed, n_threads, &frame);
  }
  frame.detections =
      simulate_detections(frame, detection_context_, scene_.noise.detection, noisy, scene_.seed);
  return frame;
}

}  // namespace dqo::sim
