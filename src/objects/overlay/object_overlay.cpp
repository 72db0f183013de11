#include "dqo_map/objects/object_overlay.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <utility>

#include <opencv2/imgproc.hpp>

namespace dqo::objects {
namespace {

constexpr double kGap = 2.0;          // pixels between a label and what it names
constexpr double kPointMark = 4.0;    // half-size of the box around an ellipse's centre dot
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

cv::Scalar scalar(const Rgb& c) { return cv::Scalar(c[0], c[1], c[2]); }  // the image is R G B

Box2d rect_at(double x, double y, double w, double h) { return {x, y, x + w, y + h}; }

// Interiors overlap (touching edges do not count): the same test as intersection(a, b).area() > 0.
bool overlaps(const Box2d& a, const Box2d& b) {
  return a.x_min < b.x_max && b.x_min < a.x_max && a.y_min < b.y_max && b.y_min < a.y_max;
}

// The rectangle moved (not resized) into [0, width] x [0, height]; the caller checks that it fits.
Box2d moved_inside(Box2d r, int width, int height) {
  const double w = r.width(), h = r.height();
  const double x = std::clamp(r.x_min, 0.0, width - w);
  const double y = std::clamp(r.y_min, 0.0, height - h);
  return rect_at(x, y, w, h);
}

// The anchor's own positions for a label of w x h, in order of preference.
std::vector<Box2d> own_positions(const LabelRequest& l) {
  const Box2d& a = l.anchor;
  const double w = l.width, h = l.height;
  if (l.kind == LabelRequest::Anchor::kPoint) {
    const Eigen::Vector2d c = a.centre();
    return {rect_at(a.x_max + kGap, c.y() - 0.5 * h, w, h),      // right
            rect_at(a.x_min - kGap - w, c.y() - 0.5 * h, w, h),  // left
            rect_at(c.x() - 0.5 * w, a.y_min - kGap - h, w, h),  // above
            rect_at(c.x() - 0.5 * w, a.y_max + kGap, w, h)};     // below
  }
  return {rect_at(a.x_min, a.y_min - kGap - h, w, h),          // above
          rect_at(a.x_min, a.y_max + kGap, w, h),              // below
          rect_at(a.x_min + kGap, a.y_min + kGap, w, h),       // inside, top
          rect_at(a.x_min + kGap, a.y_max - kGap - h, w, h),   // inside, bottom
          rect_at(a.x_max + kGap, a.y_min, w, h),              // right
          rect_at(a.x_min - kGap - w, a.y_min, w, h)};         // left
}

// The ellipse's axis-aligned extent.
Box2d ellipse_box(const Ellipse2d& e) {
  const double c = std::cos(e.angle), s = std::sin(e.angle);
  const double a = e.semi_axes(0), b = e.semi_axes(1);
  const double hw = std::sqrt(a * a * c * c + b * b * s * s);
  const double hh = std::sqrt(a * a * s * s + b * b * c * c);
  return {e.centre.x() - hw, e.centre.y() - hh, e.centre.x() + hw, e.centre.y() + hh};
}

cv::Point pixel(const Eigen::Vector2d& p) {
  return cv::Point(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
}

// Text with a dark outline, readable on any background.
void draw_text(cv::Mat* image, const std::string& text, cv::Point at, double scale, const cv::Scalar& colour) {
  cv::putText(*image, text, at, kFont, scale, cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
  cv::putText(*image, text, at, kFont, scale, colour, 1, cv::LINE_AA);
}

// An ellipse outline as dashes (a candidate's).
void draw_dashed_ellipse(cv::Mat* image, const Ellipse2d& e, const cv::Scalar& colour) {
  std::vector<cv::Point> points;
  cv::ellipse2Poly(pixel(e.centre),
                   cv::Size(static_cast<int>(std::lround(e.semi_axes(0))),
                            static_cast<int>(std::lround(e.semi_axes(1)))),
                   static_cast<int>(std::lround(e.angle * 180.0 / M_PI)), 0, 360, 4, points);
  for (size_t i = 0; i + 1 < points.size(); ++i) {
    if ((i / 2) % 2 == 0) cv::line(*image, points[i], points[i + 1], colour, 1, cv::LINE_AA);
  }
}

}  // namespace

namespace {

double golden_hue(ObjectId id) { return std::fmod(0.1 + 0.618033988749895 * static_cast<double>(id), 1.0); }

// HSV with full saturation and value: bright on the dark outline of labels.
Rgb hue_colour(double hue) {
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

double hue_distance(double a, double b) {
  const double d = std::fabs(a - b);
  return std::min(d, 1.0 - d);
}

}  // namespace

Rgb overlay_colour(ObjectId id) { return hue_colour(golden_hue(id)); }

ObjectPalette::ObjectPalette(std::vector<ObjectId> ids) {
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  const int max_steps = static_cast<int>(0.5 / kHueStep);
  for (const ObjectId id : ids) {
    const double own = golden_hue(id);
    double chosen = own;  // where every hue is taken (many objects), the own one
    for (int k = 0; k <= 2 * max_steps; ++k) {
      const double offset = ((k + 1) / 2) * kHueStep * (k % 2 == 1 ? 1.0 : -1.0);  // 0, +1, -1, +2, ...
      const double h = std::fmod(own + offset + 1.0, 1.0);
      const bool free = std::all_of(hues_.begin(), hues_.end(), [&](const std::pair<ObjectId, double>& t) {
        return hue_distance(h, t.second) >= kMinHueGap;
      });
      if (free) {
        chosen = h;
        break;
      }
    }
    hues_.emplace_back(id, chosen);
  }
}

double ObjectPalette::hue(ObjectId id) const {
  const auto it = std::lower_bound(hues_.begin(), hues_.end(), id,
                                   [](const std::pair<ObjectId, double>& e, ObjectId v) { return e.first < v; });
  return it != hues_.end() && it->first == id ? it->second : golden_hue(id);
}

Rgb ObjectPalette::colour(ObjectId id) const { return hue_colour(hue(id)); }

ObjectPalette palette_of_confirmed(const std::vector<MapObject>& objects) {
  std::vector<ObjectId> ids;
  for (const MapObject& o : objects)
    if (o.state == ObjectState::kConfirmed) ids.push_back(o.id);
  return ObjectPalette(std::move(ids));
}

std::vector<PlacedLabel> place_labels(const std::vector<LabelRequest>& labels, int image_width,
                                      int image_height, double max_shift) {
  std::vector<PlacedLabel> out(labels.size());
  std::vector<Box2d> taken;
  auto is_free = [&taken](const Box2d& r) {
    return std::none_of(taken.begin(), taken.end(), [&r](const Box2d& t) { return overlaps(r, t); });
  };
  for (size_t k = 0; k < labels.size(); ++k) {
    const LabelRequest& l = labels[k];
    if (!(l.width > 0.0) || !(l.height > 0.0) || l.width > image_width || l.height > image_height ||
        !std::isfinite(l.anchor.x_min + l.anchor.x_max + l.anchor.y_min + l.anchor.y_max)) {
      continue;
    }
    const std::vector<Box2d> own = own_positions(l);
    // First the positions that lie in the image as they are, then those moved into it (a box at
    // the top edge gets its label below before one pushed down over its own top).
    for (const bool moved : {false, true}) {
      for (const Box2d& p : own) {
        const Box2d r = moved_inside(p, image_width, image_height);
        const bool as_is = r.x_min == p.x_min && r.y_min == p.y_min;
        if (as_is != moved && is_free(r)) {
          out[k] = {r, true};
          break;
        }
      }
      if (out[k].rect.valid()) break;
    }
    if (!out[k].rect.valid()) {
      // Every own position is taken: the nearest free spot around the first, on a grid of half the
      // label's height (fine enough to find a gap a label fits in, coarse enough to stay cheap).
      const Box2d first = moved_inside(own.front(), image_width, image_height);
      const double step = std::max(2.0, 0.5 * l.height);
      const int n = static_cast<int>(std::ceil(max_shift / step));
      std::vector<std::pair<double, Box2d>> spots;
      for (int j = -n; j <= n; ++j) {
        for (int i = -n; i <= n; ++i) {
          const double dx = i * step, dy = j * step;
          if (dx * dx + dy * dy > max_shift * max_shift) continue;
          const Box2d r = rect_at(first.x_min + dx, first.y_min + dy, l.width, l.height);
          if (r.x_min < 0.0 || r.y_min < 0.0 || r.x_max > image_width || r.y_max > image_height) continue;
          spots.emplace_back(dx * dx + dy * dy, r);
        }
      }
      std::stable_sort(spots.begin(), spots.end(),
                       [](const auto& a, const auto& b) { return a.first < b.first; });
      for (const auto& s : spots) {
        if (is_free(s.second)) {
          out[k] = {s.second, false};
          break;
        }
      }
    }
    if (out[k].rect.valid()) taken.push_back(out[k].rect);
  }
  return out;
}

OverlayLayout layout_object_overlay(const PinholeCamera& camera, const SE3& T_wc,
                                    const std::vector<OverlayDetection>& detections,
                                    const std::vector<MapObject>& objects) {
  OverlayLayout layout;
  const int width = camera.width, height = camera.height;
  // The text in proportion to the image, readable from a quarter-size image up.
  layout.font_scale = std::clamp(0.45 * width / 640.0, 0.35, 0.6);
  const SE3 T_cw = T_wc.inverse();
  const Eigen::Matrix<double, 3, 4> P = camera.projection_matrix(T_cw);
  const Box2d image_box{0.0, 0.0, static_cast<double>(width), static_cast<double>(height)};

  std::vector<LabelRequest> requests;
  auto add_label = [&](std::string text, const Rgb& colour, LabelRequest::Anchor kind, const Box2d& anchor) {
    int baseline = 0;
    const cv::Size size = cv::getTextSize(text, kFont, layout.font_scale, 1, &baseline);
    LabelRequest r;
    r.kind = kind;
    r.anchor = anchor;
    // The outline (3 px strokes) reaches a pixel beyond the glyphs on every side.
    r.width = size.width + 4.0;
    r.height = size.height + baseline + 4.0;
    requests.push_back(r);
    OverlayLayout::Label label;
    label.text = std::move(text);
    label.colour = colour;
    label.anchor = anchor;
    label.baseline = baseline + 2.0;
    layout.labels.push_back(std::move(label));
  };

  std::map<ObjectId, bool> confirmed;
  const ObjectPalette palette = palette_of_confirmed(objects);
  // Confirmed objects' labels before candidates': when space runs out, a candidate's goes first.
  for (const bool want_confirmed : {true, false}) {
    for (const MapObject& o : objects) {
      const bool is_confirmed = o.state == ObjectState::kConfirmed;
      if (want_confirmed) confirmed[o.id] = is_confirmed;
      if (is_confirmed != want_confirmed) continue;
      if (!o.has_quadric || !in_front_of_camera(o.quadric, T_cw, 0.05)) continue;
      const auto e = conic_ellipse(project_quadric(o.quadric, P));
      // Far larger than the image: drawn as an outline it would only cross it; skip.
      if (!e || e->semi_axes(0) > 4.0 * std::max(width, height)) continue;
      const Box2d extent = intersection(ellipse_box(*e), image_box);
      if (!extent.valid()) continue;  // wholly outside the image
      OverlayLayout::Ellipse el;
      el.id = o.id;
      el.colour = palette.colour(o.id);
      el.confirmed = is_confirmed;
      el.ellipse = *e;
      el.centre_in_image = e->centre.x() >= 0 && e->centre.y() >= 0 && e->centre.x() < width &&
                           e->centre.y() < height;
      layout.ellipses.push_back(el);
      std::string text = "#" + std::to_string(o.id) + (o.class_name.empty() ? "" : " " + o.class_name);
      if (!is_confirmed) text += "?";
      if (el.centre_in_image) {
        const Box2d mark{e->centre.x() - kPointMark, e->centre.y() - kPointMark,
                         e->centre.x() + kPointMark, e->centre.y() + kPointMark};
        add_label(std::move(text), el.colour, LabelRequest::Anchor::kPoint, mark);
      } else {
        add_label(std::move(text), el.colour, LabelRequest::Anchor::kBox, extent);
      }
    }
  }
  for (const OverlayDetection& d : detections) {
    if (!d.box.valid()) continue;
    OverlayLayout::Box b;
    b.box = d.box;
    b.colour = d.object_id != 0 ? palette.colour(d.object_id) : kUnmatchedColour;
    const auto it = confirmed.find(d.object_id);
    b.solid = d.object_id == 0 || it == confirmed.end() || it->second;
    layout.boxes.push_back(b);
    char score[32];
    std::snprintf(score, sizeof(score), " %.2f", static_cast<double>(d.score));
    const Box2d anchor = intersection(d.box, image_box).valid() ? intersection(d.box, image_box) : d.box;
    add_label(d.class_name + score, b.colour, LabelRequest::Anchor::kBox, anchor);
  }
  const std::vector<PlacedLabel> placed = place_labels(requests, width, height);
  for (size_t k = 0; k < placed.size(); ++k) layout.labels[k].placed = placed[k];
  return layout;
}

ImageRgb8 draw_object_overlay(const ImageRgb8& rgb, const PinholeCamera& camera, const SE3& T_wc,
                              const std::vector<OverlayDetection>& detections,
                              const std::vector<MapObject>& objects) {
  ImageRgb8 out = rgb;
  if (rgb.channels != 3 || !rgb.same_size(camera.width, camera.height) || rgb.empty()) return out;
  cv::Mat image(out.height, out.width, CV_8UC3, out.data.data());  // draws into out
  const OverlayLayout layout = layout_object_overlay(camera, T_wc, detections, objects);

  for (const OverlayLayout::Ellipse& el : layout.ellipses) {
    const cv::Scalar colour = scalar(el.colour);
    if (el.confirmed) {
      cv::ellipse(image, cv::Point2d(el.ellipse.centre.x(), el.ellipse.centre.y()),
                  cv::Size2d(el.ellipse.semi_axes(0), el.ellipse.semi_axes(1)),
                  el.ellipse.angle * 180.0 / M_PI, 0.0, 360.0, colour, 2, cv::LINE_AA);
    } else {
      draw_dashed_ellipse(&image, el.ellipse, colour);
    }
  }
  for (const OverlayLayout::Box& b : layout.boxes) {
    cv::rectangle(image, pixel({b.box.x_min, b.box.y_min}), pixel({b.box.x_max, b.box.y_max}),
                  scalar(b.colour), b.solid ? 2 : 1, cv::LINE_8);
  }
  for (const OverlayLayout::Ellipse& el : layout.ellipses) {
    if (el.centre_in_image) {
      cv::circle(image, pixel(el.ellipse.centre), el.confirmed ? 3 : 2, scalar(el.colour),
                 cv::FILLED, cv::LINE_8);
    }
  }
  for (const OverlayLayout::Label& l : layout.labels) {
    const Box2d& r = l.placed.rect;
    if (!r.valid()) continue;  // no room left for it
    if (!l.placed.adjacent) {
      // Moved away from what it names: a thin line from the label to it.
      const Eigen::Vector2d to = l.anchor.centre();
      const Eigen::Vector2d from(std::clamp(to.x(), r.x_min, r.x_max), std::clamp(to.y(), r.y_min, r.y_max));
      cv::line(image, pixel(from), pixel(to), scalar(l.colour), 1, cv::LINE_AA);
    }
    // A darkened backing under the text (the label's rectangle), then the text.
    const cv::Rect roi = cv::Rect(pixel({r.x_min, r.y_min}), pixel({r.x_max, r.y_max})) &
                         cv::Rect(0, 0, image.cols, image.rows);
    if (roi.area() > 0) {
      cv::Mat backing = image(roi);
      backing.convertTo(backing, -1, 0.45);
    }
    // The text a third of the way to white: dark hues (blue, violet) stay readable on the backing.
    const Rgb& c = l.colour;
    const auto lighter = [](uint8_t v) { return static_cast<uint8_t>(v + (255 - v) / 3); };
    const Rgb text_colour = {lighter(c[0]), lighter(c[1]), lighter(c[2])};
    draw_text(&image, l.text, pixel({r.x_min + 2.0, r.y_max - l.baseline}), layout.font_scale,
              scalar(text_colour));
  }
  return out;
}

}  // namespace dqo::objects
