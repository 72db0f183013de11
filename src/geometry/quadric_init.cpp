#include "dqo_map/geometry/quadric_init.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/Eigenvalues>

#include "dqo_map/geometry/conic.h"

namespace dqo {
namespace {

using Matrix34d = Eigen::Matrix<double, 3, 4>;
using Vector10d = Eigen::Matrix<double, 10, 1>;

QuadricInitResult failure(InitStatus status, std::string error) {
  QuadricInitResult r;
  r.ok = false;
  r.status = status;
  r.error = std::move(error);
  return r;
}

QuadricInitResult degenerate_views(const std::string& why, double baseline_ratio) {
  QuadricInitResult r = failure(InitStatus::kDegenerateGeometry,
                                "degenerate geometry: all views see the object from (nearly) one "
                                "place (" + why + ")");
  r.baseline_ratio = baseline_ratio;
  return r;
}

std::string ratio_text(double ratio, double min_ratio) {
  return "baseline / distance " + std::to_string(ratio) + " < " + std::to_string(min_ratio);
}

// A camera's centre and the world direction of its ray through a pixel, from P alone: the centre is
// P's right null vector, and M⁻¹ x (M = P's left 3x3) points forward when det M > 0 (P = K[R|t]
// with a positive scale); a negative scale of P flips it back.
struct Ray {
  Eigen::Vector3d origin;
  Eigen::Vector3d direction;  // unit
};

Ray pixel_ray(const Matrix34d& P, const Eigen::Vector2d& uv) {
  const Eigen::Matrix3d M = P.leftCols<3>();
  const Eigen::PartialPivLU<Eigen::Matrix3d> lu(M);
  Ray ray;
  ray.origin = -lu.solve(P.col(3));
  const double sign = M.determinant() > 0.0 ? 1.0 : -1.0;
  ray.direction = (sign * lu.solve(Eigen::Vector3d(uv.x(), uv.y(), 1.0))).normalized();
  return ray;
}

// The point nearest to all rays in the least-squares sense: sum (I − d dᵀ)(X − C) = 0.
std::optional<Eigen::Vector3d> nearest_point_to_rays(const std::vector<Ray>& rays) {
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (const Ray& r : rays) {
    const Eigen::Matrix3d N = Eigen::Matrix3d::Identity() - r.direction * r.direction.transpose();
    A += N;
    b += N * r.origin;
  }
  const Eigen::FullPivLU<Eigen::Matrix3d> lu(A);
  if (!lu.isInvertible()) return std::nullopt;
  const Eigen::Vector3d x = lu.solve(b);
  if (!x.allFinite()) return std::nullopt;
  return x;
}

double largest_baseline(const std::vector<Ray>& rays) {
  double best = 0.0;
  for (size_t i = 0; i < rays.size(); ++i) {
    for (size_t j = i + 1; j < rays.size(); ++j) {
      best = std::max(best, (rays[i].origin - rays[j].origin).norm());
    }
  }
  return best;
}

// Coefficients of piᵀ Q* pi in q = (Q00, Q01, Q02, Q03, Q11, Q12, Q13, Q22, Q23, Q33).
Vector10d tangency_row(const Eigen::Vector4d& p) {
  Vector10d row;
  row << p(0) * p(0), 2.0 * p(0) * p(1), 2.0 * p(0) * p(2), 2.0 * p(0) * p(3), p(1) * p(1),
      2.0 * p(1) * p(2), 2.0 * p(1) * p(3), p(2) * p(2), 2.0 * p(2) * p(3), p(3) * p(3);
  return row;
}

Eigen::Matrix4d symmetric_from_vector(const Vector10d& q) {
  Eigen::Matrix4d Q;
  Q << q(0), q(1), q(2), q(3),  //
      q(1), q(4), q(5), q(6),    //
      q(2), q(5), q(7), q(8),    //
      q(3), q(6), q(8), q(9);
  return Q;
}

// Similarity of the world that puts `origin` at 0 and divides lengths by `length`:
// X_n = (X − origin) / length. Planes map as pi_n = H⁻ᵀ pi.
struct WorldNormalisation {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  double length = 1.0;

