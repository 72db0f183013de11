#pragma once
// Axis-aligned image boxes (detections and projected conics), in continuous pixel coordinates: the
// image covers [0, width] x [0, height] (see pinhole_camera.h for the pixel convention).
//
// An "empty" box (x_max <= x_min or y_max <= y_min) is a legal value: it is what the intersection of
// disjoint boxes or the clip of an off-image box gives, and has area 0.

#include <array>

#include <Eigen/Core>

namespace dqo {

struct Box2d {
  double x_min = 0.0;
  double y_min = 0.0;
  double x_max = 0.0;
  double y_max = 0.0;

  double width() const { return x_max - x_min; }
  double height() const { return y_max - y_min; }
  // 0 for an empty box, never negative.
  double area() const;
  Eigen::Vector2d centre() const { return {0.5 * (x_min + x_max), 0.5 * (y_min + y_max)}; }

  // Finite and of positive width and height.
  bool valid() const;

  // The part of the box inside the image [0, width] x [0, height]; empty when it lies outside.
  Box2d clip(int image_width, int image_height) const;

  // True when any edge lies within margin_px of the image border (or beyond it).
  bool touches_border(int image_width, int image_height, double margin_px) const;

  // The same test per edge, in the order of edge_lines(): x_min, x_max, y_min, y_max.
  std::array<bool, 4> edges_touching_border(int image_width, int image_height,
                                            double margin_px) const;

  // The homogeneous image lines l (lᵀ [u v 1]ᵀ = 0) of x = x_min, x = x_max, y = y_min, y = y_max.
  std::array<Eigen::Vector3d, 4> edge_lines() const;
};

// The overlap of a and b; empty when they are disjoint.
Box2d intersection(const Box2d& a, const Box2d& b);

// Intersection over union in [0, 1]; 0 when the union has no area.
double iou(const Box2d& a, const Box2d& b);

// area(big ∩ small) / area(small): how much of `small` is covered by `big` (METHOD.md §2.5, t).
// 0 when `small` has no area.
double overlap_ratio(const Box2d& big, const Box2d& small);

// The plane pi = Pᵀ l back-projected from image line l through the camera P = K[R|t]: every world
// point X that projects onto l satisfies piᵀ X = 0.
Eigen::Vector4d plane_from_line(const Eigen::Matrix<double, 3, 4>& P, const Eigen::Vector3d& l);

}  // namespace dqo
