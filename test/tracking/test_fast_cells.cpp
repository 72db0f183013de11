// detect_cell_corners (tracking/fast_cells.h) against the plain computation it replaces: one FAST
// pass at the low threshold over the whole search area, bucketed into cells, each cell keeping its
// strong corners where it has any.
#include <algorithm>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "fast_cells.h"

namespace {

using dqo::tracking::CellGrid;
using dqo::tracking::detect_cell_corners;

// Blurred noise whose contrast falls from left to right and from top to bottom: strong corners
// on one side, cells with weak corners only on the other, and flat cells with none.
cv::Mat fading_texture(unsigned seed, int width, int height) {
  cv::RNG rng(seed);
  cv::Mat noise(height, width, CV_32F);
  rng.fill(noise, cv::RNG::UNIFORM, -1.0, 1.0);
  cv::GaussianBlur(noise, noise, cv::Size(0, 0), 1.2);
  cv::Mat out(height, width, CV_8U);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const double gain = 400.0 * (1.0 - 0.5 * x / width - 0.5 * y / height);
      out.at<uchar>(y, x) = cv::saturate_cast<uchar>(128.0 + gain * noise.at<float>(y, x));
    }
  }
  return out;
}

CellGrid reference(const cv::Mat& image, const cv::Rect& area, int cell, int high, int low) {
  CellGrid g;
  g.cell_px = cell;
  g.cols = (area.width + cell - 1) / cell;
  g.rows = (area.height + cell - 1) / cell;
  g.cells.resize(static_cast<size_t>(g.cols) * g.rows);
  std::vector<cv::KeyPoint> corners;
  cv::FAST(image(area), corners, low, true);
  for (const cv::KeyPoint& k : corners) {
    const int cx = static_cast<int>(k.pt.x) / cell, cy = static_cast<int>(k.pt.y) / cell;
    g.cells[static_cast<size_t>(cy) * g.cols + cx].push_back(k);
  }
  for (auto& c : g.cells) {
    const bool strong = std::any_of(c.begin(), c.end(), [&](const cv::KeyPoint& k) {
      return k.response >= high;
    });
    if (strong) {
      c.erase(std::remove_if(c.begin(), c.end(),
                             [&](const cv::KeyPoint& k) { return k.response < high; }),
              c.end());
    }
  }
  return g;
}

TEST(FastCells, SameCornersAsOneLowThresholdPassOverTheWholeArea) {
  struct Case {
    int width, height, margin, cell, high, low;
  };
  // Areas that are and are not multiples of the cell; ORB-SLAM2's thresholds and others.
  const Case cases[] = {{640, 480, 16, 30, 20, 7},  {533, 400, 16, 30, 20, 7},
                        {212, 159, 16, 30, 20, 7},  {640, 480, 0, 16, 30, 5},
                        {301, 257, 5, 23, 12, 11}, {640, 480, 16, 30, 20, 20}};
  int strong_cells = 0, weak_cells = 0, weak_corners = 0;
  for (unsigned seed = 1; seed <= 3; ++seed) {
    for (const Case& c : cases) {
      const cv::Mat image = fading_texture(seed, c.width, c.height);
      const cv::Rect area(c.margin, c.margin, c.width - 2 * c.margin, c.height - 2 * c.margin);
      const CellGrid want = reference(image, area, c.cell, c.high, c.low);
      CellGrid got;
      got.cells.resize(3, {cv::KeyPoint(1, 2, 3)});  // stale contents must not survive
      detect_cell_corners(image, area, c.cell, c.high, c.low, &got);
      ASSERT_EQ(got.cols, want.cols);
      ASSERT_EQ(got.rows, want.rows);
      ASSERT_EQ(got.cells.size(), want.cells.size());
      for (size_t i = 0; i < want.cells.size(); ++i) {
        ASSERT_EQ(got.cells[i].size(), want.cells[i].size()) << "cell " << i;
        for (size_t j = 0; j < want.cells[i].size(); ++j) {
          EXPECT_EQ(got.cells[i][j].pt, want.cells[i][j].pt) << "cell " << i << " corner " << j;
          EXPECT_EQ(got.cells[i][j].response, want.cells[i][j].response);
        }
        if (want.cells[i].empty()) continue;
        const bool strong = want.cells[i].front().response >= c.high;
        strong_cells += strong;
        weak_cells += !strong;
        if (!strong) weak_corners += static_cast<int>(want.cells[i].size());
      }
    }
  }
  // Both kinds of cell were exercised (the second pass had corners to find).
  EXPECT_GT(strong_cells, 100);
  EXPECT_GT(weak_cells, 100);
  EXPECT_GT(weak_corners, 300);
}

}  // namespace
