// Shapes: analytic intersections against their implicit equations, the BVH against brute force,
// the procedural meshes closed, outward and of the right volume.

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <utility>

#include "dqo_map/sim/mesh_shape.h"
#include "dqo_map/sim/primitives.h"
#include "dqo_map/sim/procedural_mesh.h"
#include "dqo_map/sim/triangle_bvh.h"
#include "dqo_map/sim/union_shape.h"
#include "sim_test_utils.h"

namespace dqo::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;

// A ray from a random point on a sphere of radius `r` towards a random point near the origin, with
// a direction of random length (shapes must not assume unit directions).
Ray random_ray(std::mt19937_64& rng, double r, double spread) {
  std::normal_distribution<double> n(0.0, 1.0);
  std::uniform_real_distribution<double> u(-1.0, 1.0), len(0.3, 3.0);
  Ray ray;
  ray.origin = Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized() * r;
  const Eigen::Vector3d target(spread * u(rng), spread * u(rng), spread * u(rng));
  ray.direction = (target - ray.origin).normalized() * len(rng);
  return ray;
}

// Every directed edge once, and its reverse once: closed, consistently wound, manifold.
void expect_closed(const TriangleMesh& mesh) {
  std::map<std::pair<int, int>, int> edges;
  for (const auto& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) ++edges[{t[k], t[(k + 1) % 3]}];
  }
  int bad = 0;
  for (const auto& [e, count] : edges) {
    const auto rev = edges.find({e.second, e.first});
    if (count != 1 || rev == edges.end() || rev->second != 1) ++bad;
  }
  EXPECT_EQ(bad, 0) << "edges without exactly one opposite partner";
  EXPECT_GT(signed_volume(mesh), 0.0);
}

TEST(Primitives, QuadHitIsOnThePlaneInsideTheRectangle) {
  const Quad quad(Eigen::Vector2d(2.0, 1.0));
  std::mt19937_64 rng(1);
  int hits = 0;
  for (int i = 0; i < 2000; ++i) {
    const Ray ray = random_ray(rng, 3.0, 1.2);
    Hit hit;
    const bool h = quad.intersect(ray, 0.0, kInfinity, &hit);
    // Independent: where the ray crosses z = 0.
    const double t = -ray.origin.z() / ray.direction.z();
    const Eigen::Vector3d p = ray.origin + t * ray.direction;
    const bool expected = t > 0.0 && std::abs(p.x()) <= 1.0 && std::abs(p.y()) <= 0.5;
    ASSERT_EQ(h, expected);
    if (h) {
      ++hits;
      EXPECT_NEAR(hit.t, t, 1e-12 * std::abs(t));
      EXPECT_EQ(hit.normal, Eigen::Vector3d::UnitZ());
    }
  }
  EXPECT_GT(hits, 100);
}

TEST(Primitives, AnalyticHitsLieOnTheirSurfaces) {
  const Box box(Eigen::Vector3d(0.4, 0.6, 0.2));
  const Ellipsoid ell(Eigen::Vector3d(0.3, 0.5, 0.2));
  const Cylinder cyl(0.25, 0.6);
  std::mt19937_64 rng(2);
  int hits[3] = {0, 0, 0};
  for (int i = 0; i < 3000; ++i) {
    const Ray ray = random_ray(rng, 2.0, 0.5);
    Hit hit;
    if (box.intersect(ray, 0.0, kInfinity, &hit)) {
      ++hits[0];
      const Eigen::Vector3d p = ray.origin + hit.t * ray.direction;
      const Eigen::Vector3d q = p.cwiseAbs().cwiseQuotient(Eigen::Vector3d(0.2, 0.3, 0.1));
      EXPECT_NEAR(q.maxCoeff(), 1.0, 1e-12);
      EXPECT_LT(hit.normal.dot(ray.direction), 0.0);  // from outside: the entering face
    }
    if (ell.intersect(ray, 0.0, kInfinity, &hit)) {
      ++hits[1];
      const Eigen::Vector3d p = ray.origin + hit.t * ray.direction;
      EXPECT_NEAR(p.cwiseQuotient(Eigen::Vector3d(0.3, 0.5, 0.2)).squaredNorm(), 1.0, 1e-12);
      const Eigen::Vector3d grad = p.cwiseQuotient(Eigen::Vector3d(0.09, 0.25, 0.04)).normalized();
      EXPECT_NEAR((hit.normal - grad).norm(), 0.0, 1e-12);
    }
    if (cyl.intersect(ray, 0.0, kInfinity, &hit)) {
      ++hits[2];
      const Eigen::Vector3d p = ray.origin + hit.t * ray.direction;
      const double r = std::hypot(p.x(), p.y());
      const bool on_side = std::abs(r - 0.25) < 1e-12 && std::abs(p.z()) <= 0.3 + 1e-12;
      const bool on_cap = std::abs(std::abs(p.z()) - 0.3) < 1e-12 && r <= 0.25 + 1e-12;
      EXPECT_TRUE(on_side || on_cap) << p.transpose();
      EXPECT_LT(hit.normal.dot(ray.direction), 0.0);
    }
  }
  for (const int h : hits) EXPECT_GT(h, 300);
}

