#include "dqo_map/sim/lighting.h"

#include <algorithm>

namespace dqo::sim {

Eigen::Vector3f irradiance(const Lighting& lighting, const Eigen::Vector3d& p,
                           const Eigen::Vector3d& n) {
  Eigen::Vector3f e = lighting.ambient;
  for (const Light& light : lighting.lights) {
    double lambert;
    if (light.type == Light::Type::kDirectional) {
      lambert = std::max(0.0, -n.dot(light.direction));
    } else {
      const Eigen::Vector3d l = light.position - p;
      const double d2 = l.squaredNorm();
      if (d2 <= 0.0) continue;
      lambert = std::max(0.0, n.dot(l)) / std::sqrt(d2) / (1.0 + d2 / (light.range * light.range));
    }
    e += light.colour * static_cast<float>(light.intensity * lambert);
  }
  return e;
}

}  // namespace dqo::sim
