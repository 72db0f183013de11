#include "dqo_map/io/image_io.h"

#include <cctype>
#include <cmath>
#include <cstring>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "text_util.h"

namespace dqo {

using io_detail::fail;

namespace {

bool ends_with(const std::string& s, const std::string& suffix) {
  if (s.size() < suffix.size()) return false;
  for (size_t i = 0; i < suffix.size(); ++i) {
    if (std::tolower(static_cast<unsigned char>(s[s.size() - suffix.size() + i])) != suffix[i]) {
      return false;
    }
  }
  return true;
}

template <typename T>
constexpr int cv_depth();
template <>
constexpr int cv_depth<uint8_t>() {
  return CV_8U;
}
template <>
constexpr int cv_depth<uint16_t>() {
  return CV_16U;
}

// A cv::Mat in OpenCV's channel order (BGR/BGRA) holding a copy of the image.
template <typename T>
bool to_mat(const Image<T>& image, const std::string& path, cv::Mat* mat, std::string* error) {
  if (image.empty() || image.width <= 0 || image.height <= 0) {
    return fail(error, path + ": refusing to write an empty image");
  }
  if (image.data.size() != static_cast<size_t>(image.width) * image.height * image.channels) {
    return fail(error, path + ": image buffer size does not match width x height x channels");
  }
  const int c = image.channels;
  if (c != 1 && c != 3 && c != 4) {
    return fail(error, path + ": cannot write an image of " + std::to_string(c) + " channels");
  }
  // The wrapper does not own the data; cvtColor / clone below make the copy that imwrite reads.
  const cv::Mat wrapped(image.height, image.width, CV_MAKETYPE(cv_depth<T>(), c),
                        const_cast<T*>(image.data.data()));
  if (c == 3) {
    cv::cvtColor(wrapped, *mat, cv::COLOR_RGB2BGR);
  } else if (c == 4) {
    cv::cvtColor(wrapped, *mat, cv::COLOR_RGBA2BGRA);
  } else {
    *mat = wrapped.clone();
  }
  return true;
}

bool write_mat(const std::string& path, const cv::Mat& mat, const std::vector<int>& params,
               std::string* error) {
  try {
    if (!cv::imwrite(path, mat, params)) return fail(error, path + ": cannot write image");
  } catch (const cv::Exception& e) {
    return fail(error, path + ": cannot write image: " + e.what());
  }
  return true;
}

template <typename T>
bool write_png_impl(const std::string& path, const Image<T>& image, std::string* error) {
  if (!ends_with(path, ".png")) return fail(error, path + ": write_png needs a .png file name");
  if (sizeof(T) == 2 && image.channels == 4) {
    return fail(error, path + ": 16-bit images with 4 channels are not supported");
  }
  cv::Mat mat;
  if (!to_mat(image, path, &mat, error)) return false;
  // Level 1: several times faster than the default of libpng at a few percent larger files.
  return write_mat(path, mat, {cv::IMWRITE_PNG_COMPRESSION, 1}, error);
}

bool read_mat(const std::string& path, cv::Mat* mat, std::string* error) {
  try {
    *mat = cv::imread(path, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    return fail(error, path + ": cannot decode image: " + e.what());
  }
  if (mat->empty()) {
    return fail(error, path + ": cannot read image (missing file or not a decodable image)");
  }
  return true;
}

}  // namespace

bool write_png(const std::string& path, const Image<uint8_t>& image, std::string* error) {
  return write_png_impl(path, image, error);
}

bool write_png(const std::string& path, const Image<uint16_t>& image, std::string* error) {
  return write_png_impl(path, image, error);
}

bool write_jpeg(const std::string& path, const Image<uint8_t>& image, int quality,
                std::string* error) {
  if (!ends_with(path, ".jpg") && !ends_with(path, ".jpeg")) {
    return fail(error, path + ": write_jpeg needs a .jpg or .jpeg file name");
  }
  if (image.channels != 1 && image.channels != 3) {
    return fail(error, path + ": JPEG needs a grey or RGB image");
  }
  cv::Mat mat;
  if (!to_mat(image, path, &mat, error)) return false;
  return write_mat(path, mat, {cv::IMWRITE_JPEG_QUALITY, quality}, error);
}

std::optional<ImageRgb8> read_rgb_image(const std::string& path, std::string* error) {
  cv::Mat mat;
  if (!read_mat(path, &mat, error)) return std::nullopt;
  if (mat.depth() != CV_8U) {
    fail(error, path + ": expected an 8-bit colour image, found a " +
                    std::to_string(8 * static_cast<int>(mat.elemSize1())) + "-bit one");
    return std::nullopt;
  }
  cv::Mat rgb;
  switch (mat.channels()) {
    case 1:
      cv::cvtColor(mat, rgb, cv::COLOR_GRAY2RGB);
      break;
    case 3:
      cv::cvtColor(mat, rgb, cv::COLOR_BGR2RGB);
      break;
    case 4:
      cv::cvtColor(mat, rgb, cv::COLOR_BGRA2RGB);
      break;
    default:
      fail(error, path + ": unsupported channel count " + std::to_string(mat.channels()));
      return std::nullopt;
  }
  ImageRgb8 image(rgb.cols, rgb.rows, 3);
  for (int y = 0; y < rgb.rows; ++y) {
    std::memcpy(&image.at(0, y), rgb.ptr<uint8_t>(y), static_cast<size_t>(rgb.cols) * 3);
  }
  return image;
}

std::optional<Image<uint16_t>> read_png_u16(const std::string& path, std::string* error) {
  cv::Mat mat;
  if (!read_mat(path, &mat, error)) return std::nullopt;
  if (mat.depth() != CV_16U || mat.channels() != 1) {
    fail(error, path + ": expected a single-channel 16-bit image, found " +
                    std::to_string(mat.channels()) + " channel(s) of " +
                    std::to_string(8 * static_cast<int>(mat.elemSize1())) + " bits");
    return std::nullopt;
  }
  Image<uint16_t> image(mat.cols, mat.rows, 1);
  for (int y = 0; y < mat.rows; ++y) {
    std::memcpy(&image.at(0, y), mat.ptr<uint16_t>(y), static_cast<size_t>(mat.cols) * 2);
  }
  return image;
}

Image<uint16_t> depth_to_u16(const DepthImage& depth, double depth_scale) {
  Image<uint16_t> stored(depth.width, depth.height, 1);
  for (int y = 0; y < depth.height; ++y) {
    for (int x = 0; x < depth.width; ++x) {
      const double d = depth.at(x, y, 0);
      if (!std::isfinite(d) || d <= 0.0) continue;
      const double v = std::round(d * depth_scale);
      if (v >= 1.0 && v <= 65535.0) stored.at(x, y) = static_cast<uint16_t>(v);
    }
  }
  return stored;
}

DepthImage depth_from_u16(const Image<uint16_t>& stored, double depth_scale) {
  DepthImage depth(stored.width, stored.height, 1);
  for (size_t i = 0; i < stored.data.size() && i < depth.data.size(); ++i) {
    const uint16_t v = stored.data[i];
    depth.data[i] = v == 0 ? 0.0f : static_cast<float>(static_cast<double>(v) / depth_scale);
  }
  return depth;
}

DepthImage quantise_depth(const DepthImage& depth, double depth_scale) {
  return depth_from_u16(depth_to_u16(depth, depth_scale), depth_scale);
}

}  // namespace dqo
