#pragma once
// Private to io/: checks shared by the dataset readers.

#include <filesystem>
#include <string>
#include <system_error>

#include "dqo_map/common/image.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "text_util.h"

namespace dqo {
namespace io_detail {

inline bool check_dataset_dir(const std::string& dir, std::string* error) {
  std::error_code ec;
  if (!std::filesystem::exists(dir, ec)) return fail(error, dir + ": dataset folder not found");
  if (!std::filesystem::is_directory(dir, ec)) return fail(error, dir + ": not a folder");
  return true;
}

template <typename T>
bool check_image_size(const std::string& path, const Image<T>& image, const PinholeCamera& camera,
                      std::string* error) {
  if (image.same_size(camera.width, camera.height)) return true;
  return fail(error, path + ": image is " + std::to_string(image.width) + "x" +
                         std::to_string(image.height) + " but the camera is " +
                         std::to_string(camera.width) + "x" + std::to_string(camera.height));
}

}  // namespace io_detail
}  // namespace dqo