TEST(Primitives, AnalyticShapesAgreeWithTheirGroundTruthMeshes) {
  // The renderer draws the analytic surface, meshes_gt holds the tessellation: every analytic hit
  // must lie well under a millimetre from the mesh, and the mesh must be closed and outward.
  std::vector<std::shared_ptr<const Shape>> shapes = {
      std::make_shared<Box>(Eigen::Vector3d(0.4, 0.6, 0.2)),
      std::make_shared<Ellipsoid>(Eigen::Vector3d(0.3, 0.5, 0.2)),
      std::make_shared<Cylinder>(0.25, 0.6)};
  std::mt19937_64 rng(3);
  for (const auto& shape : shapes) {
    const TriangleMesh mesh = shape->surface_mesh();
    expect_closed(mesh);
    int compared = 0;
    double worst = 0.0;
    for (int i = 0; i < 300; ++i) {
      const Ray ray = random_ray(rng, 2.0, 0.4);
      Hit hit;
      if (!shape->intersect(ray, 0.0, kInfinity, &hit)) continue;
      ++compared;
      worst =
          std::max(worst, testing::point_mesh_distance(ray.origin + hit.t * ray.direction, mesh));
    }
    EXPECT_LT(worst, 4e-4) << shape->type_name();
    EXPECT_GT(compared, 60) << shape->type_name();
  }
}

TEST(Primitives, RayFromInsideABoxHitsTheExitFace) {
  const Box room(Eigen::Vector3d(4.0, 4.0, 2.0));
  Ray ray;
  ray.origin = Eigen::Vector3d(0.5, 0.0, 0.0);
  ray.direction = Eigen::Vector3d(2.0, 0.0, 0.0);
  Hit hit;
  ASSERT_TRUE(room.intersect(ray, 0.0, kInfinity, &hit));
  EXPECT_DOUBLE_EQ(hit.t, 0.75);
  EXPECT_EQ(hit.normal, Eigen::Vector3d::UnitX());
}

TEST(Primitives, IntervalBoundsAreRespected) {
  const Ellipsoid sphere(Eigen::Vector3d::Constant(1.0));
  Ray ray;
  ray.origin = Eigen::Vector3d(0.0, 0.0, -3.0);
  ray.direction = Eigen::Vector3d::UnitZ();
  Hit hit;
  ASSERT_TRUE(sphere.intersect(ray, 0.0, kInfinity, &hit));
  EXPECT_DOUBLE_EQ(hit.t, 2.0);
  ASSERT_TRUE(sphere.intersect(ray, 2.5, kInfinity, &hit));  // the far side
  EXPECT_DOUBLE_EQ(hit.t, 4.0);
  EXPECT_FALSE(sphere.intersect(ray, 0.0, 1.9, &hit));
  EXPECT_FALSE(sphere.any_hit(ray, 4.1, kInfinity));
}

// Brute-force Möller–Trumbore over all triangles, written again here.
bool brute_force(const TriangleMesh& m, const Ray& ray, double* t_best) {
  bool found = false;
  *t_best = kInfinity;
  for (const auto& tri : m.triangles) {
    const Eigen::Vector3d a = m.vertices[tri[0]], e1 = m.vertices[tri[1]] - a,
                          e2 = m.vertices[tri[2]] - a;
    const Eigen::Vector3d n = e1.cross(e2);
    const double denom = n.dot(ray.direction);
    if (denom == 0.0) continue;
    const double t = n.dot(a - ray.origin) / denom;
    if (!(t > 0.0) || t >= *t_best) continue;
    const Eigen::Vector3d p = ray.origin + t * ray.direction - a;
    // Barycentric coordinates by areas.
    const double area = n.squaredNorm();
    const double v = e1.cross(p).dot(n) / area;
    const double u = p.cross(e2).dot(n) / area;
    if (u >= -1e-9 && v >= -1e-9 && u + v <= 1.0 + 1e-9) {
      *t_best = t;
      found = true;
    }
  }
  return found;
}

