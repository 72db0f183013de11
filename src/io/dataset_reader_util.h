#pragma once
// Private to io/: what the dataset readers share: folder and image-size checks, a base class with
// the folder, info and format name, the frame-range check and reading a colour and a depth image,
// and the open-or-nullptr factory.

#include <filesystem>
#include <memory>
#include <string>
#include <system_error>
#include <utility>

#include "dqo_map/common/image.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/io/dataset_reader.h"
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

// The part of a reader that does not depend on the format. A reader fills dir_ and info_ in its
// open(), and starts read_frame with check_frame_index.
class BasicDatasetReader : public DatasetReader {
 public:
  const DatasetInfo& info() const override { return info_; }
  std::string format() const override { return format_; }
  const std::string& dir() const override { return dir_; }

 protected:
  explicit BasicDatasetReader(std::string format) : format_(std::move(format)) {}

  // False and *error ("dir: frame i out of range [0, n)") unless 0 <= i < num_frames().
  bool check_frame_index(int i, std::string* error) const;
  // frame->rgb and frame->depth (metres, through info_.depth_scale) from a colour image and a
  // uint16 depth PNG, both checked against the camera's size.
  bool read_rgbd(const std::string& rgb_path, const std::string& depth_path, Frame* frame,
                 std::string* error) const;

  std::string dir_;
  DatasetInfo info_;

 private:
  std::string format_;
};

// The open_*_dataset functions: a reader of type Reader, or nullptr and *error when the folder is
// missing or Reader::open(dir, params, error) fails.
template <typename Reader, typename Params>
std::unique_ptr<DatasetReader> open_reader(const std::string& dir, const Params& params,
                                           std::string* error) {
  if (!check_dataset_dir(dir, error)) return nullptr;
  auto reader = std::make_unique<Reader>();
  if (!reader->open(dir, params, error)) return nullptr;
  return reader;
}

}  // namespace io_detail
}  // namespace dqo