  Eigen::Vector4d plane_to_normalised(const Eigen::Vector4d& pi) const {
    // piᵀ X = nᵀ (length X_n + origin) + d.
    Eigen::Vector4d out;
    out.head<3>() = length * pi.head<3>();
    out(3) = pi.head<3>().dot(origin) + pi(3);
    return out;
  }
  DualQuadric quadric_to_world(const DualQuadric& q_n) const {
    return DualQuadric::from_params(origin + length * q_n.centre(), q_n.rotation(),
                                    length * q_n.semi_axes());
  }
};

struct LinearSolution {
  Eigen::Matrix4d Qstar_n;  // in the normalised frame, up to scale
  double sigma_ratio = 0.0;
  double sigma_second_relative = 0.0;  // second-smallest over largest singular value
};

// A back-projected box edge: the plane and the centre of the camera it passes through.
struct EdgePlane {
  Eigen::Vector4d plane;
  Eigen::Vector3d camera_centre;
};

// Solves piᵀ Q* pi = 0 for all planes in the normalised frame. Without a previous estimate, every
// plane has a unit normal, so each equation measures the same geometric quantity. With one, each
// equation is also divided by its sensitivity to pixel noise: moving the plane by delta changes
// piᵀ Q* pi by about 2 r delta (r the ellipsoid's support radius along the normal), and an edge
// error of e px moves the plane by about e / f times the camera's distance to the object; weighting
// by 1 / (r · distance) makes the algebraic fit close to the least-squares fit of the edges.
LinearSolution solve_tangency(const std::vector<EdgePlane>& planes, const WorldNormalisation& norm,
                              const std::optional<DualQuadric>& previous) {
  // The null vector of the stacked rows A, from the normal matrix N = AᵀA (10×10) rather than an
  // SVD of A: the eigenvectors of N are A's right singular vectors and its eigenvalues the squared
  // singular values. The association's fine step runs this for every candidate pair of a keyframe,
  // and the fixed-size eigen-solver is ~10× faster than a JacobiSVD of the 4n×10 matrix. The rows
  // are conditioned (normalised frame, unit normals), so squaring the condition number costs no
  // accuracy that the tests and bench_geometry can see.
  using Matrix10d = Eigen::Matrix<double, 10, 10>;
  Matrix10d N = Matrix10d::Zero();
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  if (previous) S = previous->shape_matrix();
  for (const EdgePlane& edge : planes) {
    Eigen::Vector4d p = norm.plane_to_normalised(edge.plane);
    p /= p.head<3>().norm();
    double weight = 1.0;
    if (previous) {
      const Eigen::Vector3d n = edge.plane.head<3>().normalized();
      const double r = std::sqrt(std::max(0.0, n.dot(S * n)));
      const double distance = (edge.camera_centre - previous->centre()).norm();
      if (r > 0.0 && distance > 0.0) weight = norm.length * norm.length / (r * distance);
    }
    const Eigen::Matrix<double, 10, 1> row = weight * tangency_row(p);
    N.selfadjointView<Eigen::Lower>().rankUpdate(row);
  }
  const Eigen::SelfAdjointEigenSolver<Matrix10d> eig(N.selfadjointView<Eigen::Lower>());
  // Eigenvalues ascending: singular values s_k = sqrt(max(λ, 0)), smallest first.
  const auto sigma = [&](int k) { return std::sqrt(std::max(0.0, eig.eigenvalues()(k))); };
  LinearSolution sol;
  sol.Qstar_n = symmetric_from_vector(eig.eigenvectors().col(0));
  sol.sigma_ratio = sigma(1) > 0.0 ? sigma(0) / sigma(1) : 1.0;
  sol.sigma_second_relative = sigma(9) > 0.0 ? sigma(1) / sigma(9) : 0.0;
  return sol;
}

struct Projection {
  DualQuadric quadric;
  bool clamped = false;
};

// The nearest valid ellipsoid to an up-to-scale Q*: centre and shape from the normalised matrix, the
// shape's small or negative eigenvalues (noise on a flat object) raised to a floor. Fewer than two
// positive eigenvalues is no ellipsoid at all.
std::optional<Projection> nearest_ellipsoid(const Eigen::Matrix4d& Qstar, double min_axis_ratio) {
  if (!Qstar.allFinite()) return std::nullopt;
  const double scale = Qstar.cwiseAbs().maxCoeff();
  if (!(scale > 0.0) || std::abs(Qstar(3, 3)) < 1e-10 * scale) return std::nullopt;
  Eigen::Matrix4d Q = Qstar / (-Qstar(3, 3));
  Q = 0.5 * (Q + Q.transpose()).eval();
  const Eigen::Vector3d mu = -Q.topRightCorner<3, 1>();
  const Eigen::Matrix3d S = Q.topLeftCorner<3, 3>() + mu * mu.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(S);
  if (eig.info() != Eigen::Success) return std::nullopt;
  Eigen::Vector3d lambda = eig.eigenvalues();  // ascending
  if (!(lambda(1) > 0.0)) return std::nullopt;
  const double floor = std::pow(min_axis_ratio, 2) * lambda(2);
  Projection out;
  for (int i = 0; i < 3; ++i) {
    if (lambda(i) < floor) {
      lambda(i) = floor;
      out.clamped = true;
    }
  }
  Eigen::Matrix4d rebuilt = Eigen::Matrix4d::Zero();
  rebuilt.topLeftCorner<3, 3>() = eig.eigenvectors() * lambda.asDiagonal() *
                                      eig.eigenvectors().transpose() -
                                  mu * mu.transpose();
  rebuilt.topRightCorner<3, 1>() = -mu;
  rebuilt.bottomLeftCorner<1, 3>() = -mu.transpose();
  rebuilt(3, 3) = -1.0;
  const std::optional<DualQuadric> q = DualQuadric::from_matrix(rebuilt);
  if (!q) return std::nullopt;
  out.quadric = *q;
  return out;
}

}  // namespace

QuadricInitResult initialise_from_boxes(const std::vector<BoxObservation>& observations,
                                        const InitParams& params) {
  if (observations.size() < 3) {
    return failure(InitStatus::kTooFewViews, "need at least 3 views, got " +
                                                 std::to_string(observations.size()));
  }

  std::vector<EdgePlane> planes;
  std::vector<Ray> rays;
  std::vector<std::array<bool, 4>> used_edges;
  int dropped_at_border = 0;
  for (size_t i = 0; i < observations.size(); ++i) {
    const BoxObservation& o = observations[i];
    if (!o.P.allFinite() || !o.box.valid() || o.width <= 0 || o.height <= 0 ||
        std::abs(o.P.leftCols<3>().determinant()) <= 0.0) {
      return failure(InitStatus::kInvalidInput,
                     "observation " + std::to_string(i) + " has an invalid box, image size or P");
    }
    const std::array<bool, 4> at_border =
        o.box.edges_touching_border(o.width, o.height, params.border_margin_px);
    const std::array<Eigen::Vector3d, 4> lines = o.box.edge_lines();
    rays.push_back(pixel_ray(o.P, o.box.centre()));
    std::array<bool, 4> used{};
    for (int e = 0; e < 4; ++e) {
      if (at_border[e]) {
        ++dropped_at_border;
        continue;
      }
      planes.push_back(EdgePlane{plane_from_line(o.P, lines[e]), rays.back().origin});
      used[e] = true;
    }
    used_edges.push_back(used);
  }

  if (planes.size() < 9) {
    if (dropped_at_border > 0) {
      return failure(InitStatus::kBoxesTouchBorder,
                     "boxes touch the image border: only " + std::to_string(planes.size()) +
                         " of the 9 box edges needed are usable");
    }
    return failure(InitStatus::kTooFewPlanes,
                   "need at least 9 box edges, got " + std::to_string(planes.size()));
  }

  // Where the box-centre rays meet is the object's rough position. It fixes the scale of the
  // degeneracy test and, below, the conditioning of the linear solve. Cameras at one place make the
  // object's distance unobservable: their rays meet at the cameras (or nowhere), and the ratio is
  // 0/0, so coincident centres and a meeting point not in front of every camera are caught first.
  const double baseline = largest_baseline(rays);
  double coordinate_scale = 1.0;
  for (const Ray& r : rays) coordinate_scale = std::max(coordinate_scale, r.origin.norm());
  const std::optional<Eigen::Vector3d> rough_centre = nearest_point_to_rays(rays);
  double distance = 0.0;
  bool in_front = rough_centre.has_value();
  if (rough_centre) {
    for (const Ray& r : rays) {
      distance += (r.origin - *rough_centre).norm();
      in_front = in_front && r.direction.dot(*rough_centre - r.origin) > 0.0;
    }
    distance /= static_cast<double>(rays.size());
  }
  const double baseline_ratio = distance > 0.0 ? baseline / distance : 0.0;
  if (baseline <= 1e-9 * coordinate_scale) {
    return degenerate_views("the camera centres coincide", 0.0);
  }
  if (!in_front) {
    return degenerate_views("the box rays do not meet in front of the cameras", baseline_ratio);
  }
  if (baseline_ratio < params.min_baseline_ratio) {
    return degenerate_views(ratio_text(baseline_ratio, params.min_baseline_ratio), baseline_ratio);
  }

  // Conditioning: the rough position at the origin and the cameras at unit distance for a first
  // solve; each ellipsoid then sets the origin and unit length of the next solve (and its weights,
  // see solve_tangency), so that Q*'s entries are all of order one. With the world in metres and the
  // object metres away, they differ by orders of magnitude and the SVD's smallest singular vector
  // favours the large ones, which costs accuracy under box noise.
  WorldNormalisation norm;
  norm.origin = *rough_centre;
  norm.length = distance;

  LinearSolution sol;
  std::optional<Projection> proj;
  // Pass 0 unweighted, then reweighted; the weights settle after one pass, the third is cheap.
  for (int pass = 0; pass < 3; ++pass) {
    const LinearSolution s =
        solve_tangency(planes, norm, proj ? std::optional<DualQuadric>(proj->quadric) : std::nullopt);
    if (s.sigma_second_relative < 1e-12) {
      if (pass == 0) {
        return failure(InitStatus::kDegenerateGeometry,
                       "degenerate geometry: the box edges fit more than one quadric");
      }
      break;
    }
    const std::optional<Projection> p = nearest_ellipsoid(s.Qstar_n, params.min_axis_ratio);
    if (!p) break;
    sol = s;
    proj = Projection{norm.quadric_to_world(p->quadric), p->clamped};
    norm.origin = proj->quadric.centre();
    norm.length = proj->quadric.semi_axes().maxCoeff();
  }
  if (!proj) {
    return failure(InitStatus::kNotEllipsoid, "the box edges do not fit an ellipsoid");
  }

  double fitted_distance = 0.0;
  for (const Ray& ray : rays) fitted_distance += (ray.origin - proj->quadric.centre()).norm();
  fitted_distance /= static_cast<double>(rays.size());
  const double fitted_ratio = baseline / fitted_distance;
  if (fitted_ratio < params.min_baseline_ratio) {
    return degenerate_views(ratio_text(fitted_ratio, params.min_baseline_ratio), fitted_ratio);
  }

  QuadricInitResult r;
  r.quadric = proj->quadric;
  r.clamped = proj->clamped;
  r.num_planes = static_cast<int>(planes.size());
  r.singular_ratio = sol.sigma_ratio;
  r.baseline_ratio = std::min(baseline_ratio, fitted_ratio);

  // A fit behind a camera or crossing its image plane matches the lines but not the detections.
  double error_sum = 0.0;
  int error_count = 0;
  for (size_t i = 0; i < observations.size(); ++i) {
    const BoxObservation& o = observations[i];
    const double sign = o.P.leftCols<3>().determinant() > 0.0 ? 1.0 : -1.0;
    const Eigen::Vector3d x = o.P * r.quadric.centre().homogeneous();
    const std::optional<Box2d> box = conic_bounding_box(project_quadric(r.quadric, o.P));
    if (sign * x.z() <= 0.0 || !box) {
      return failure(InitStatus::kNotEllipsoid,
                     "the fitted ellipsoid is not in front of view " + std::to_string(i));
    }
    const std::array<double, 4> fitted{box->x_min, box->x_max, box->y_min, box->y_max};
    const std::array<double, 4> seen{o.box.x_min, o.box.x_max, o.box.y_min, o.box.y_max};
    for (int e = 0; e < 4; ++e) {
      if (!used_edges[i][e]) continue;
      error_sum += std::abs(fitted[e] - seen[e]);
      ++error_count;
    }
  }
  r.mean_edge_error_px = error_count > 0 ? error_sum / error_count : 0.0;
  if (r.mean_edge_error_px > params.max_mean_edge_error_px) {
    QuadricInitResult poor = failure(
        InitStatus::kPoorFit, "the fitted ellipsoid does not reproduce the boxes (mean edge error " +
                                  std::to_string(r.mean_edge_error_px) + " px)");
    poor.mean_edge_error_px = r.mean_edge_error_px;
    return poor;
  }
  r.ok = true;
  r.status = InitStatus::kOk;
  return r;
}

namespace {

// Valid depth samples in the pixel centres of [u0, u1) x [v0, v1), at most about `budget` of them
// (a regular stride in both directions).
std::vector<double> depth_samples(const DepthView& depth, double u0d, double v0d, double u1d,
                                  double v1d, const DepthInitParams& params, int budget) {
  const int u0 = std::max(0, static_cast<int>(std::ceil(u0d)));
  const int v0 = std::max(0, static_cast<int>(std::ceil(v0d)));
  const int u1 = std::min(depth.width, static_cast<int>(std::ceil(u1d)));
  const int v1 = std::min(depth.height, static_cast<int>(std::ceil(v1d)));
  std::vector<double> out;
  if (u1 <= u0 || v1 <= v0) return out;
  const double area = static_cast<double>(u1 - u0) * (v1 - v0);
  const int stride = std::max(1, static_cast<int>(std::floor(std::sqrt(area / std::max(1, budget)))));
  for (int v = v0; v < v1; v += stride) {
    for (int u = u0; u < u1; u += stride) {
      const double d = depth.at(u, v);
      if (std::isfinite(d) && d >= params.min_depth && d <= params.max_depth) out.push_back(d);
    }
  }
  return out;
}

// The order statistic at floor(q (n − 1)); reorders v. v must not be empty.
double order_quantile(std::vector<double>& v, double q) {
  const size_t k = static_cast<size_t>(std::clamp(q, 0.0, 1.0) * static_cast<double>(v.size() - 1));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
  return v[k];
}

}  // namespace

QuadricInitResult initialise_from_depth(const Box2d& box, const PinholeCamera& camera,
                                        const SE3& T_wc, const DepthView& depth,
                                        const DepthInitParams& params) {
  if (!box.valid() || depth.data == nullptr || depth.width <= 0 || depth.height <= 0 ||
      !(camera.fx > 0.0) || !(camera.fy > 0.0)) {
    return failure(InitStatus::kInvalidInput, "invalid box, camera or depth image");
  }
  // Fewer samples than this give no quantile worth the name.
  constexpr size_t kMinSamples = 4;
  const double w = box.width(), h = box.height();
  const double margin = 0.5 * (1.0 - std::clamp(params.front_window, 0.0, 1.0));
  std::vector<double> window =
      depth_samples(depth, box.x_min + margin * w, box.y_min + margin * h, box.x_max - margin * w,
                    box.y_max - margin * h, params, params.window_samples);
  if (window.size() < kMinSamples) {
    return failure(InitStatus::kNoValidDepth, "no valid depth in the box's centre");
  }
  const double front = order_quantile(window, params.low_quantile);
  // Lateral semi-axes at the front surface bound how deep the object can reach.
  const double lateral_max = 0.5 * std::max(w / camera.fx, h / camera.fy) * front;
  const double lateral_min = 0.5 * std::min(w / camera.fx, h / camera.fy) * front;
  const std::vector<double> all =
      depth_samples(depth, box.x_min, box.y_min, box.x_max, box.y_max, params, params.box_samples);
  std::vector<double> object;
  for (const double d : all) {
    if (d >= front - params.front_tolerance && d <= front + params.max_depth_reach * lateral_max) {
      object.push_back(d);
    }
  }
  double spread = 0.0;
  if (object.size() >= kMinSamples) {
    std::vector<double> copy = object;
    spread = order_quantile(copy, params.high_quantile) - order_quantile(object, params.low_quantile);
  }
  const double lo = std::max(params.min_semi_axis, params.min_depth_axis_ratio * lateral_min);
  const double hi = std::max(lo, std::max(params.min_semi_axis, params.max_depth_axis_ratio * lateral_max));
  const double c = std::clamp(spread, lo, hi);
  const double z_c = front + c;
  const Eigen::Vector2d uv = box.centre();
  const Eigen::Vector3d centre_c = camera.back_project(uv.x(), uv.y(), z_c);
  Eigen::Vector3d axes(0.5 * w * z_c / camera.fx, 0.5 * h * z_c / camera.fy, c);
  axes = axes.cwiseMax(params.min_semi_axis);

  QuadricInitResult r;
  r.ok = true;
  r.status = InitStatus::kOk;
  r.quadric = DualQuadric::from_params(T_wc * centre_c, T_wc.rotation(), axes);
  r.num_depth_samples = static_cast<int>(object.size());
  return r;
}

const char* to_string(InitStatus status) {
  switch (status) {
    case InitStatus::kOk: return "ok";
    case InitStatus::kInvalidInput: return "invalid input";
    case InitStatus::kTooFewViews: return "too few views";
    case InitStatus::kTooFewPlanes: return "too few planes";
    case InitStatus::kBoxesTouchBorder: return "boxes touch the image border";
    case InitStatus::kDegenerateGeometry: return "degenerate geometry";
    case InitStatus::kNotEllipsoid: return "not an ellipsoid";
    case InitStatus::kPoorFit: return "poor fit";
    case InitStatus::kNoValidDepth: return "no valid depth";
  }
  return "unknown";
}

}  // namespace dqo