TEST(TriangleBvh, MatchesBruteForce) {
  const TriangleMesh cup = make_lathe_mesh(
      {{0, 0}, {0.034, 0}, {0.04, 0.10}, {0.036, 0.10}, {0.0305, 0.008}, {0, 0.008}}, 64);
  const TriangleMesh sq = make_superquadric_mesh(Eigen::Vector3d(0.3, 0.2, 0.1), 0.3, 0.6, 48);
  for (const TriangleMesh* mesh : {&cup, &sq}) {
    const TriangleBvh bvh(*mesh);
    EXPECT_LE(bvh.depth(), TriangleBvh::kMaxDepth);
    std::mt19937_64 rng(4);
    int hits = 0;
    for (int i = 0; i < 3000; ++i) {
      Ray ray = random_ray(rng, 0.6, 0.1);
      ray.origin.z() += 0.05;
      double t_ref;
      const bool ref = brute_force(*mesh, ray, &t_ref);
      TriangleHit h;
      const bool got = bvh.intersect(ray, 0.0, kInfinity, &h);
      ASSERT_EQ(got, ref) << "ray " << i;
      EXPECT_EQ(bvh.any_hit(ray, 0.0, kInfinity), ref);
      if (got) {
        ++hits;
        EXPECT_NEAR(h.t, t_ref, 1e-9);
      }
    }
    EXPECT_GT(hits, 500);
  }
}

TEST(ProceduralMesh, LatheCupIsClosedWithTheRightVolume) {
  // Solid of revolution of the profile: outer frustum minus the inner (hollow) frustum.
  const TriangleMesh cup = make_lathe_mesh(
      {{0, 0}, {0.034, 0}, {0.04, 0.10}, {0.036, 0.10}, {0.0305, 0.008}, {0, 0.008}}, 256);
  expect_closed(cup);
  auto frustum = [](double r0, double r1, double h) {
    return kPi * h / 3.0 * (r0 * r0 + r0 * r1 + r1 * r1);
  };
  const double expected = frustum(0.034, 0.04, 0.10) - frustum(0.0305, 0.036, 0.092);
  EXPECT_NEAR(signed_volume(cup), expected, 2e-3 * expected);
}

TEST(ProceduralMesh, LatheWindingIsOutwardEitherWay) {
  std::vector<Eigen::Vector2d> profile = {{0, 0}, {0.1, 0}, {0.1, 0.2}, {0, 0.2}};
  const double v1 = signed_volume(make_lathe_mesh(profile, 64));
  std::reverse(profile.begin(), profile.end());
  const double v2 = signed_volume(make_lathe_mesh(profile, 64));
  EXPECT_GT(v1, 0.0);
  EXPECT_NEAR(v1, v2, 1e-12);
}

TEST(ProceduralMesh, ExtrusionOfANonConvexPolygon) {
  // An L: area 0.3 * 0.1 + 0.1 * 0.2 = 0.05, in clockwise order to test the reorientation.
  const std::vector<Eigen::Vector2d> l = {{0, 0},     {0, 0.3},   {0.1, 0.3},
                                          {0.1, 0.1}, {0.3, 0.1}, {0.3, 0}};
  const TriangleMesh m = make_extrusion_mesh(l, 0.2);
  expect_closed(m);
  EXPECT_NEAR(signed_volume(m), 0.05 * 0.2, 1e-12);
}

TEST(ProceduralMesh, BoxEllipsoidCylinderSuperquadric) {
  const TriangleMesh box = make_box_mesh(Eigen::Vector3d(0.2, 0.3, 0.4));
  expect_closed(box);
  EXPECT_NEAR(signed_volume(box), 0.024, 1e-12);
  const TriangleMesh ell = make_ellipsoid_mesh(Eigen::Vector3d(0.1, 0.2, 0.3), 256);
  expect_closed(ell);
  EXPECT_NEAR(signed_volume(ell), 4.0 / 3.0 * kPi * 0.006, 1e-3 * 4.0 / 3.0 * kPi * 0.006);
  const TriangleMesh cyl = make_cylinder_mesh(0.1, 0.5, 256);
  expect_closed(cyl);
  EXPECT_NEAR(signed_volume(cyl), kPi * 0.01 * 0.5, 1e-3 * kPi * 0.01 * 0.5);
  // Exponents 1, 1 give the ellipsoid; small exponents approach the box.
  const TriangleMesh sq1 = make_superquadric_mesh(Eigen::Vector3d(0.1, 0.2, 0.3), 1.0, 1.0, 256);
  expect_closed(sq1);
  EXPECT_NEAR(signed_volume(sq1), signed_volume(ell), 1e-3 * signed_volume(ell));
  const TriangleMesh sq0 = make_superquadric_mesh(Eigen::Vector3d(0.1, 0.2, 0.3), 0.1, 0.1, 128);
  expect_closed(sq0);
  EXPECT_GT(signed_volume(sq0), 0.9 * 0.2 * 0.4 * 0.6);
}

