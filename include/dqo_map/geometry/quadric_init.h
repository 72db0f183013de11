#pragma once
// Initial ellipsoid of a new object (METHOD.md §1):
//  - from three or more views of its detection box: each box edge back-projects to a plane pi = Pᵀ l
//    tangent to the ellipsoid, piᵀ Q* pi = 0 is linear in the 10 entries of the symmetric Q*, and the
//    stacked system is solved by SVD, then projected to the nearest valid ellipsoid;
//  - from one view and its depth image (the released code's fallback, made robust to background).
// Both return a result value; failures carry a status and a message, never an exception.

#include <string>
#include <vector>

#include <Eigen/Core>

#include "dqo_map/geometry/box2d.h"
#include "dqo_map/geometry/dual_quadric.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"

namespace dqo {

// One detection of the object: the box in an image of size width x height taken by P = K [R_cw|t_cw].
struct BoxObservation {
  Eigen::Matrix<double, 3, 4> P = Eigen::Matrix<double, 3, 4>::Zero();
  Box2d box;
  int width = 0;
  int height = 0;
};

struct InitParams {
  // Box edges this close to the image border are cut by it, not tangent to the object: dropped.
  double border_margin_px = 5.0;
  // Views whose camera centres lie closer together than this fraction of their distance to the
  // object (largest distance between two camera centres / mean distance from a camera to where the
  // box-centre rays meet; about the parallax angle in radians) cannot fix the depth: degenerate.
  double min_baseline_ratio = 0.05;
  // Shape eigenvalues (axes²) below (min_axis_ratio × largest axis)² are clamped up to it, so a flat
  // object seen edge-on still gives a (thin) ellipsoid rather than a failure.
  double min_axis_ratio = 0.01;
  // A fit whose boxes miss the used edges by more than this on average explains nothing (views from
  // nearly one place with noisy boxes give tiny ellipsoids next to the cameras): rejected.
  double max_mean_edge_error_px = 30.0;
};

enum class InitStatus {
  kOk,
  kInvalidInput,
  kTooFewViews,
  kTooFewPlanes,
  kBoxesTouchBorder,
  kDegenerateGeometry,
  kNotEllipsoid,
  kPoorFit,
  kNoValidDepth,
};

struct QuadricInitResult {
  bool ok = false;
  InitStatus status = InitStatus::kInvalidInput;
  std::string error;  // empty when ok
  DualQuadric quadric;
  // From boxes: planes used, the smallest singular value over the next one (near 0: well
  // determined, near 1: a second solution fits as well), the baseline ratio of the views, the
  // mean |edge error| in pixels of the final ellipsoid's boxes against the used edges, and whether
  // an axis had to be clamped.
  int num_planes = 0;
  double singular_ratio = 0.0;
  double baseline_ratio = 0.0;
  double mean_edge_error_px = 0.0;
  bool clamped = false;
  // From depth: the (strided) valid depth samples of the box taken as the object's.
  int num_depth_samples = 0;
};

QuadricInitResult initialise_from_boxes(const std::vector<BoxObservation>& observations,
                                        const InitParams& params = InitParams());

// A depth image in metres, row-major with rows of `width` floats; 0, negative or NaN means invalid.
// A view so that the library stays free of image types; the caller owns the data.
struct DepthView {
  const float* data = nullptr;
  int width = 0;
  int height = 0;

  float at(int u, int v) const { return data[static_cast<long>(v) * width + u]; }
};

struct DepthInitParams {
  double min_depth = 0.1;  // metres; samples outside [min_depth, max_depth] are ignored
  double max_depth = 20.0;
  // The front surface is the low quantile of the depth in the box's central window; the depth
  // extent is the spread between the two quantiles of the object's samples.
  double low_quantile = 0.1;
  double high_quantile = 0.9;
  double min_semi_axis = 0.02;  // metres; no axis is shorter (a wall seen fronto-parallel has 0 spread)
  // The central window (this share of the box's width and height, centred): an object covers its
  // box's centre, the background its margins.
  double front_window = 0.5;
  // Samples up to this far (metres) in front of the front surface still belong to the object.
  double front_tolerance = 0.02;
  // ... and up to this many times the larger lateral semi-axis behind it (the background beyond).
  double max_depth_reach = 2.0;
  // The depth semi-axis lies between these multiples of the smaller and the larger lateral
  // semi-axis (objects are about as deep as they are wide; a flat front gives no spread).
  double min_depth_axis_ratio = 0.5;
  double max_depth_axis_ratio = 1.0;
  // At most about this many samples are read from the central window and from the whole box
  // (a regular stride over the pixels): the association runs this for every kept detection.
  int window_samples = 400;
  int box_samples = 1500;
};

// Single view (METHOD.md §1, fallback), robust to the background that a detection box always
// holds: the front surface is the low quantile of the depth in the box's central window; the
// object's samples are those from front_tolerance before it to max_depth_reach lateral semi-axes
// behind it; the depth semi-axis is their quantile spread, bounded by the lateral semi-axes; the
// centre lies on the box-centre ray one depth semi-axis behind the front surface; the lateral
// semi-axes are half the box width/height × the centre's depth / focal. Rotation facing the camera
// (the axes along the camera's x, y, z). T_wc maps camera to world; the result is in world.
// The released code's rule (centre at the mean depth in the box, axis from the whole box's depth
// spread) put thin objects (a bottle covers a third of its box) on the wall behind them, with
// metre-long depth axes.
QuadricInitResult initialise_from_depth(const Box2d& box, const PinholeCamera& camera,
                                        const SE3& T_wc, const DepthView& depth,
                                        const DepthInitParams& params = DepthInitParams());

const char* to_string(InitStatus status);

}  // namespace dqo
