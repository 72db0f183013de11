#include "dataset_reader_util.h"

#include "dqo_map/io/image_io.h"

namespace dqo {
namespace io_detail {

bool BasicDatasetReader::check_frame_index(int i, std::string* error) const {
  if (i >= 0 && i < num_frames()) return true;
  return fail(error, dir_ + ": frame " + std::to_string(i) + " out of range [0, " +
                         std::to_string(num_frames()) + ")");
}

bool BasicDatasetReader::read_rgbd(const std::string& rgb_path, const std::string& depth_path,
                                   Frame* frame, std::string* error) const {
  auto rgb = read_rgb_image(rgb_path, error);
  if (!rgb || !check_image_size(rgb_path, *rgb, info_.camera, error)) return false;
  auto depth = read_png_u16(depth_path, error);
  if (!depth || !check_image_size(depth_path, *depth, info_.camera, error)) return false;
  frame->rgb = std::move(*rgb);
  frame->depth = depth_from_u16(*depth, info_.depth_scale);
  return true;
}

}  // namespace io_detail
}  // namespace dqo
