#include "dqo_map/sim/clutter.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "dqo_map/sim/random.h"

namespace dqo::sim {
namespace {

double uniform(std::mt19937_64& rng) {
  return (static_cast<double>(rng() >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}

int index(std::mt19937_64& rng, int n) {
  return std::min(n - 1, static_cast<int>(uniform(rng) * n));
}

// The nearest hit of the world ray c_w + t d_w on `obj`, or infinity (t is the world parameter:
// the object frame's ray is scaled with the object, so its t is the same).
double hit_distance(const SceneObject& obj, const Eigen::Vector3d& c_w, const Eigen::Vector3d& d_w,
                    double near) {
  const Eigen::Matrix3d R_ow = obj.T_wo.rotation().transpose();
  const double inv_s = 1.0 / obj.scale;
  Ray ray;
  ray.origin = inv_s * (R_ow * (c_w - obj.T_wo.translation()));
  ray.direction = inv_s * (R_ow * d_w);
  Hit hit;
  return obj.shape->intersect(ray, near, kInfinity, &hit) ? hit.t : kInfinity;
}

struct Sphere {
  Eigen::Vector3d centre;
  double radius;
};

}  // namespace

std::vector<ClutterSpot> place_clutter_spots(const Scene& scene, int count, uint64_t seed) {
  std::vector<ClutterSpot> spots;
  if (count <= 0 || scene.trajectory.empty() || scene.classes.empty() || scene.background.empty())
    return spots;
  std::vector<int> class_ids;
  for (const auto& [id, name] : scene.classes) class_ids.push_back(id);
  std::vector<Sphere> objects;
  for (const SceneObject& obj : scene.objects) {
    const Aabb b = obj.shape->bounds();
    if (b.empty()) continue;
    const Eigen::Vector3d centre_o = 0.5 * (b.min + b.max);
    objects.push_back({obj.T_wo * (obj.scale * centre_o), 0.5 * obj.scale * (b.max - b.min).norm()});
  }
  const PinholeCamera& cam = scene.camera;
  std::mt19937_64 rng(hash_combine(seed, 0xc1a77e5b075ULL));
  for (int attempt = 0; attempt < 100 * count && static_cast<int>(spots.size()) < count;
       ++attempt) {
    // Every draw of an attempt is made whatever its outcome.
    const int frame = index(rng, static_cast<int>(scene.trajectory.size()));
    const double fu = 0.1 + 0.8 * uniform(rng), fv = 0.1 + 0.8 * uniform(rng);
    const double width = 0.08 + 0.2 * uniform(rng);
    const double height = width * (0.5 + uniform(rng));
    const int cls = class_ids[index(rng, static_cast<int>(class_ids.size()))];

    const SE3& T_wc = scene.trajectory[frame].T_wc;
    const Eigen::Vector3d d_c((fu * cam.width - 0.5 - cam.cx) / cam.fx,
                              (fv * cam.height - 0.5 - cam.cy) / cam.fy, 1.0);
    const Eigen::Vector3d d_w = T_wc.rotation() * d_c;
    const Eigen::Vector3d c_w = T_wc.translation();
    double t_background = kInfinity, t_object = kInfinity;
    for (const SceneObject& obj : scene.background)
      t_background = std::min(t_background, hit_distance(obj, c_w, d_w, scene.near));
    for (const SceneObject& obj : scene.objects)
      t_object = std::min(t_object, hit_distance(obj, c_w, d_w, scene.near));
    // t is depth (d_c.z = 1).
    if (!(t_background < t_object) || t_background < 0.3 || t_background > 4.0) continue;
    const Eigen::Vector3d p_w = c_w + t_background * d_w;
    const bool near_object = std::any_of(objects.begin(), objects.end(), [&](const Sphere& s) {
      return (p_w - s.centre).norm() < s.radius + 0.1;
    });
    const bool near_spot = std::any_of(spots.begin(), spots.end(), [&](const ClutterSpot& s) {
      return (p_w - s.p_w).norm() < 0.3;
    });
    if (near_object || near_spot) continue;
    spots.push_back({p_w, width, height, cls});
  }
  return spots;
}

}  // namespace dqo::sim
