#pragma once
// Lambertian shading: ambient light plus directional and point lights, no shadows (see the weak
// points in config/scenes/README.md: an object on a table has no contact shadow).

#include <Eigen/Core>
#include <vector>

namespace dqo::sim {

struct Light {
  enum class Type { kDirectional, kPoint };
  Type type = Type::kDirectional;
  Eigen::Vector3d direction = -Eigen::Vector3d::UnitZ();  // directional: unit, travel direction
  Eigen::Vector3d position = Eigen::Vector3d::Zero();     // point: world position
  Eigen::Vector3f colour = Eigen::Vector3f::Ones();       // times intensity
  double intensity = 1.0;
  // Point light: irradiance falls as 1 / (1 + (d / range)^2): full strength near the lamp, inverse
  // square far away, never infinite.
  double range = 3.0;
};

struct Lighting {
  Eigen::Vector3f ambient = Eigen::Vector3f::Constant(0.3f);
  std::vector<Light> lights;
};

// Radiance factor (multiplies the albedo) at world point p with unit normal n that faces the
// viewer.
Eigen::Vector3f irradiance(const Lighting& lighting, const Eigen::Vector3d& p,
                           const Eigen::Vector3d& n);

}  // namespace dqo::sim
