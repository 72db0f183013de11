#include "dqo_map/tracking/undistortion.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

namespace dqo::tracking {

struct Undistorter::Maps {
  PinholeCamera camera;
  bool identity = false;
  cv::Mat K;      // raw intrinsics, CV_64F 3x3
  cv::Mat D;      // CV_64F 1xN
  cv::Mat new_K;  // rectified intrinsics
  cv::Mat map_x;  // CV_32FC1 per rectified pixel: raw x (float maps keep nearest-neighbour exact)
  cv::Mat map_y;
};

namespace {

// The number of coefficients each model takes, in OpenCV's (and ROS's) order.
int model_coefficients(const std::string& model) {
  if (model == "plumb_bob") return 5;
  if (model == "rational_polynomial") return 8;
  return -1;
}

template <typename T>
cv::Mat wrap(const Image<T>& image, int cv_depth) {
  // cv::Mat does not write through this view: the const_cast only satisfies its constructor.
  return cv::Mat(image.height, image.width, CV_MAKETYPE(cv_depth, image.channels),
                 const_cast<T*>(image.data.data()));
}

}  // namespace

Undistorter::Undistorter() : maps_(std::make_unique<Maps>()) {}
Undistorter::~Undistorter() = default;
Undistorter::Undistorter(Undistorter&&) noexcept = default;
Undistorter& Undistorter::operator=(Undistorter&&) noexcept = default;

std::optional<Undistorter> Undistorter::create(const CameraCalibration& c, std::string* error) {
  auto fail = [&](const std::string& message) -> std::optional<Undistorter> {
    if (error) *error = message;
    return std::nullopt;
  };
  if (c.width <= 0 || c.height <= 0) {
    return fail("camera size " + std::to_string(c.width) + "x" + std::to_string(c.height) +
                " is not positive");
  }
  if (!(c.K[0] > 0.0) || !(c.K[4] > 0.0)) return fail("K has a non-positive focal length");
  const bool has_p = std::any_of(c.P.begin(), c.P.end(), [](double v) { return v != 0.0; });
  if (has_p && (!(c.P[0] > 0.0) || !(c.P[5] > 0.0))) {
    return fail("P has a non-positive focal length");
  }
  const bool zero_d = std::all_of(c.D.begin(), c.D.end(), [](double v) { return v == 0.0; });
  int n = 0;
  if (!c.distortion_model.empty()) {
    n = model_coefficients(c.distortion_model);
    if (n < 0 && !zero_d) {
      return fail("distortion model '" + c.distortion_model +
                  "' is not supported (plumb_bob, rational_polynomial)");
    }
    if (n < 0) n = 0;  // an unknown model with all-zero coefficients is still a pinhole camera
  } else if (!zero_d) {
    return fail("distortion coefficients given without a distortion model");
  }
  if (static_cast<int>(c.D.size()) > n && !zero_d) {
    return fail("distortion model '" + c.distortion_model + "' takes " + std::to_string(n) +
                " coefficients, got " + std::to_string(c.D.size()));
  }

  Undistorter u;
  Maps& m = *u.maps_;
  m.K = cv::Mat(3, 3, CV_64F);
  std::memcpy(m.K.ptr<double>(), c.K.data(), 9 * sizeof(double));
  m.D = cv::Mat::zeros(1, std::max(n, 5), CV_64F);
  for (size_t i = 0; i < c.D.size() && static_cast<int>(i) < m.D.cols; ++i) {
    m.D.at<double>(0, static_cast<int>(i)) = c.D[i];
  }
  m.camera.width = c.width;
  m.camera.height = c.height;
  if (has_p) {
    m.camera.fx = c.P[0];
    m.camera.fy = c.P[5];
    m.camera.cx = c.P[2];
    m.camera.cy = c.P[6];
  } else {
    m.camera.fx = c.K[0];
    m.camera.fy = c.K[4];
    m.camera.cx = c.K[2];
    m.camera.cy = c.K[5];
  }
  m.new_K = (cv::Mat_<double>(3, 3) << m.camera.fx, 0.0, m.camera.cx, 0.0, m.camera.fy,
             m.camera.cy, 0.0, 0.0, 1.0);
  // The skew K[1] is dropped by the pinhole camera; with it non-zero the images need a remap too.
  m.identity = zero_d && c.K[1] == 0.0 && m.camera.fx == c.K[0] && m.camera.fy == c.K[4] &&
               m.camera.cx == c.K[2] && m.camera.cy == c.K[5];
  if (!m.identity) {
    cv::initUndistortRectifyMap(m.K, m.D, cv::Mat(), m.new_K, cv::Size(c.width, c.height), CV_32FC1,
                                m.map_x, m.map_y);
  }
  return u;
}

const PinholeCamera& Undistorter::camera() const { return maps_->camera; }
bool Undistorter::is_identity() const { return maps_->identity; }

bool Undistorter::rectify_rgb(const ImageRgb8& raw, ImageRgb8* rectified, std::string* error) const {
  const Maps& m = *maps_;
  if (!raw.same_size(m.camera.width, m.camera.height) || raw.data.size() != raw.index(0, raw.height)) {
    if (error) {
      *error = "colour image is " + std::to_string(raw.width) + "x" + std::to_string(raw.height) +
               ", the camera " + std::to_string(m.camera.width) + "x" + std::to_string(m.camera.height);
    }
    return false;
  }
  if (raw.channels != 1 && raw.channels != 3 && raw.channels != 4) {
    if (error) *error = "colour image has " + std::to_string(raw.channels) + " channels";
    return false;
  }
  if (m.identity) {
    *rectified = raw;
    return true;
  }
  *rectified = ImageRgb8(raw.width, raw.height, raw.channels);
  cv::Mat out = wrap(*rectified, CV_8U);
  cv::remap(wrap(raw, CV_8U), out, m.map_x, m.map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, 0);
  return true;
}

bool Undistorter::rectify_depth(const DepthImage& raw, DepthImage* rectified,
                                std::string* error) const {
  const Maps& m = *maps_;
  if (!raw.same_size(m.camera.width, m.camera.height) || raw.channels != 1 ||
      raw.data.size() != raw.index(0, raw.height)) {
    if (error) {
      *error = "depth image is " + std::to_string(raw.width) + "x" + std::to_string(raw.height) + "x" +
               std::to_string(raw.channels) + ", the camera " + std::to_string(m.camera.width) + "x" +
               std::to_string(m.camera.height) + "x1";
    }
    return false;
  }
  if (m.identity) {
    *rectified = raw;
    return true;
  }
  *rectified = DepthImage(raw.width, raw.height, 1);
  cv::Mat out = wrap(*rectified, CV_32F);
  cv::remap(wrap(raw, CV_32F), out, m.map_x, m.map_y, cv::INTER_NEAREST, cv::BORDER_CONSTANT, 0);
  return true;
}

Eigen::Vector2d Undistorter::rectify_point(const Eigen::Vector2d& uv_raw) const {
  const Maps& m = *maps_;
  if (m.identity) return uv_raw;
  std::vector<cv::Point2d> in{{uv_raw.x(), uv_raw.y()}}, out;
  // OpenCV's default of 5 fixed-point iterations leaves tenths of a pixel at the corners of a
  // wide-angle lens; iterate to convergence instead.
  cv::undistortPoints(in, out, m.K, m.D, cv::noArray(), m.new_K,
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-12));
  return {out[0].x, out[0].y};
}

