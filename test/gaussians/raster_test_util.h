#pragma once
// Helpers of the rasteriser tests: random Gaussians in view, double-precision Gaussian arrays for
// the templated core (detail/cpu_rasteriser.h), and renders into owned buffers.

#include <Eigen/Geometry>
#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "dqo_map/gaussians/detail/cpu_rasteriser.h"
#include "dqo_map/gaussians/gaussian_map.h"
#include "dqo_map/gaussians/rasteriser.h"

namespace dqo::gs::testing {

inline double uniform(std::mt19937_64& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

inline PinholeCamera make_camera(int width, int height, double f) {
  PinholeCamera c;
  c.width = width;
  c.height = height;
  c.fx = f;
  c.fy = f * 1.02;
  c.cx = 0.5 * (width - 1) + 0.7;
  c.cy = 0.5 * (height - 1) - 0.4;
  return c;
}

// A camera pose that is not the identity, so that world-to-camera is exercised.
inline SE3 test_pose() {
  return SE3(
      Eigen::Quaterniond(Eigen::AngleAxisd(0.2, Eigen::Vector3d(0.3, -1.0, 0.5).normalized())),
      Eigen::Vector3d(0.1, -0.05, 0.2));
}

// A Gaussian whose mean projects into the image (pixel (u, v), depth z) of camera/pose.
inline GaussianInit gaussian_at(const PinholeCamera& cam, const SE3& T_cw, double u, double v,
                                double z, std::mt19937_64& rng, double log_scale_lo,
                                double log_scale_hi) {
  GaussianInit g;
  const Eigen::Vector3d p_c = cam.back_project(u, v, z);
  g.position = (T_cw.inverse() * p_c).cast<float>();
  for (int k = 0; k < 3; ++k)
    g.log_scale[k] = static_cast<float>(uniform(rng, log_scale_lo, log_scale_hi));
  // Deliberately not unit: the rasteriser normalises.
  Eigen::Vector4f q(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1),
                    uniform(rng, -1, 1));
  g.rotation = q.normalized() * static_cast<float>(uniform(rng, 0.7, 1.4));
  g.colour = Eigen::Vector3f(uniform(rng, 0, 1), uniform(rng, 0, 1), uniform(rng, 0, 1));
  return g;
}

// Attributes in double, for the templated core.
struct DoubleGaussians {
  std::vector<double> position, log_scale, rotation, opacity, colour;
  std::vector<uint32_t> object_id;
  std::vector<uint8_t> type;

  size_t size() const { return opacity.size(); }
  void add(const GaussianInit& g, double opacity_value) {
    for (int k = 0; k < 3; ++k) {
      position.push_back(g.position[k]);
      log_scale.push_back(g.log_scale[k]);
      colour.push_back(g.colour[k]);
    }
    for (int k = 0; k < 4; ++k) rotation.push_back(g.rotation[k]);
    opacity.push_back(opacity_value);
    object_id.push_back(g.object_id);
    type.push_back(static_cast<uint8_t>(g.type));
  }
  detail::GaussianArrays<double> arrays() const {
    detail::GaussianArrays<double> a;
    a.count = size();
    a.position = position.data();
    a.log_scale = log_scale.data();
    a.rotation = rotation.data();
    a.opacity = opacity.data();
    a.colour = colour.data();
    a.object_id = object_id.data();
    a.type = type.data();
    return a;
  }
  // The attribute arrays in a fixed order, for finite differences over all of them.
  std::vector<std::vector<double>*> blocks() {
    return {&position, &log_scale, &rotation, &opacity, &colour};
  }
};

template <typename S>
struct Images {
  int width = 0, height = 0;
  std::vector<S> rgb, depth, alpha, ins;
  std::vector<uint32_t> dominant_id;
  std::unique_ptr<RenderState> state;
};

template <typename S>
Images<S> render(const detail::GaussianArrays<S>& g, const PinholeCamera& cam, const SE3& T_cw,
                 const RenderSettings& settings, int threads, bool keep_state = false) {
  Images<S> im;
  const size_t n = static_cast<size_t>(cam.width) * cam.height;
  im.width = cam.width;
  im.height = cam.height;
  im.rgb.resize(3 * n);
  im.depth.resize(n);
  im.alpha.resize(n);
  im.ins.resize(n);
  im.dominant_id.resize(n);
  detail::ImageBuffers<S> b;
  b.rgb = im.rgb.data();
  b.depth = im.depth.data();
  b.alpha = im.alpha.data();
  b.ins = im.ins.data();
  b.dominant_id = im.dominant_id.data();
  detail::cpu_forward(g, cam, T_cw, settings, threads, b, keep_state ? &im.state : nullptr);
  return im;
}

}  // namespace dqo::gs::testing
