#pragma once
// Oriented 3D boxes and their exact intersection volume: the pose metric of the evaluation
// (3D IoU between a ground-truth box and the box circumscribing an estimated ellipsoid).
#include <array>
#include <random>

#include <Eigen/Core>

namespace dqo {

class DualQuadric;

// A box in the world frame. `rotation` is orthonormal with det +1 (its columns are the box axes
// in world); `half_extents` are along those axes and non-negative. A zero half-extent is a flat
// box: legal, with zero volume.
struct OrientedBox {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d half_extents = Eigen::Vector3d::Zero();
};

double box_volume(const OrientedBox& box);

// Corner k has local coordinates (±hx, ±hy, ±hz) with the sign of axis i set by bit i of k
// (bit clear: minus), so corners k and k ^ (1 << i) share an edge along axis i.
std::array<Eigen::Vector3d, 8> box_corners(const OrientedBox& box);

// Closed box, with a tolerance of 1e-12 of the box's size so that its own corners count as inside.
bool contains(const OrientedBox& box, const Eigen::Vector3d& p_w);

// Exact volume of a ∩ b (to rounding). Coincident faces (identical boxes, a box flush inside
// another), touching boxes and flat boxes are handled.
double intersection_volume(const OrientedBox& a, const OrientedBox& b);

// Exact intersection over union, in [0, 1]; 0 when the union has no volume.
double iou_3d(const OrientedBox& a, const OrientedBox& b);

// Independent Monte Carlo estimate of iou_3d from `samples` uniform points in the axis-aligned
// bounding box of a ∪ b; for tests of the exact one (standard error ≈ sqrt(iou (1 - iou) / hits)).
double monte_carlo_iou_3d(const OrientedBox& a, const OrientedBox& b, int samples,
                          std::mt19937_64& rng);

double centre_distance(const OrientedBox& a, const OrientedBox& b);

// The box circumscribing the quadric's ellipsoid: same centre and rotation, full extents twice the
// semi-axes (half extents = semi-axes).
OrientedBox box_from_quadric(const DualQuadric& q);

// One orientation for an ellipsoid or a box wherever it is reported (messages, services): its
// axes permuted and flipped, the shape unchanged, so that z is the axis nearest the map's up
// (+z) and points up, x is the longer of the other two (the one nearer the map's +x where they
// are equal) and points to +x's side (+y's where it is perpendicular to x), y = z × x. `R`'s
// columns are the axes, `extents` their lengths (semi-axes or half extents).
void canonical_axes(Eigen::Matrix3d* R, Eigen::Vector3d* extents);

}  // namespace dqo
