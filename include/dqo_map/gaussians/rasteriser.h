#pragma once
// The rasteriser interface, in the manner of 3DGS: project every Gaussian (EWA Jacobian, 0.3 px
// low-pass), bin into 16x16 tiles, sort each tile by depth, composite front to back with early
// stop. The CPU implementation is the reference (and the oracle of the CUDA one); both implement
// this interface and share the per-Gaussian maths of include/dqo_map/gaussians/math/.
//
// Conventions: pixel (u, v) has its centre at integer coordinates (PinholeCamera); a Gaussian's
// depth is the camera-frame z of its mean; rotations are quaternions (w, x, y, z) of any norm,
// normalised where used, and their gradient is taken through that normalisation. A Gaussian adds
// to a pixel where α = min(0.99, o exp(−½ dᵀ Σ⁻¹ d)) ≥ 1/255 and the pixel's tile is within its 3σ
// square; a pixel stops once its transmittance would fall below 1e-4. Gradients are exact
// derivatives of the rendered outputs, zero where a cap or clamp is active; which Gaussians form
// a pixel's surface (RenderSettings::surface_depth) is, like those cut-offs, piecewise constant.

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <vector>

#include "dqo_map/gaussians/gaussian_map.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"

namespace dqo::gs {

// RenderOutput's images, as bits of RenderSettings::outputs.
enum RenderImage : uint8_t {
  kRenderRgb = 1,
  kRenderDepth = 2,
  kRenderAlpha = 4,
  kRenderIns = 8,
  kRenderDominantId = 16,
  kRenderAll = 31,
};

struct RenderSettings {
  // The images the caller reads (RenderImage bits). The others may be left empty: a device
  // backend then does not bring them back (a million-pixel render is 23 MB over the bus, the
  // masks' second render needs 4 of them). The CPU rasteriser fills all of them.
  uint8_t outputs = kRenderAll;
  bool normalise_depth = false;  // depth / accumulated alpha instead of Σ T α z
  // Depth of the one surface the pixel sees instead (takes precedence over normalise_depth): the
  // normalised depth over the run of contributors, split where consecutive ones lie more than
  // max(surface_gap, surface_gap_relative · z) apart in depth, in which the accumulated alpha
  // reaches ½ (the last run where it never does). See math/composite.h.
  bool surface_depth = false;
  float surface_gap = 0.02f;           // metres
  float surface_gap_relative = 0.03f;  // of the depth
  uint32_t ins_object = 0;             // object whose instance opacity `ins` is rendered (0: none)
  // Non-null (width × height labels, row-major, the caller's until forward() returns): `ins` of
  // each pixel is the instance opacity of the object it is labelled with (0 for label 0), in
  // place of ins_object's: the masks' test of every object of a keyframe in one render. No
  // gradient of such an `ins` (backward() refuses one).
  const uint32_t* ins_labels = nullptr;
  float background[3] = {0.f, 0.f, 0.f};
  float near = 0.01f;  // metres: Gaussians nearer than this are culled
};

// Per pixel, row-major; rgb interleaved.
struct RenderOutput {
  int width = 0, height = 0;
  std::vector<float> rgb;    // 3 per pixel
  std::vector<float> depth;  // Σ T_i α_i z_i (or normalised, or the surface's: RenderSettings)
  std::vector<float> alpha;  // accumulated alpha 1 − T_final
  std::vector<float> ins;    // Σ α_i over the OG Gaussians of settings.ins_object (METHOD §4),
                             // or of the pixel's label (settings.ins_labels)
  std::vector<uint32_t> dominant_id;  // object ID of the Gaussian of largest T_i α_i (0: none)
};

// dL/d(outputs), same layout as RenderOutput; an empty vector means zero. `depth` is the gradient
// of the depth as rendered (normalised, or the surface's, as the settings say).
struct OutputGradients {
  std::vector<float> rgb, depth, ins;
  std::vector<float> alpha;  // of the accumulated alpha (e.g. a silhouette loss)
};

// dL/d(map attributes), same layout as the map's arrays (rotation: dL/d of the raw, unnormalised
// quaternion). Accumulated (+=) by backward(); left empty, backward() sizes it (zero-filled) first.
struct MapGradients {
  std::vector<float> position, log_scale, rotation, opacity, colour;
  // The caller reads `colour` alone (the trainer's review): a backend may then leave the other
  // arrays as they are (a GPU backend does, and saves bringing them back).
  bool colour_only = false;
  void resize_for(const GaussianMap& map);  // zero-filled, sized like the map
};

// What forward() keeps for backward(): projections, tile lists, per-pixel final transmittance and
// last contributor. Opaque to callers; valid as long as the map and settings it was made with are
// unchanged.
class RenderState {
 public:
  virtual ~RenderState() = default;
};

// Thrown by a GPU backend whose device memory ran out (the step that failed is in what()): the
// caller may free memory (prune the map) and try again; the backend stays usable.
struct OutOfDeviceMemory : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class Rasteriser {
 public:
  virtual ~Rasteriser() = default;

  // T_cw maps world to camera (optical frame). `state` may be null when no backward follows.
  // Resizes `out` to the camera's image.
  virtual void forward(const GaussianMap& map, const PinholeCamera& camera, const SE3& T_cw,
                       const RenderSettings& settings, RenderOutput* out,
                       std::unique_ptr<RenderState>* state) = 0;

  // Gradients of a loss with respect to the map's attributes, given dL/d(outputs) of the forward
  // pass that made `state` (same map, camera and settings).
  virtual void backward(const GaussianMap& map, const PinholeCamera& camera, const SE3& T_cw,
                        const RenderSettings& settings, const RenderState& state,
                        const OutputGradients& grad_out, MapGradients* grad_map) = 0;
};

// The CPU reference (src/gaussians/cpu_rasteriser.cpp), multi-threaded over tiles; threads <= 0:
// all cores. Results are deterministic for a given thread count.
std::unique_ptr<Rasteriser> make_cpu_rasteriser(int threads = 0);

}  // namespace dqo::gs
