#include "dqo_map/objects/object_overlay.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <opencv2/imgproc.hpp>

#include "dqo_map/geometry/conic.h"

namespace dqo::objects {
namespace {

cv::Scalar scalar(const Rgb& c) { return cv::Scalar(c[0], c[1], c[2]); }  // the image is R G B

// Text with a dark outline, readable on any background.
void label(cv::Mat* image, const std::string& text, cv::Point at, const cv::Scalar& colour) {
  cv::putText(*image, text, at, cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
  cv::putText(*image, text, at, cv::FONT_HERSHEY_SIMPLEX, 0.45, colour, 1, cv::LINE_AA);
}

}  // namespace

Rgb overlay_colour(ObjectId id) {
  const double hue = std::fmod(0.1 + 0.618033988749895 * static_cast<double>(id), 1.0);
  // HSV with full saturation and value: bright on the dark outline of labels.
  const double h6 = hue * 6.0;
  const int sector = static_cast<int>(h6) % 6;
  const double f = h6 - std::floor(h6);
  const auto u8 = [](double v) { return static_cast<uint8_t>(std::lround(255.0 * v)); };
  const uint8_t up = u8(f), down = u8(1.0 - f);
  switch (sector) {
    case 0: return {255, up, 0};
    case 1: return {down, 255, 0};
    case 2: return {0, 255, up};
    case 3: return {0, down, 255};
    case 4: return {up, 0, 255};
    default: return {255, 0, down};
  }
}

ImageRgb8 draw_object_overlay(const ImageRgb8& rgb, const PinholeCamera& camera, const SE3& T_wc,
                              const std::vector<OverlayDetection>& detections,
                              const std::vector<MapObject>& objects) {
  ImageRgb8 out = rgb;
  if (rgb.channels != 3 || !rgb.same_size(camera.width, camera.height) || rgb.empty()) return out;
  cv::Mat image(out.height, out.width, CV_8UC3, out.data.data());  // draws into out
  const SE3 T_cw = T_wc.inverse();
  const Eigen::Matrix<double, 3, 4> P = camera.projection_matrix(T_cw);

  struct Placed {
    ObjectId id;
    Eigen::Vector2d centre;
  };
  std::vector<Placed> centres;
  for (const MapObject& o : objects) {
    if (!o.has_quadric || !in_front_of_camera(o.quadric, T_cw, 0.05)) continue;
    const auto e = conic_ellipse(project_quadric(o.quadric, P));
    // Far larger than the image: drawn as an outline it would only cross it; skip.
    if (!e || e->semi_axes(0) > 4.0 * std::max(camera.width, camera.height)) continue;
    cv::ellipse(image, cv::Point2d(e->centre.x(), e->centre.y()), cv::Size2d(e->semi_axes(0), e->semi_axes(1)),
                e->angle * 180.0 / M_PI, 0.0, 360.0, scalar(overlay_colour(o.id)), 2, cv::LINE_AA);
    centres.push_back({o.id, e->centre});
  }
  for (const OverlayDetection& d : detections) {
    if (!d.box.valid()) continue;
    const Rgb colour = d.object_id != 0 ? overlay_colour(d.object_id) : kUnmatchedColour;
    const cv::Point p0(static_cast<int>(std::lround(d.box.x_min)), static_cast<int>(std::lround(d.box.y_min)));
    const cv::Point p1(static_cast<int>(std::lround(d.box.x_max)), static_cast<int>(std::lround(d.box.y_max)));
    cv::rectangle(image, p0, p1, scalar(colour), 2, cv::LINE_8);
    char text[96];
    std::snprintf(text, sizeof(text), "%s %.2f", d.class_name.c_str(), static_cast<double>(d.score));
    label(&image, text, cv::Point(p0.x, std::max(12, p0.y - 4)), scalar(colour));
  }
  for (const Placed& c : centres) {
    const cv::Point p(static_cast<int>(std::lround(c.centre.x())), static_cast<int>(std::lround(c.centre.y())));
    cv::circle(image, p, 3, scalar(overlay_colour(c.id)), cv::FILLED, cv::LINE_8);
    label(&image, std::to_string(c.id), p + cv::Point(6, -6), scalar(overlay_colour(c.id)));
  }
  return out;
}

}  // namespace dqo::objects
