#include "dqo_map/sim/triangle_bvh.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace dqo::sim {
namespace {

constexpr int kBins = 16;
constexpr int kLeafSize = 4;
// Barycentric slack so that a ray through a shared edge cannot slip between its two triangles
// (rounding could otherwise leave a one-pixel crack in a closed mesh).
constexpr double kEdgeEps = 1e-9;

double half_area(const Aabb& b) {
  if (b.empty()) return 0.0;
  const Eigen::Vector3d e = b.extent();
  return e.x() * e.y() + e.y() * e.z() + e.z() * e.x();
}

}  // namespace

TriangleBvh::TriangleBvh(const TriangleMesh& mesh) {
  const int n = static_cast<int>(mesh.triangles.size());
  std::vector<int> order(n);
  std::vector<Aabb> boxes(n);
  std::vector<Eigen::Vector3d> centres(n);
  for (int i = 0; i < n; ++i) {
    order[i] = i;
    for (int k = 0; k < 3; ++k) boxes[i].extend(mesh.vertices[mesh.triangles[i][k]]);
    centres[i] = boxes[i].centre();
    bounds_.extend(boxes[i]);
  }
  if (n == 0) return;
  nodes_.reserve(2 * n / kLeafSize + 1);
  build(order, boxes, centres, 0, n, 1);
  // Leaves index contiguous ranges of tris_, in the order the build left `order` in.
  tris_.reserve(n);
  for (const int i : order) {
    const auto& t = mesh.triangles[i];
    const Eigen::Vector3d& v0 = mesh.vertices[t[0]];
    tris_.push_back({v0, mesh.vertices[t[1]] - v0, mesh.vertices[t[2]] - v0, i});
  }
}

int TriangleBvh::build(std::vector<int>& order, std::vector<Aabb>& boxes,
                       std::vector<Eigen::Vector3d>& centres, int begin, int end, int level) {
  const int index = static_cast<int>(nodes_.size());
  nodes_.emplace_back();
  depth_ = std::max(depth_, level);
  Aabb box, centre_box;
  for (int i = begin; i < end; ++i) {
    box.extend(boxes[order[i]]);
    centre_box.extend(centres[order[i]]);
  }
  nodes_[index].box = box;
  const int count = end - begin;
  auto make_leaf = [&] {
    nodes_[index].first = begin;
    nodes_[index].count = count;
    return index;
  };
  if (count <= kLeafSize || level >= kMaxDepth) return make_leaf();

  int axis = 0;
  const Eigen::Vector3d extent = centre_box.extent();
  if (extent.y() > extent[axis]) axis = 1;
  if (extent.z() > extent[axis]) axis = 2;

  int mid = begin;
  if (extent[axis] > 0.0) {
    // Binned SAH: cost of every split between bins, from prefix and suffix sweeps.
    std::array<int, kBins> bin_count{};
    std::array<Aabb, kBins> bin_box;
    const double lo = centre_box.min[axis];
    const double scale = kBins / extent[axis];
    auto bin_of = [&](int tri) {
      return std::min(kBins - 1, static_cast<int>((centres[tri][axis] - lo) * scale));
    };
    for (int i = begin; i < end; ++i) {
      const int b = bin_of(order[i]);
      ++bin_count[b];
      bin_box[b].extend(boxes[order[i]]);
    }
    std::array<double, kBins - 1> left_cost{};
    Aabb acc;
    int acc_count = 0;
    for (int b = 0; b < kBins - 1; ++b) {
      acc.extend(bin_box[b]);
      acc_count += bin_count[b];
      left_cost[b] = half_area(acc) * acc_count;
    }
    acc = Aabb();
    acc_count = 0;
    double best_cost = kInfinity;
    int best_split = -1;
    for (int b = kBins - 1; b > 0; --b) {
      acc.extend(bin_box[b]);
      acc_count += bin_count[b];
      const double cost = left_cost[b - 1] + half_area(acc) * acc_count;
      if (cost < best_cost) {
        best_cost = cost;
        best_split = b;
      }
    }
    // Splitting costs a traversal step; a small node whose best split is no better stays a leaf.
    const double leaf_cost = half_area(box) * count;
    if (count <= 2 * kLeafSize && best_cost + half_area(box) >= leaf_cost) return make_leaf();
    mid = static_cast<int>(std::partition(order.begin() + begin, order.begin() + end,
                                          [&](int tri) { return bin_of(tri) < best_split; }) -
                           order.begin());
  }
  if (mid == begin || mid == end) {
    // All centres in one bin (or on one point): a median split by index still halves the work.
    mid = begin + count / 2;
    std::nth_element(order.begin() + begin, order.begin() + mid, order.begin() + end,
                     [&](int a, int b) { return centres[a][axis] < centres[b][axis]; });
  }
  build(order, boxes, centres, begin, mid, level + 1);  // left child: index + 1
  const int right = build(order, boxes, centres, mid, end, level + 1);
  nodes_[index].first = right;
  nodes_[index].count = 0;
  return index;
}

