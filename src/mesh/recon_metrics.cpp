// Reconstruction metrics: our own seeded area sampler, Open3D's KD-tree for nearest neighbours.
#include "dqo_map/mesh/recon_metrics.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <Eigen/Geometry>
#include <open3d/geometry/KDTreeFlann.h>

namespace dqo::mesh {

namespace {

bool fail(std::string* error, const std::string& message) {
  if (error) *error = message;
  return false;
}

// A double in [0, 1) from the top 53 bits: the same sequence with every standard library, unlike
// std::uniform_real_distribution, whose algorithm is unspecified.
double uniform01(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

// Distinct, well-mixed streams from one user seed (splitmix64's finaliser).
uint64_t mix_seed(uint64_t seed, uint64_t stream) {
  uint64_t z = seed + 0x9e3779b97f4a7c15ULL * (stream + 1);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

bool check_mesh(const TriangleMesh& mesh, const std::string& name, std::string* error) {
  if (mesh.triangles.empty()) return fail(error, name + " mesh is empty");
  const int n = static_cast<int>(mesh.vertices.size());
  for (const auto& t : mesh.triangles) {
    for (const int i : t) {
      if (i < 0 || i >= n) {
        return fail(error, name + " mesh has a triangle index outside its " + std::to_string(n) +
                               " vertices");
      }
    }
  }
  for (const Eigen::Vector3d& v : mesh.vertices) {
    if (!v.allFinite()) return fail(error, name + " mesh has a vertex that is not finite");
  }
  return true;
}

// Whether the triangle may reach into the box: its bounding box in the box's frame overlaps the
// box (conservative; the exact test is on the sampled points).
bool may_touch(const OrientedBox& box, const Eigen::Matrix3d& R_bw, const Eigen::Vector3d& a,
               const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d pa = R_bw * (a - box.centre);
  const Eigen::Vector3d pb = R_bw * (b - box.centre);
  const Eigen::Vector3d pc = R_bw * (c - box.centre);
  const Eigen::Vector3d lo = pa.cwiseMin(pb).cwiseMin(pc);
  const Eigen::Vector3d hi = pa.cwiseMax(pb).cwiseMax(pc);
  return (lo.array() <= box.half_extents.array()).all() &&
         (hi.array() >= -box.half_extents.array()).all();
}

bool inside(const OrientedBox& box, const Eigen::Matrix3d& R_bw, const Eigen::Vector3d& p) {
  return ((R_bw * (p - box.centre)).cwiseAbs() - box.half_extents).maxCoeff() <= 0.0;
}

// Mean nearest distance from `from` to `to`, and the fractions within 1 and 5 cm.
struct NearestStats {
  double mean = 0.0;
  double within_1cm = 0.0;
  double within_5cm = 0.0;
};

NearestStats nearest_stats(const std::vector<Eigen::Vector3d>& from,
                           const std::vector<Eigen::Vector3d>& to) {
  Eigen::MatrixXd data(3, static_cast<Eigen::Index>(to.size()));
  for (size_t i = 0; i < to.size(); ++i) data.col(static_cast<Eigen::Index>(i)) = to[i];
  const open3d::geometry::KDTreeFlann tree(data);
  std::vector<int> index(1);
  std::vector<double> dist2(1);
  double sum = 0.0;
  size_t n1 = 0, n5 = 0;
  for (const Eigen::Vector3d& p : from) {
    tree.SearchKNN(p, 1, index, dist2);
    const double d = std::sqrt(dist2[0]);
    sum += d;
    n1 += d < 0.01;
    n5 += d < 0.05;
  }
  const double n = static_cast<double>(from.size());
  return {sum / n, n1 / n, n5 / n};
}

}  // namespace

std::vector<Eigen::Vector3d> sample_surface(const TriangleMesh& mesh, int count, uint64_t seed,
                                            const OrientedBox* crop, std::string* error) {
  if (count < 1) {
    fail(error, "sample count must be at least 1 (got " + std::to_string(count) + ")");
    return {};
  }
  if (!check_mesh(mesh, "the", error)) return {};
  const Eigen::Matrix3d R_bw =
      crop ? Eigen::Matrix3d(crop->rotation.transpose()) : Eigen::Matrix3d::Identity();

  // Cumulative areas of the candidate triangles: a point then falls in a triangle with
  // probability proportional to its area.
  std::vector<int> candidates;
  std::vector<double> cumulative;
  double total = 0.0;
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    const Eigen::Vector3d& a = mesh.vertices[tri[0]];
    const Eigen::Vector3d& b = mesh.vertices[tri[1]];
    const Eigen::Vector3d& c = mesh.vertices[tri[2]];
    if (crop && !may_touch(*crop, R_bw, a, b, c)) continue;
    const double area = 0.5 * (b - a).cross(c - a).norm();
    if (!(area > 0.0)) continue;
    total += area;
    candidates.push_back(static_cast<int>(t));
    cumulative.push_back(total);
  }
  if (candidates.empty()) {
    if (!crop) fail(error, "the mesh has no area");
    return {};  // a crop that misses the surface is no error here: the caller reports it
  }

  std::mt19937_64 rng(seed);
  std::vector<Eigen::Vector3d> points;
  points.reserve(static_cast<size_t>(count));
  const int64_t max_draws = crop ? 50 * static_cast<int64_t>(count) : count;
  for (int64_t draw = 0; draw < max_draws && static_cast<int>(points.size()) < count; ++draw) {
    const double r = uniform01(rng) * total;
    const size_t k = std::min<size_t>(
        std::upper_bound(cumulative.begin(), cumulative.end(), r) - cumulative.begin(),
        cumulative.size() - 1);
    const auto& tri = mesh.triangles[candidates[k]];
    // Uniform in the triangle: sqrt of the first variate makes the density linear along the
    // median, which cancels the triangle narrowing towards vertex a.
    const double s = std::sqrt(uniform01(rng));
    const double u = uniform01(rng);
    const Eigen::Vector3d p = (1.0 - s) * mesh.vertices[tri[0]] +
                              s * (1.0 - u) * mesh.vertices[tri[1]] +
                              s * u * mesh.vertices[tri[2]];
    if (crop && !inside(*crop, R_bw, p)) continue;
    points.push_back(p);
  }
  return points;
}

std::optional<ReconMetrics> evaluate_reconstruction(const TriangleMesh& rec,
                                                    const TriangleMesh& gt,
                                                    const ReconParams& params,
                                                    std::string* error) {
  if (params.samples < 1) {
    fail(error, "samples must be at least 1");
    return std::nullopt;
  }
  if (!check_mesh(rec, "reconstructed", error) || !check_mesh(gt, "ground-truth", error)) {
    return std::nullopt;
  }
  std::optional<OrientedBox> crop;
  if (params.crop_box) {
    crop = *params.crop_box;
    if (!(params.crop_scale > 0.0) || !crop->half_extents.allFinite() ||
        !crop->centre.allFinite() || !crop->rotation.allFinite()) {
      fail(error, "crop box or crop scale is not finite and positive");
      return std::nullopt;
    }
    crop->half_extents *= params.crop_scale;
  }

  std::string why;
  const std::vector<Eigen::Vector3d> gt_points =
      sample_surface(gt, params.samples, mix_seed(params.seed, 0), nullptr, &why);
  if (gt_points.empty()) {
    fail(error, "ground-truth mesh: " + why);
    return std::nullopt;
  }
  const std::vector<Eigen::Vector3d> rec_points = sample_surface(
      rec, params.samples, mix_seed(params.seed, 1), crop ? &*crop : nullptr, &why);
  if (rec_points.empty()) {
    fail(error, crop ? "reconstruction: no surface inside the crop box (all points cropped away)"
                     : "reconstructed mesh: " + why);
    return std::nullopt;
  }

  const NearestStats acc = nearest_stats(rec_points, gt_points);
  const NearestStats comp = nearest_stats(gt_points, rec_points);
  ReconMetrics m;
  m.accuracy_cm = 100.0 * acc.mean;
  m.completion_cm = 100.0 * comp.mean;
  m.comp_ratio_1cm = 100.0 * comp.within_1cm;
  m.comp_ratio_5cm = 100.0 * comp.within_5cm;
  m.rec_points = static_cast<int>(rec_points.size());
  m.gt_points = static_cast<int>(gt_points.size());
  return m;
}

}  // namespace dqo::mesh
