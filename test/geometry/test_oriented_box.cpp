#include "dqo_map/geometry/oriented_box.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "dqo_map/geometry/dual_quadric.h"

namespace dqo {
namespace {

constexpr std::uint64_t kSeeds[] = {1, 7, 42, 2024, 987654321};

Eigen::Matrix3d random_rotation(std::mt19937_64& rng) {
  // A normalised 4D Gaussian is a uniform unit quaternion.
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
  q.normalize();
  return q.toRotationMatrix();
}

Eigen::Vector3d random_unit(std::mt19937_64& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::Vector3d u(normal(rng), normal(rng), normal(rng));
  return u.normalized();
}

Eigen::Vector3d random_vector(std::mt19937_64& rng, double lo, double hi) {
  std::uniform_real_distribution<double> uni(lo, hi);
  return Eigen::Vector3d(uni(rng), uni(rng), uni(rng));
}

OrientedBox random_box(std::mt19937_64& rng, double centre_range = 5.0) {
  OrientedBox box;
  box.centre = random_vector(rng, -centre_range, centre_range);
  box.rotation = random_rotation(rng);
  box.half_extents = random_vector(rng, 0.1, 2.0);
  return box;
}

// A second box whose centre lies inside the first, so that the pair overlaps.
OrientedBox random_overlapping(const OrientedBox& a, std::mt19937_64& rng) {
  OrientedBox b = random_box(rng);
  const Eigen::Vector3d local = random_vector(rng, -1.0, 1.0).cwiseProduct(a.half_extents);
  b.centre = a.centre + a.rotation * local;
  return b;
}

// Half-width of the box's projection on unit direction u.
double support(const OrientedBox& box, const Eigen::Vector3d& u) {
  return (box.rotation.transpose() * u).cwiseAbs().dot(box.half_extents);
}

double interval_overlap(double c1, double h1, double c2, double h2) {
  return std::max(0.0, std::min(c1 + h1, c2 + h2) - std::max(c1 - h1, c2 - h2));
}

std::string seed_trace(std::uint64_t seed) { return "seed " + std::to_string(seed); }

TEST(OrientedBox, VolumeAndCorners) {
  for (const std::uint64_t seed : kSeeds) {
    SCOPED_TRACE(seed_trace(seed));
    std::mt19937_64 rng(seed);
    const OrientedBox box = random_box(rng);
    EXPECT_NEAR(box_volume(box), 8.0 * box.half_extents.prod(), 1e-12);
    const auto corners = box_corners(box);
    for (int k = 0; k < 8; ++k) {
      EXPECT_TRUE(contains(box, corners[k])) << "corner " << k;
      // Pushed outwards along the diagonal, a corner leaves the box.
      EXPECT_FALSE(contains(box, box.centre + 1.001 * (corners[k] - box.centre))) << "corner " << k;
      for (int i = 0; i < 3; ++i) {
        const Eigen::Vector3d edge = corners[k ^ (1 << i)] - corners[k];
        EXPECT_NEAR(edge.norm(), 2.0 * box.half_extents[i], 1e-12);
        EXPECT_NEAR(std::abs(edge.normalized().dot(box.rotation.col(i))), 1.0, 1e-12);
      }
    }
    EXPECT_TRUE(contains(box, box.centre));
  }
}

TEST(OrientedBox, CentreDistance) {
  for (const std::uint64_t seed : kSeeds) {
    SCOPED_TRACE(seed_trace(seed));
    std::mt19937_64 rng(seed);
    const OrientedBox a = random_box(rng);
    OrientedBox b = random_box(rng);
    const Eigen::Vector3d offset = random_vector(rng, -3.0, 3.0);
    b.centre = a.centre + offset;
    EXPECT_NEAR(centre_distance(a, b), offset.norm(), 1e-12);
    EXPECT_NEAR(centre_distance(b, a), offset.norm(), 1e-12);
  }
}

TEST(OrientedBox, IdenticalBoxesHaveIouOne) {
  for (const std::uint64_t seed : kSeeds) {
    SCOPED_TRACE(seed_trace(seed));
    std::mt19937_64 rng(seed);
    for (int trial = 0; trial < 20; ++trial) {
      const OrientedBox a = random_box(rng, 100.0);
      EXPECT_NEAR(iou_3d(a, a), 1.0, 1e-12);
      EXPECT_NEAR(intersection_volume(a, a), box_volume(a), 1e-12 * box_volume(a));

      // The same box written with its axes permuted cyclically and two of them negated: every
      // face of one coincides with a face of the other only up to rounding.
      OrientedBox b;
      b.centre = a.centre;
      b.rotation.col(0) = -a.rotation.col(1);
      b.rotation.col(1) = -a.rotation.col(2);
      b.rotation.col(2) = a.rotation.col(0);
      b.half_extents = Eigen::Vector3d(a.half_extents[1], a.half_extents[2], a.half_extents[0]);
      EXPECT_NEAR(iou_3d(a, b), 1.0, 1e-12);
      EXPECT_NEAR(iou_3d(b, a), 1.0, 1e-12);
    }
  }
}

TEST(OrientedBox, DisjointBoxesHaveIouZero) {
  for (const std::uint64_t seed : kSeeds) {
    SCOPED_TRACE(seed_trace(seed));
    std::mt19937_64 rng(seed);
    for (int trial = 0; trial < 50; ++trial) {
      const OrientedBox a = random_box(rng);
      OrientedBox b = random_box(rng);
      const Eigen::Vector3d u = random_unit(rng);
      const double reach = support(a, u) + support(b, u);
      // Separated along u by a small gap, then exactly touching (a corner or edge on a face).
      b.centre = a.centre + (reach + 1e-3) * u;
      EXPECT_EQ(intersection_volume(a, b), 0.0);
      EXPECT_EQ(iou_3d(a, b), 0.0);
      b.centre = a.centre + reach * u;
      EXPECT_LT(iou_3d(a, b), 1e-9);
      EXPECT_LT(iou_3d(b, a), 1e-9);
    }
  }
}

TEST(OrientedBox, FaceToFaceTouchingHasZeroVolume) {
  for (const std::uint64_t seed : kSeeds) {
    SCOPED_TRACE(seed_trace(seed));
    std::mt19937_64 rng(seed);
    for (int trial = 0; trial < 20; ++trial) {
      const OrientedBox a = random_box(rng);
      // b shares a's rotation and sits against one of a's faces, overlapping it partly in the plane.
      OrientedBox b = a;
      b.half_extents = random_vector(rng, 0.1, 2.0);
      const int axis = trial % 3;
      Eigen::Vector3d local = random_vector(rng, -1.0, 1.0).cwiseProduct(a.half_extents);
      local[axis] = a.half_extents[axis] + b.half_extents[axis];
      b.centre = a.centre + a.rotation * local;
      EXPECT_LT(intersection_volume(a, b), 1e-12 * box_volume(a));
      EXPECT_LT(iou_3d(b, a), 1e-12);
    }
  }
}

TEST(OrientedBox, IouIsSymmetricAndBounded) {
  for (const std::uint64_t seed : kSeeds) {
    SCOPED_TRACE(seed_trace(seed));
    std::mt19937_64 rng(seed);
    int overlapping = 0;
    for (int trial = 0; trial < 200; ++trial) {
      const OrientedBox a = random_box(rng, 1.0);
      const OrientedBox b = (trial % 2 == 0) ? random_overlapping(a, rng) : random_box(rng, 1.0);
      const double ab = iou_3d(a, b);
      const double ba = iou_3d(b, a);
      EXPECT_NEAR(ab, ba, 1e-12);
      EXPECT_GE(ab, 0.0);
      EXPECT_LE(ab, 1.0);
      const double inter = intersection_volume(a, b);
      EXPECT_LE(inter, std::min(box_volume(a), box_volume(b)));
      overlapping += ab > 0.0 ? 1 : 0;
    }
    // The pairs must exercise the clipping, not only the early exits.
    EXPECT_GT(overlapping, 100);
  }
}

TEST(OrientedBox, AgreesWithMonteCarlo) {
  for (const std::uint64_t seed : {3u, 11u, 99u}) {
    SCOPED_TRACE(seed_trace(seed));
    std::mt19937_64 rng(seed);
    for (int trial = 0; trial < 6; ++trial) {
      const OrientedBox a = random_box(rng);
      const OrientedBox b = random_overlapping(a, rng);
      const double exact = iou_3d(a, b);
      const double estimate = monte_carlo_iou_3d(a, b, 400000, rng);
      EXPECT_GT(exact, 0.0);
      EXPECT_NEAR(exact, estimate, 0.01) << "trial " << trial;
    }
  }
}

// Exactness for arbitrary orientations: cutting b in two along one of its axes splits a ∩ b into
// two pieces whose volumes must add up, whatever a's pose.
TEST(OrientedBox, IntersectionIsAdditiveOverSplits) {
  for (const std::uint64_t seed : kSeeds) {
    SCOPED_TRACE(seed_trace(seed));
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> fraction(0.05, 0.95);
    for (int trial = 0; trial < 50; ++trial) {
      const OrientedBox a = random_box(rng);
      const OrientedBox b = random_overlapping(a, rng);
      const int axis = trial % 3;
      const double t = fraction(rng);  // share of b's extent on the minus side
      const double h = b.half_extents[axis];
      OrientedBox lower = b;
      OrientedBox upper = b;
      lower.half_extents[axis] = t * h;
      upper.half_extents[axis] = (1.0 - t) * h;
      lower.centre = b.centre + (-h + t * h) * b.rotation.col(axis);
      upper.centre = b.centre + (h - (1.0 - t) * h) * b.rotation.col(axis);
      const double whole = intersection_volume(a, b);
      const double parts = intersection_volume(a, lower) + intersection_volume(a, upper);
      EXPECT_NEAR(whole, parts, 1e-9 * std::max(whole, 1e-3)) << "trial " << trial;
    }
  }
}

// Faces a hair apart in angle: too far apart to be the same plane, too close for their line of
// intersection to be well conditioned. Clipping each face on its own loses ~1e-5 of the volume
// here; a watertight clip must stay additive and symmetric to rounding.
TEST(OrientedBox, NearlyCoplanarFacesStayExact) {
  for (const std::uint64_t seed : kSeeds) {
    SCOPED_TRACE(seed_trace(seed));
    std::mt19937_64 rng(seed);
    for (const double angle : {1e-13, 1e-11, 1e-10, 1e-9, 1e-8, 1e-6}) {
      for (int trial = 0; trial < 60; ++trial) {
        const OrientedBox a = random_box(rng);
        OrientedBox b = a;
        b.rotation = Eigen::AngleAxisd(angle, random_unit(rng)).toRotationMatrix() * a.rotation;
        if (trial % 2 == 1) {  // flush against a corner of a instead of identical
          b.half_extents = a.half_extents.cwiseProduct(random_vector(rng, 0.2, 0.9));
          b.centre = a.centre + a.rotation * (a.half_extents - b.half_extents);
        }
        const int axis = trial % 3;
        const double h = b.half_extents[axis];
        OrientedBox lower = b;
        OrientedBox upper = b;
        lower.half_extents[axis] = 0.3 * h;
        upper.half_extents[axis] = 0.7 * h;
        lower.centre = b.centre - 0.7 * h * b.rotation.col(axis);
        upper.centre = b.centre + 0.3 * h * b.rotation.col(axis);
        const double whole = intersection_volume(a, b);
        const double scale = box_volume(b);
        EXPECT_NEAR(whole, intersection_volume(b, a), 1e-9 * scale) << "angle " << angle;
        EXPECT_NEAR(whole, intersection_volume(a, lower) + intersection_volume(a, upper),
                    1e-9 * scale)
            << "angle " << angle;
        // Rotating b by `angle` moves its surface by at most angle × its radius, so the volume it
        // can lose is at most that times its area.
        const double area = scale * b.half_extents.cwiseInverse().sum();
        EXPECT_NEAR(whole, scale, angle * b.half_extents.norm() * area + 1e-12 * scale)
            << "angle " << angle;
      }
    }
  }
}

// A rigid motion of both boxes changes nothing.
TEST(OrientedBox, IntersectionIsRigidInvariant) {
  for (const std::uint64_t seed : kSeeds) {
    SCOPED_TRACE(seed_trace(seed));
    std::mt19937_64 rng(seed);
    for (int trial = 0; trial < 50; ++trial) {
      const OrientedBox a = random_box(rng);
      const OrientedBox b = random_overlapping(a, rng);
      const Eigen::Matrix3d R = random_rotation(rng);
      const Eigen::Vector3d t = random_vector(rng, -10.0, 10.0);
      OrientedBox a2 = a;
      OrientedBox b2 = b;
      a2.centre = R * a.centre + t;
      a2.rotation = R * a.rotation;
      b2.centre = R * b.centre + t;
      b2.rotation = R * b.rotation;
      const double v = intersection_volume(a, b);
      EXPECT_NEAR(v, intersection_volume(a2, b2), 1e-9 * std::max(v, 1e-3));
    }
  }
}

// Boxes aligned with one common frame overlap in a box: the product of the interval overlaps.
// Centres and extents on a coarse grid make shared and touching faces common; the common frame
// is random, so those faces coincide only up to rounding.
TEST(OrientedBox, AlignedPairsMatchIntervalProduct) {
  for (const std::uint64_t seed : kSeeds) {
    SCOPED_TRACE(seed_trace(seed));
    std::mt19937_64 rng(seed);
    std::uniform_int_distribution<int> grid(-4, 4);
    std::uniform_int_distribution<int> size(1, 4);
    int with_shared_plane = 0;
    for (int trial = 0; trial < 300; ++trial) {
      const bool world_aligned = trial % 2 == 0;
      const Eigen::Matrix3d R = world_aligned ? Eigen::Matrix3d::Identity() : random_rotation(rng);
      const Eigen::Vector3d t = world_aligned ? Eigen::Vector3d::Zero() : random_vector(rng, -5, 5);
      Eigen::Vector3d ca, cb, ha, hb;
      for (int i = 0; i < 3; ++i) {
        ca[i] = 0.25 * grid(rng);
        cb[i] = 0.25 * grid(rng);
        ha[i] = 0.25 * size(rng);
        hb[i] = 0.25 * size(rng);
      }
      double expected = 1.0;
      for (int i = 0; i < 3; ++i) {
        expected *= interval_overlap(ca[i], ha[i], cb[i], hb[i]);
        const bool shared = std::abs((ca[i] + ha[i]) - (cb[i] + hb[i])) < 1e-12 ||
                            std::abs((ca[i] - ha[i]) - (cb[i] - hb[i])) < 1e-12 ||
                            std::abs((ca[i] + ha[i]) - (cb[i] - hb[i])) < 1e-12 ||
                            std::abs((ca[i] - ha[i]) - (cb[i] + hb[i])) < 1e-12;
        with_shared_plane += shared ? 1 : 0;
      }
      const OrientedBox a{R * ca + t, R, ha};
      const OrientedBox b{R * cb + t, R, hb};
      const double scale = std::min(box_volume(a), box_volume(b));
      EXPECT_NEAR(intersection_volume(a, b), expected, 1e-9 * scale) << "trial " << trial;
      EXPECT_NEAR(intersection_volume(b, a), expected, 1e-9 * scale) << "trial " << trial;
      const double uni = box_volume(a) + box_volume(b) - expected;
      EXPECT_NEAR(iou_3d(a, b), expected / uni, 1e-9) << "trial " << trial;
    }
    EXPECT_GT(with_shared_plane, 50);
  }
}

TEST(OrientedBox, ContainedBoxGivesVolumeRatio) {
  for (const std::uint64_t seed : kSeeds) {
    SCOPED_TRACE(seed_trace(seed));
    std::mt19937_64 rng(seed);
    int tested = 0;
    for (int trial = 0; trial < 200 && tested < 40; ++trial) {
      const OrientedBox outer = random_box(rng);
      OrientedBox inner = random_overlapping(outer, rng);
      inner.half_extents = random_vector(rng, 0.05, 0.5).cwiseProduct(outer.half_extents);
      bool inside = true;
      for (const Eigen::Vector3d& c : box_corners(inner)) inside = inside && contains(outer, c);
      if (!inside) continue;
      ++tested;
      const double ratio = box_volume(inner) / box_volume(outer);
      EXPECT_NEAR(iou_3d(outer, inner), ratio, 1e-9 * ratio);
      EXPECT_NEAR(iou_3d(inner, outer), ratio, 1e-9 * ratio);
      EXPECT_NEAR(intersection_volume(outer, inner), box_volume(inner), 1e-9 * box_volume(inner));
    }
    EXPECT_GE(tested, 10);
  }
}

// The inner box is flush with a corner of the outer one: three pairs of coincident faces.
TEST(OrientedBox, FlushContainedBoxGivesVolumeRatio) {
  for (const std::uint64_t seed : kSeeds) {
    SCOPED_TRACE(seed_trace(seed));
    std::mt19937_64 rng(seed);
    for (int trial = 0; trial < 20; ++trial) {
      const OrientedBox outer = random_box(rng);
      OrientedBox inner = outer;
      inner.half_extents = random_vector(rng, 0.1, 1.0).cwiseProduct(outer.half_extents);
      inner.centre = outer.centre + outer.rotation * (outer.half_extents - inner.half_extents);
      const double ratio = box_volume(inner) / box_volume(outer);
      EXPECT_NEAR(iou_3d(outer, inner), ratio, 1e-9 * ratio);
      EXPECT_NEAR(iou_3d(inner, outer), ratio, 1e-9 * ratio);
    }
  }
}

TEST(OrientedBox, FlatBoxesHaveZeroVolume) {
  for (const std::uint64_t seed : kSeeds) {
    SCOPED_TRACE(seed_trace(seed));
    std::mt19937_64 rng(seed);
    const OrientedBox a = random_box(rng);
    OrientedBox flat = random_overlapping(a, rng);
    flat.half_extents[seed % 3] = 0.0;
    EXPECT_EQ(box_volume(flat), 0.0);
    EXPECT_EQ(intersection_volume(a, flat), 0.0);
    EXPECT_EQ(iou_3d(a, flat), 0.0);
    EXPECT_EQ(iou_3d(flat, flat), 0.0);  // empty union
    OrientedBox point = a;
    point.half_extents.setZero();
    EXPECT_EQ(iou_3d(point, point), 0.0);
  }
}

TEST(OrientedBox, BoxFromQuadricCircumscribesEllipsoid) {
  for (const std::uint64_t seed : kSeeds) {
    SCOPED_TRACE(seed_trace(seed));
    std::mt19937_64 rng(seed);
    for (int trial = 0; trial < 10; ++trial) {
      const Eigen::Vector3d centre = random_vector(rng, -5.0, 5.0);
      const Eigen::Matrix3d rotation = random_rotation(rng);
      const Eigen::Vector3d semi_axes = random_vector(rng, 0.1, 2.0);
      const DualQuadric q = DualQuadric::from_params(centre, rotation, semi_axes);
      const OrientedBox box = box_from_quadric(q);
      EXPECT_TRUE(box.centre.isApprox(centre, 1e-12));
      EXPECT_TRUE(box.rotation.isApprox(rotation, 1e-12));
      EXPECT_NEAR(box_volume(box), 8.0 * semi_axes.prod(), 1e-12 * box_volume(box));
      // Full extents: twice the semi-axes.
      const auto corners = box_corners(box);
      for (int i = 0; i < 3; ++i) {
        EXPECT_NEAR((corners[1 << i] - corners[0]).norm(), 2.0 * semi_axes[i], 1e-12);
      }
      // Every corner sits at (±a, ±b, ±c) in the ellipsoid's frame.
      for (const Eigen::Vector3d& corner : corners) {
        const Eigen::Vector3d local = rotation.transpose() * (corner - centre);
        EXPECT_TRUE(local.cwiseAbs().isApprox(semi_axes, 1e-12)) << local.transpose();
      }
      // Every face plane is tangent to the ellipsoid: piᵀ Q* pi = 0 with pi = (n, −n·x_face).
      const Eigen::Matrix4d Q = q.matrix();
      for (int i = 0; i < 3; ++i) {
        for (const double sign : {1.0, -1.0}) {
          const Eigen::Vector3d n = sign * box.rotation.col(i);
          const double offset = n.dot(box.centre) + box.half_extents[i];
          const Eigen::Vector4d pi(n.x(), n.y(), n.z(), -offset);
          EXPECT_NEAR(pi.dot(Q * pi), 0.0, 1e-9 * (1.0 + offset * offset));
        }
      }
    }
  }
}

// The same ellipsoid recovered from its matrix has canonical (reordered) axes; its box is the same.
TEST(OrientedBox, BoxFromQuadricIndependentOfParametrisation) {
  for (const std::uint64_t seed : kSeeds) {
    SCOPED_TRACE(seed_trace(seed));
    std::mt19937_64 rng(seed);
    for (int trial = 0; trial < 10; ++trial) {
      const DualQuadric q = DualQuadric::from_params(
          random_vector(rng, -5.0, 5.0), random_rotation(rng), random_vector(rng, 0.1, 2.0));
      const auto recovered = DualQuadric::from_matrix(q.matrix());
      ASSERT_TRUE(recovered.has_value());
      EXPECT_NEAR(iou_3d(box_from_quadric(q), box_from_quadric(*recovered)), 1.0, 1e-9);
    }
  }
}

// The same ellipsoid given with its axes in any order and sign reports one rotation: z nearest
// the map's up and pointing up, x the longer of the others, right-handed; the shape unchanged.
TEST(CanonicalAxes, AnyOrderAndSignOfTheAxesGivesOneRotation) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0), len(0.05, 1.0);
  const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int trial = 0; trial < 200; ++trial) {
    const Eigen::Matrix3d R0 =
        Eigen::Quaterniond(Eigen::Vector4d(u(rng), u(rng), u(rng), u(rng)).normalized()).toRotationMatrix();
    const Eigen::Vector3d e0(len(rng), len(rng), len(rng));
    const Eigen::Matrix3d shape = R0 * e0.array().square().matrix().asDiagonal() * R0.transpose();
    Eigen::Matrix3d R_ref = R0;
    Eigen::Vector3d e_ref = e0;
    canonical_axes(&R_ref, &e_ref);
    // A proper rotation, z up and nearest the map's up, x the longer of the other two.
    EXPECT_NEAR(R_ref.determinant(), 1.0, 1e-9);
    EXPECT_LT((R_ref.transpose() * R_ref - Eigen::Matrix3d::Identity()).norm(), 1e-9);
    EXPECT_GE(R_ref(2, 2), 0.0);
    EXPECT_GE(std::abs(R_ref(2, 2)), std::abs(R_ref(2, 0)) - 1e-12);
    EXPECT_GE(std::abs(R_ref(2, 2)), std::abs(R_ref(2, 1)) - 1e-12);
    EXPECT_GE(e_ref.x(), e_ref.y());
    EXPECT_GE(R_ref(0, 0), 0.0);
    // The shape it describes is the same.
    EXPECT_LT((R_ref * e_ref.array().square().matrix().asDiagonal() * R_ref.transpose() - shape).norm(), 1e-9);
    // Every permutation and sign of the axes gives the same.
    for (const auto& p : perms) {
      for (int signs = 0; signs < 8; ++signs) {
        Eigen::Matrix3d R;
        Eigen::Vector3d e;
        for (int c = 0; c < 3; ++c) {
          R.col(c) = ((signs >> c) & 1 ? -1.0 : 1.0) * R0.col(p[c]);
          e(c) = e0(p[c]);
        }
        canonical_axes(&R, &e);
        EXPECT_LT((R - R_ref).norm(), 1e-12) << "trial " << trial;
        EXPECT_LT((e - e_ref).norm(), 1e-15);
      }
    }
  }
}

}  // namespace
}  // namespace dqo
