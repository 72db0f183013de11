#pragma once
// Projection of a dual quadric into an image: the dual conic C* = P Q* Pᵀ and its bounding box.
//
// The box is closed form: a vertical line x = u, l = (1, 0, −u), is tangent to the conic iff
// lᵀ C* l = 0, i.e. C*₂₂ u² − 2 C*₀₂ u + C*₀₀ = 0, u = (C*₀₂ ± sqrt(C*₀₂² − C*₀₀ C*₂₂)) / C*₂₂;
// the same with C*₁₂, C*₁₁ for horizontal lines.

#include <optional>

#include <Eigen/Core>

#include "dqo_map/geometry/box2d.h"
#include "dqo_map/geometry/dual_quadric.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"

namespace dqo {

// C* = P Q* Pᵀ with Q* = quadric.matrix() (scale fixed by Q*(3,3) = −1).
Eigen::Matrix3d project_quadric(const DualQuadric& quadric, const Eigen::Matrix<double, 3, 4>& P);

// The bounding box of the conic. C* must carry the scale of project_quadric (Q*(3,3) = −1, any
// scale of P): then C*₂₂ = p₃ᵀ Q* p₃ is negative exactly when the camera plane (third row p₃ of P)
// misses the ellipsoid. nullopt when C* is not finite, C*₂₂ >= −eps (the ellipsoid straddles or
// touches the camera plane, so its image is unbounded) or a discriminant is negative. An ellipsoid
// wholly behind the camera also gives a box here: in_front_of_camera tells the two apart.
std::optional<Box2d> conic_bounding_box(const Eigen::Matrix3d& Cstar);

// True when every point of the ellipsoid has camera depth > near: with r₃ the optical axis in world
// (third row of R_cw) and S the shape matrix, the smallest depth is z_c(centre) − sqrt(r₃ᵀ S r₃).
bool in_front_of_camera(const DualQuadric& quadric, const SE3& T_cw, double near = 0.0);

// The ellipse of a dual conic, as drawing libraries take it (cv::ellipse: centre, semi-axes, angle).
// With C* scaled to C*₂₂ = −1 an ellipse of centre c and shape M (points x with
// (x − c)ᵀ M⁻¹ (x − c) = 1) is C* = [[M − c cᵀ, −c], [−cᵀ, −1]] (the 2D analogue of the dual
// quadric), so c = −C*₀:₂,₂ and M = C*₀:₂,₀:₂ + c cᵀ, whose eigen-decomposition gives the axes.
struct Ellipse2d {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();      // pixels
  Eigen::Vector2d semi_axes = Eigen::Vector2d::Zero();   // pixels, the first the larger
  double angle = 0.0;  // radians from the image's +x axis to the first semi-axis (towards +y)
};
// nullopt where conic_bounding_box has none (not an ellipse in front of the camera) or M is not
// positive definite.
std::optional<Ellipse2d> conic_ellipse(const Eigen::Matrix3d& Cstar);

struct ProjectedBox {
  Box2d box;                       // clipped to the image; empty when wholly outside it
  Box2d unclipped;                 // the conic's box
  double fraction_in_image = 0.0;  // area(box) / area(unclipped), for the "≥ 30 % in image" rule
};

// The object's box in an image: nullopt when the ellipsoid is not wholly in front of the camera
// (depth > near) or its conic has no bounded box.
std::optional<ProjectedBox> projected_box(const DualQuadric& quadric, const PinholeCamera& camera,
                                          const SE3& T_cw, double near = 0.0);

}  // namespace dqo