TEST(ProceduralMesh, SmoothProfileKeepsControlPointsAndCorners) {
  const std::vector<Eigen::Vector2d> p = {{0, 0},      {0.036, 0},    {0.037, 0.15},
                                          {0.02, 0.2}, {0.014, 0.24}, {0, 0.25}};
  const auto s = smooth_profile(p, 4);
  EXPECT_EQ(s.size(), (p.size() - 1) * 5 + 1);
  for (size_t i = 0; i < p.size(); ++i) EXPECT_EQ(s[i * 5], p[i]);
  for (const auto& q : s) {
    EXPECT_GE(q.y(), 0.0) << "the base must not sag below z = 0";
    EXPECT_GE(q.x(), 0.0);
  }
}

TEST(UnionShape, PartsKeepTheirFramesAndMaterialIndex) {
  std::vector<UnionPart> parts;
  parts.push_back({std::make_shared<Box>(Eigen::Vector3d(1.0, 1.0, 0.1)), SE3()});
  // A thin upright plate, turned 90 degrees about x, standing at y = 0.5.
  const SE3 T_up(Eigen::Quaterniond(Eigen::AngleAxisd(kPi / 2, Eigen::Vector3d::UnitX())),
                 Eigen::Vector3d(0.0, 0.5, 0.5));
  parts.push_back({std::make_shared<Box>(Eigen::Vector3d(1.0, 1.0, 0.02)), T_up});
  const UnionShape u(std::move(parts));
  EXPECT_EQ(u.num_parts(), 2);
  Ray ray;
  ray.origin = Eigen::Vector3d(0.0, -2.0, 0.5);
  ray.direction = Eigen::Vector3d::UnitY();
  Hit hit;
  ASSERT_TRUE(u.intersect(ray, 0.0, kInfinity, &hit));
  EXPECT_EQ(hit.part, 1);
  EXPECT_NEAR(hit.t, 2.49, 1e-12);
  EXPECT_NEAR((hit.normal - Eigen::Vector3d(0, -1, 0)).norm(), 0.0, 1e-12);  // union frame
  EXPECT_NEAR(std::abs(hit.tex_point.z()), 0.01, 1e-12);                     // part frame
  ray.origin = Eigen::Vector3d(0.2, 0.0, 2.0);
  ray.direction = -Eigen::Vector3d::UnitZ();
  ASSERT_TRUE(u.intersect(ray, 0.0, kInfinity, &hit));
  EXPECT_EQ(hit.part, 0);
  EXPECT_NEAR(hit.t, 1.95, 1e-12);
  // Bounds hold both parts' meshes.
  const Aabb b = u.bounds();
  for (const auto& v : u.surface_mesh().vertices) {
    EXPECT_TRUE((v.array() >= b.min.array() - 1e-12).all() &&
                (v.array() <= b.max.array() + 1e-12).all());
  }
}

TEST(MeshShape, InterpolatedNormalsAreSmoothButCreasesStaySharp) {
  const MeshShape cyl(make_cylinder_mesh(0.5, 1.0, 32), "lathe");
  Ray ray;
  ray.origin = Eigen::Vector3d(-3.0, 0.05, 0.0);  // hits the side between two ring vertices
  ray.direction = Eigen::Vector3d::UnitX();
  Hit hit;
  ASSERT_TRUE(cyl.intersect(ray, 0.0, kInfinity, &hit));
  const Eigen::Vector3d p = ray.origin + hit.t * ray.direction;
  const Eigen::Vector3d radial = Eigen::Vector3d(p.x(), p.y(), 0.0).normalized();
  EXPECT_GT(hit.normal.dot(radial), 0.9999);  // smooth: close to the true cylinder normal
  EXPECT_NEAR(hit.normal.z(), 0.0, 1e-9);     // the cap's normal did not leak in
  ray.origin = Eigen::Vector3d(0.49 * std::cos(0.1), 0.49 * std::sin(0.1), 3.0);
  ray.direction = -Eigen::Vector3d::UnitZ();
  ASSERT_TRUE(cyl.intersect(ray, 0.0, kInfinity, &hit));
  EXPECT_NEAR(hit.normal.z(), 1.0, 1e-9);  // the cap stays flat up to its rim
}

}  // namespace
}  // namespace dqo::sim
