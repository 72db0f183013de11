#pragma once
// FAST corners of one pyramid level bucketed into grid cells, with ORB-SLAM2's two thresholds: a
// cell keeps its corners that pass the high threshold where it has any, else those that pass the
// low one. OrbExtractor ranks and spreads them (orb_frame.cpp).
//
// The result is exactly that of one non-max-suppressed FAST pass at the low threshold over the
// whole search area, filtered per cell, but cheaper: one pass at the high threshold over the area,
// then a low-threshold pass only over the runs of cells the first left empty. FAST at a low
// threshold on a textured image spends its time scoring and suppressing thousands of weak corners
// that a cell with a strong one throws away (TUM fr1: 14k corners per frame at 7, 8k at 20; the
// search took 3.9 ms of a 22 ms frame). Why the two passes agree: a corner's FAST score does not
// depend on the threshold it was found at, and non-maximum suppression only removes a corner
// beside a higher-scoring one, which passes the high threshold whenever the corner does; the low
// pass over a run is widened by kBorderPx, so that its corners see the same circle and the same
// neighbours as in a pass over the whole area.
//
// Private to tracking/ (OpenCV).

#include <vector>

#include <opencv2/core.hpp>

namespace dqo::tracking {

struct CellGrid {
  int cols = 0;
  int rows = 0;
  int cell_px = 0;
  // Per cell (row-major), its corners in the raster order FAST finds them, in the coordinates of
  // the search area.
  std::vector<std::vector<cv::KeyPoint>> cells;
};

// FAST reads a circle of radius 3 around a pixel; suppression compares it with its 8 neighbours.
constexpr int kFastBorderPx = 4;

// Corners inside `area` of `image` (FAST's 3-pixel border is inside the area) in cells of
// `cell_px`; cells at the right and bottom edge take the remainder. A cell keeps its corners of
// score >= high where it has any, else those of score >= low. Reuses grid's buffers.
void detect_cell_corners(const cv::Mat& image, const cv::Rect& area, int cell_px, int high,
                         int low, CellGrid* grid);

}  // namespace dqo::tracking
