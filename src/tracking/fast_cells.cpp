#include "fast_cells.h"

#include <algorithm>

#include <opencv2/features2d.hpp>

namespace dqo::tracking {

void detect_cell_corners(const cv::Mat& image, const cv::Rect& area, int cell_px, int high,
                         int low, CellGrid* grid) {
  grid->cell_px = std::max(1, cell_px);
  grid->cols = std::max(1, (area.width + grid->cell_px - 1) / grid->cell_px);
  grid->rows = std::max(1, (area.height + grid->cell_px - 1) / grid->cell_px);
  grid->cells.resize(static_cast<size_t>(grid->cols) * grid->rows);
  for (auto& c : grid->cells) c.clear();
  const cv::Mat search = image(area);
  auto cell_of = [&](const cv::KeyPoint& k) -> std::vector<cv::KeyPoint>& {
    const int cx = std::min(grid->cols - 1, static_cast<int>(k.pt.x) / grid->cell_px);
    const int cy = std::min(grid->rows - 1, static_cast<int>(k.pt.y) / grid->cell_px);
    return grid->cells[static_cast<size_t>(cy) * grid->cols + cx];
  };

  std::vector<cv::KeyPoint> corners;
  cv::FAST(search, corners, std::max(high, low), true);
  for (const cv::KeyPoint& k : corners)
    if (k.response >= high) cell_of(k).push_back(k);
  if (low >= high) return;  // every corner the low threshold finds is already strong

  // Runs of consecutive empty cells along a row of cells: one low-threshold pass each.
  for (int cy = 0; cy < grid->rows; ++cy) {
    const auto empty = [&](int cx) {
      return grid->cells[static_cast<size_t>(cy) * grid->cols + cx].empty();
    };
    for (int cx = 0; cx < grid->cols;) {
      if (!empty(cx)) {
        ++cx;
        continue;
      }
      int end = cx;
      while (end < grid->cols && empty(end)) ++end;
      const int x0 = cx * grid->cell_px, y0 = cy * grid->cell_px;
      const int x1 = std::min(area.width, end * grid->cell_px);
      const int y1 = std::min(area.height, y0 + grid->cell_px);
      const int wx0 = std::max(0, x0 - kFastBorderPx), wy0 = std::max(0, y0 - kFastBorderPx);
      const int wx1 = std::min(area.width, x1 + kFastBorderPx);
      const int wy1 = std::min(area.height, y1 + kFastBorderPx);
      corners.clear();
      cv::FAST(search(cv::Rect(wx0, wy0, wx1 - wx0, wy1 - wy0)), corners, low, true);
      for (cv::KeyPoint& k : corners) {
        k.pt.x += static_cast<float>(wx0);
        k.pt.y += static_cast<float>(wy0);
        if (k.pt.x >= x0 && k.pt.x < x1 && k.pt.y >= y0 && k.pt.y < y1) cell_of(k).push_back(k);
      }
      cx = end;
    }
  }
}

}  // namespace dqo::tracking