Eigen::Vector2d Undistorter::distort_point(const Eigen::Vector2d& uv_rectified) const {
  const Maps& m = *maps_;
  if (m.identity) return uv_rectified;
  const PinholeCamera& c = m.camera;
  std::vector<cv::Point3d> in{{(uv_rectified.x() - c.cx) / c.fx, (uv_rectified.y() - c.cy) / c.fy, 1.0}};
  std::vector<cv::Point2d> out;
  cv::projectPoints(in, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), m.K, m.D, out);
  return {out[0].x, out[0].y};
}

Box2d Undistorter::rectify_box(const Box2d& raw) const {
  if (!std::isfinite(raw.x_min) || !std::isfinite(raw.y_min) || !std::isfinite(raw.x_max) ||
      !std::isfinite(raw.y_max) || is_identity()) {
    return raw;
  }
  constexpr int kSamples = 8;  // per edge: enough for the bend of a wide-angle lens over one box
  Box2d out{INFINITY, INFINITY, -INFINITY, -INFINITY};
  auto add = [&](double u, double v) {
    const Eigen::Vector2d p = rectify_point({u, v});
    out.x_min = std::min(out.x_min, p.x()), out.x_max = std::max(out.x_max, p.x());
    out.y_min = std::min(out.y_min, p.y()), out.y_max = std::max(out.y_max, p.y());
  };
  for (int i = 0; i <= kSamples; ++i) {
    const double s = static_cast<double>(i) / kSamples;
    const double u = raw.x_min + s * (raw.x_max - raw.x_min);
    const double v = raw.y_min + s * (raw.y_max - raw.y_min);
    add(u, raw.y_min), add(u, raw.y_max), add(raw.x_min, v), add(raw.x_max, v);
  }
  return out;
}

bool Undistorter::rectify_labels(const InstanceImage& raw, InstanceImage* rectified,
                                 std::string* error) const {
  // The depth remap is nearest-neighbour with 0 outside: exactly what labels need. uint16 values
  // are exact in float.
  DepthImage as_float(raw.width, raw.height, 1);
  for (size_t i = 0; i < raw.data.size() && i < as_float.data.size(); ++i) as_float.data[i] = raw.data[i];
  DepthImage out;
  if (raw.channels != 1 || !rectify_depth(as_float, &out, error)) {
    if (error && raw.channels != 1) *error = "instance image must have one channel";
    return false;
  }
  *rectified = InstanceImage(out.width, out.height, 1, 0);
  for (size_t i = 0; i < out.data.size(); ++i) rectified->data[i] = static_cast<uint16_t>(out.data[i]);
  return true;
}

}  // namespace dqo::tracking