bool TriangleBvh::intersect_triangle(const Tri& tri, const Ray& ray, double t_min, double t_max,
                                     TriangleHit* hit) {
  const Eigen::Vector3d p = ray.direction.cross(tri.e2);
  const double det = tri.e1.dot(p);
  if (det == 0.0) return false;
  const double inv = 1.0 / det;
  const Eigen::Vector3d s = ray.origin - tri.v0;
  const double u = s.dot(p) * inv;
  if (u < -kEdgeEps || u > 1.0 + kEdgeEps) return false;
  const Eigen::Vector3d q = s.cross(tri.e1);
  const double v = ray.direction.dot(q) * inv;
  if (v < -kEdgeEps || u + v > 1.0 + kEdgeEps) return false;
  const double t = tri.e2.dot(q) * inv;
  if (!(t > t_min && t < t_max)) return false;
  hit->t = t;
  hit->u = u;
  hit->v = v;
  hit->triangle = tri.index;
  return true;
}

bool TriangleBvh::intersect(const Ray& ray, double t_min, double t_max, TriangleHit* hit) const {
  if (nodes_.empty()) return false;
  const Eigen::Vector3d inv = ray.direction.cwiseInverse();
  double t_enter;
  if (!nodes_[0].box.intersect(ray.origin, inv, t_min, t_max, &t_enter)) return false;
  int stack[kMaxDepth + 4];
  int top = 0;
  stack[top++] = 0;
  bool found = false;
  double best = t_max;
  while (top > 0) {
    const Node& node = nodes_[stack[--top]];
    if (node.count > 0) {
      for (int i = node.first; i < node.first + node.count; ++i) {
        if (intersect_triangle(tris_[i], ray, t_min, best, hit)) {
          best = hit->t;
          found = true;
        }
      }
      continue;
    }
    const int left = static_cast<int>(&node - nodes_.data()) + 1;
    const int right = node.first;
    double t_left, t_right;
    const bool hit_left = nodes_[left].box.intersect(ray.origin, inv, t_min, best, &t_left);
    const bool hit_right = nodes_[right].box.intersect(ray.origin, inv, t_min, best, &t_right);
    // Nearer child on top of the stack: its hits shorten `best` before the farther one is opened.
    if (hit_left && hit_right) {
      if (t_left <= t_right) {
        stack[top++] = right;
        stack[top++] = left;
      } else {
        stack[top++] = left;
        stack[top++] = right;
      }
    } else if (hit_left) {
      stack[top++] = left;
    } else if (hit_right) {
      stack[top++] = right;
    }
  }
  return found;
}

bool TriangleBvh::any_hit(const Ray& ray, double t_min, double t_max) const {
  if (nodes_.empty()) return false;
  const Eigen::Vector3d inv = ray.direction.cwiseInverse();
  int stack[kMaxDepth + 4];
  int top = 0;
  stack[top++] = 0;
  TriangleHit hit;
  while (top > 0) {
    const int index = stack[--top];
    const Node& node = nodes_[index];
    double t_enter;
    if (!node.box.intersect(ray.origin, inv, t_min, t_max, &t_enter)) continue;
    if (node.count > 0) {
      for (int i = node.first; i < node.first + node.count; ++i) {
        if (intersect_triangle(tris_[i], ray, t_min, t_max, &hit)) return true;
      }
      continue;
    }
    stack[top++] = node.first;
    stack[top++] = index + 1;
  }
  return false;
}

}  // namespace dqo::sim
