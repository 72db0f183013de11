#pragma once
// The CPU rasteriser's core, templated on the scalar: make_cpu_rasteriser() runs it in float on the
// map's own arrays; the gradient tests run it in double on arrays of their own, so that central
// finite differences are accurate to 1e-4 and better. Not part of the stable interface.
//
// Arrays are flat and caller-owned, in the map's layout (shapes in brackets, N Gaussians, P = width
// × height pixels, row-major).

#include <cstddef>
#include <cstdint>
#include <memory>

#include "dqo_map/gaussians/math/project_gaussian.h"
#include "dqo_map/gaussians/rasteriser.h"

namespace dqo::gs::detail {

template <typename S>
struct GaussianArrays {
  size_t count = 0;
  const S* position = nullptr;          // [N*3] world frame
  const S* log_scale = nullptr;         // [N*3]
  const S* rotation = nullptr;          // [N*4] w x y z, any norm
  const S* opacity = nullptr;           // [N]
  const S* colour = nullptr;            // [N*3]
  const uint32_t* object_id = nullptr;  // [N]
  const uint8_t* type = nullptr;        // [N] GaussianType
};

GaussianArrays<float> arrays_of(const GaussianMap& map);

// Every pointer required.
template <typename S>
struct ImageBuffers {
  S* rgb = nullptr;                 // [P*3]
  S* depth = nullptr;               // [P]
  S* alpha = nullptr;               // [P]
  S* ins = nullptr;                 // [P]
  uint32_t* dominant_id = nullptr;  // [P]
};

// dL/d(outputs); a null pointer means zero.
template <typename S>
struct ImageGradients {
  const S* rgb = nullptr;    // [P*3]
  const S* depth = nullptr;  // [P] (of the depth as output: normalised or the surface's)
  const S* ins = nullptr;    // [P]
  const S* alpha = nullptr;  // [P]
};

// Accumulated (+=); every pointer required, sized like the map's arrays.
template <typename S>
struct AttributeGradients {
  S* position = nullptr;   // [N*3]
  S* log_scale = nullptr;  // [N*3]
  S* rotation = nullptr;   // [N*4]
  S* opacity = nullptr;    // [N]
  S* colour = nullptr;     // [N*3]
};

// threads <= 0: all cores. `state` may be null. Throws std::invalid_argument on a camera without
// pixels.
template <typename S>
void cpu_forward(const GaussianArrays<S>& gaussians, const PinholeCamera& camera, const SE3& T_cw,
                 const RenderSettings& settings, int threads, const ImageBuffers<S>& out,
                 std::unique_ptr<RenderState>* state);

// `state` must come from cpu_forward<S> with the same Gaussians, camera and settings; throws
// std::invalid_argument where it visibly does not (scalar type, Gaussian count, image size).
template <typename S>
void cpu_backward(const GaussianArrays<S>& gaussians, const PinholeCamera& camera, const SE3& T_cw,
                  const RenderSettings& settings, int threads, const RenderState& state,
                  const ImageGradients<S>& grad_out, const AttributeGradients<S>& grad);

extern template void cpu_forward<float>(const GaussianArrays<float>&, const PinholeCamera&,
                                        const SE3&, const RenderSettings&, int,
                                        const ImageBuffers<float>&, std::unique_ptr<RenderState>*);
extern template void cpu_forward<double>(const GaussianArrays<double>&, const PinholeCamera&,
                                         const SE3&, const RenderSettings&, int,
                                         const ImageBuffers<double>&,
                                         std::unique_ptr<RenderState>*);
extern template void cpu_backward<float>(const GaussianArrays<float>&, const PinholeCamera&,
                                         const SE3&, const RenderSettings&, int, const RenderState&,
                                         const ImageGradients<float>&,
                                         const AttributeGradients<float>&);
extern template void cpu_backward<double>(const GaussianArrays<double>&, const PinholeCamera&,
                                          const SE3&, const RenderSettings&, int,
                                          const RenderState&, const ImageGradients<double>&,
                                          const AttributeGradients<double>&);

// The camera as the per-Gaussian maths take it (both rasterisers).
template <typename S>
CameraView<S> make_camera_view(const PinholeCamera& camera, const SE3& T_cw, float near) {
  CameraView<S> view;
  view.K = {S(camera.fx), S(camera.fy), S(camera.cx), S(camera.cy), camera.width, camera.height};
  const Eigen::Matrix3d R = T_cw.rotation();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) view.R_cw.m[i][j] = S(R(i, j));
  view.t_cw = {S(T_cw.translation().x()), S(T_cw.translation().y()), S(T_cw.translation().z())};
  view.near = S(near);
  return view;
}

}  // namespace dqo::gs::detail
