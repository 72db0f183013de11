#pragma once
// Dense RGB-D alignment: projective point-to-plane ICP on a depth pyramid with a photometric term,
// solved by Gauss-Newton on SE(3). Returns the pose and the information matrix (the Gauss-Newton
// Hessian at the solution), which the pose optimiser uses as a prior fused with the features.
// Method, schedule and failure tests: src/tracking/dense_alignment.cpp; pyramid:
// src/tracking/dense_pyramid.cpp; the per-residual maths: src/tracking/dense_residuals.h.
//
// Conventions
// - Result: T_ref_cur maps points of the current camera into the reference camera,
//   p_ref = T_ref_cur * p_cur.
// - Tangent space of `information`: the RIGHT perturbation T_ref_cur = T̂_ref_cur * SE3::exp(xi),
//   xi = [rho; phi] (translation part first, then the rotation vector, as SE3::exp), so xi is
//   expressed in the current camera's frame. With the reference pose held fixed this is also the
//   right perturbation of T_w_cur (T_w_cur * exp(xi)) and, up to the sign of xi (which leaves an
//   information matrix unchanged), the left perturbation of T_cur_w (exp(xi) * T_cur_w). Apply it
//   as a prior cost 0.5 * xiᵀ information xi with xi = log(T̂_ref_cur⁻¹ * T_ref_cur).
// - Units of `information`: the cost is whitened — point-to-plane residuals divided by the depth
//   noise σ(z) = sqrt(min_depth_sigma_m² + (depth_sigma_per_m2 z²)²), photometric residuals by
//   intensity_sigma and weighted by colour_weight, Huber weights included — so information is
//   1/m² (rho) and 1/rad² (phi), the inverse covariance if pixels were independent. They are not
//   (shared calibration and model errors), so on real data it will be overconfident: scale it with
//   PoseOptimiserParams::dense_prior_weight. On `tabletop` (noise exactly as modelled) bench_dense
//   measures E[eᵀ information e] / 6 ≈ 0.4, i.e. honest to slightly conservative there.
// - Pyramid level i has the size of the input halved i times (floor) and intrinsics
//   fx / 2^i, fy / 2^i, cx_i = (cx_{i-1} - 0.5) / 2 (pixel centres at integer coordinates, each
//   pixel the average of a 2x2 block of the level below).

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "dqo_map/common/image.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"
#include "dqo_map/tracking/tracker_params.h"

namespace dqo::tracking {

// A frame prepared for alignment: per level, depth (metres), intensity (float in [0, 1]),
// intensity gradients, back-projected points and normals (camera frame). Built once per frame and
// kept for the next frame's alignment: a frame is the `current` side once and the `reference` side
// the next time, so both are prepared here. Levels below params.finest_level keep only their camera
// (nothing is aligned there); the others are filled. Depth beyond params.max_depth is dropped.
class RgbdPyramid {
 public:
  // Intensity with its gradient in intensity units per pixel of the level (central differences).
  struct Texel {
    float intensity = 0.0f;
    float gx = 0.0f;
    float gy = 0.0f;
    float pad = 0.0f;  // 16 bytes: one bilinear lookup reads four of them
  };
  // A back-projected point with its normal (unit, facing the camera). Zeros rather than NaN mark
  // what is missing, so that the alignment's vectorised loops stay finite: p = 0 where the pixel
  // has no depth, n = 0 where it has no normal (no depth, a depth edge, or the image border).
  struct Surfel {
    Eigen::Vector3f p;
    Eigen::Vector3f n;
  };
  // The pixels that can be aligned (valid point and normal), gathered as a structure of arrays so
  // that the alignment's loops read contiguous memory and vectorise.
  struct Samples {
    std::vector<float> x, y, z;       // point, camera frame, metres
    std::vector<float> nx, ny, nz;    // unit normal
    std::vector<float> intensity;     // in [0, 1]
    std::vector<float> inv_sigma2;    // 1 / σ(z)² of a point-to-plane residual at this depth
    std::vector<float> textured;      // 1 where the gradient reaches min_gradient (photometric)
    size_t size() const { return x.size(); }
  };
  struct Level {
    PinholeCamera camera;
    std::vector<float> depth;     // [width * height] metres, 0 = none
    std::vector<Texel> texels;    // [width * height]; empty when the frame had no colour
    std::vector<Surfel> surfels;  // [width * height]
    Samples samples;              // [valid_points]
    double mean_depth = 0.0;      // of the samples: converts a pose step into pixels
    bool built() const { return !surfels.empty(); }
  };

  // rgb may be empty (depth only: the photometric term is then off); otherwise it must have the
  // depth's size and 3 channels. A depth of the wrong size or an empty one gives a pyramid with no
  // valid points, which align_dense reports as a failure.
  RgbdPyramid(const PinholeCamera& camera, const ImageRgb8& rgb, const DepthImage& depth,
              const DenseParams& params);
  RgbdPyramid() = default;  // no levels: rebuild() it, or align_dense reports a failure
  // The same as constructing anew, but reusing this pyramid's buffers: a tracker that keeps two
  // pyramids and swaps them allocates nothing per frame. Fresh buffers cost page faults: building
  // a new 640x480 pyramid per frame is about 0.5 ms slower (bench_dense).
  void rebuild(const PinholeCamera& camera, const ImageRgb8& rgb, const DepthImage& depth,
               const DenseParams& params);
  RgbdPyramid(RgbdPyramid&&) noexcept = default;
  RgbdPyramid& operator=(RgbdPyramid&&) noexcept = default;
  RgbdPyramid(const RgbdPyramid&) = delete;
  RgbdPyramid& operator=(const RgbdPyramid&) = delete;

  int levels() const { return static_cast<int>(levels_.size()); }
  int finest_level() const { return finest_level_; }
  bool has_colour() const { return has_colour_; }
  const PinholeCamera& camera(int level) const { return levels_[level].camera; }
  int valid_points(int level) const { return static_cast<int>(levels_[level].samples.size()); }
  const Level& level(int i) const { return levels_[i]; }

 private:
  std::vector<Level> levels_;
  std::vector<float> scratch_;  // rows of points and normals while they are computed
  int finest_level_ = 0;
  bool has_colour_ = false;
};

struct DenseResult {
  bool ok = false;
  // The estimate when ok; the guess, unchanged, when not.
  SE3 T_ref_cur;                      // maps the current camera frame into the reference's
  // Gauss-Newton Hessian JᵀWJ of the whitened cost at T_ref_cur, finest level used, both terms;
  // right perturbation, ordering [rho; phi] (see the conventions above). Zero when !ok.
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
  int inliers = 0;                    // correspondences at the finest level used
  double inlier_ratio = 0.0;          // inliers / valid current points at that level
  double rmse_m = 0.0;                // point-to-plane RMS of the inliers at the end
  double whitened_rms = 0.0;          // sqrt(robust whitened cost / inliers), both terms: ~σ units
  int iterations = 0;                 // Gauss-Newton steps taken, all levels
  const char* failure = "";           // why !ok, for a log line
};

// Aligns `current` to `reference`, starting from T_ref_cur_guess (e.g. the motion model). Both
// pyramids must have been built with the same camera and the same params as passed here.
// Single-threaded; allocates nothing per pixel.
DenseResult align_dense(const RgbdPyramid& reference, const RgbdPyramid& current,
                        const SE3& T_ref_cur_guess, const DenseParams& params);

}  // namespace dqo::tracking
