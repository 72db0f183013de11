#include "dqo_map/io/dataset_reader.h"

#include <filesystem>
#include <system_error>

#include "dataset_reader_util.h"
#include "text_util.h"

namespace dqo {

namespace fs = std::filesystem;

std::string detect_dataset_format(const std::string& dir) {
  std::error_code ec;
  const fs::path d(dir);
  auto file = [&](const char* name) { return fs::is_regular_file(d / name, ec); };
  auto folder = [&](const char* name) { return fs::is_directory(d / name, ec); };
  if (!fs::is_directory(d, ec)) return "";
  // TUM first: a TUM sequence holds rgb/ and, for us, a camera.yaml too; the own format never
  // holds rgb.txt.
  if (file("rgb.txt") && file("depth.txt")) return "tum";
  if (file("camera.yaml") && folder("rgb")) return "dqo";
  if (folder("results") && file("traj.txt")) return "replica";
  return "";
}

std::unique_ptr<DatasetReader> open_dataset(const std::string& dir, std::string* error) {
  return open_dataset(dir, DatasetReaderParams(), error);
}

std::unique_ptr<DatasetReader> open_dataset(const std::string& dir,
                                            const DatasetReaderParams& params,
                                            std::string* error) {
  if (!io_detail::check_dataset_dir(dir, error)) return nullptr;
  const std::string format = detect_dataset_format(dir);
  if (format == "dqo") return open_own_dataset(dir, params.load_meshes, error);
  if (format == "tum") {
    TumReaderParams tum = params.tum;
    tum.load_meshes = params.load_meshes;
    return open_tum_dataset(dir, tum, error);
  }
  if (format == "replica") return open_replica_dataset(dir, params.replica, error);
  io_detail::fail(error, dir +
                             ": not a dataset folder: expected camera.yaml and rgb/ (own format), "
                             "rgb.txt and depth.txt (TUM RGB-D), or results/ and traj.txt "
                             "(Replica)");
  return nullptr;
}

}  // namespace dqo
