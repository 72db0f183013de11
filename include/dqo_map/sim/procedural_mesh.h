#pragma once
// Triangle meshes built from a few parameters: the surfaces of the analytic primitives (for ground
// truth), and the shapes that are rendered as meshes (lathe, extrusion, superquadric). Every mesh
// is closed and wound counter-clockwise seen from outside.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

#include "dqo_map/common/triangle_mesh.h"
#include "dqo_map/geometry/se3.h"

namespace dqo::sim {

TriangleMesh make_quad_mesh(const Eigen::Vector2d& size);
TriangleMesh make_box_mesh(const Eigen::Vector3d& size);
// `segments` around the equator, segments / 2 from pole to pole; the poles, the equator and the
// ends of the x and y axes are vertices (when segments is a multiple of 4), so the mesh's bounding
// box is the ellipsoid's.
TriangleMesh make_ellipsoid_mesh(const Eigen::Vector3d& radii, int segments);
TriangleMesh make_cylinder_mesh(double radius, double height, int segments);

// Surface of revolution about the local z axis of a profile of (r, z) points, r >= 0, swept with
// `segments` steps. A profile point with r = 0 becomes a single pole vertex. To be closed, the
// profile starts and ends on the axis; it may double back, which is how a hollow cup is made: axis
// → outer bottom edge → outer rim → inner rim → inner bottom → axis gives a closed solid with an
// inner wall and a floor (a "thick-walled" cup, not an infinitely thin one, so it has a volume and
// a well-defined inside). The winding is fixed afterwards so that the enclosed volume is positive,
// whichever way the profile runs.
TriangleMesh make_lathe_mesh(const std::vector<Eigen::Vector2d>& profile, int segments);

// Centripetal Catmull-Rom resampling of a profile: `subdivisions` points between each pair of
// input points (0 returns the input). Rounds a bottle's shoulder from a handful of control points;
// the end points and every control point are kept.
std::vector<Eigen::Vector2d> smooth_profile(const std::vector<Eigen::Vector2d>& points,
                                            int subdivisions);

// Prism of a simple polygon in the local xy plane (either orientation), extruded along z over
// [-depth / 2, depth / 2]; the caps are ear-clipped. Empty mesh when the polygon is degenerate.
TriangleMesh make_extrusion_mesh(const std::vector<Eigen::Vector2d>& polygon, double depth);

// Superquadric |x/a|^(2/e2) + |y/b|^(2/e2))^(e2/e1) + |z/c|^(2/e1) = 1, sampled with the usual
// signed-power parametrisation (e1 shapes the latitude, e2 the longitude; 1, 1 is an ellipsoid,
// small values approach a box). `segments` around, segments / 2 pole to pole.
TriangleMesh make_superquadric_mesh(const Eigen::Vector3d& radii, double e1, double e2,
                                    int segments);

// Appends `part` mapped by p -> T * (scale * p).
void append_mesh(const TriangleMesh& part, const SE3& T, double scale, TriangleMesh* out);

// Signed volume (positive for a closed, outward-wound mesh).
double signed_volume(const TriangleMesh& mesh);

}  // namespace dqo::sim
