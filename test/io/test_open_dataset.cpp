// open_dataset: choosing the reader by the folder's contents, and its errors.
#include <filesystem>

#include <gtest/gtest.h>

#include "dqo_map/io/dataset_reader.h"
#include "io_test_util.h"

namespace dqo {
namespace {

namespace fs = std::filesystem;

TEST(OpenDataset, DetectsTheFormatFromTheFolderContents) {
  test::TempDir tmp;
  const std::string own = tmp / "own";
  test::write_text(own + "/camera.yaml", "");
  fs::create_directories(own + "/rgb");
  EXPECT_EQ(detect_dataset_format(own), "dqo");

  const std::string tum = tmp / "tum";
  test::write_text(tum + "/rgb.txt", "");
  test::write_text(tum + "/depth.txt", "");
  EXPECT_EQ(detect_dataset_format(tum), "tum");

  const std::string replica = tmp / "replica";
  fs::create_directories(replica + "/results");
  test::write_text(replica + "/traj.txt", "");
  EXPECT_EQ(detect_dataset_format(replica), "replica");

  // Half of a layout is none.
  const std::string half = tmp / "half";
  test::write_text(half + "/rgb.txt", "");
  fs::create_directories(half + "/rgb");
  EXPECT_EQ(detect_dataset_format(half), "");
  EXPECT_EQ(detect_dataset_format(tmp / "missing"), "");
}

TEST(OpenDataset, EmptyFolderIsAClearError) {
  test::TempDir tmp;
  std::string error;
  EXPECT_FALSE(open_dataset(tmp.path(), &error));
  EXPECT_NE(error.find(tmp.path()), std::string::npos) << error;
  EXPECT_NE(error.find("not a dataset folder"), std::string::npos) << error;
}

TEST(OpenDataset, MissingFolderOrAFileIsAnErrorNotACrash) {
  test::TempDir tmp;
  std::string error;
  EXPECT_FALSE(open_dataset(tmp / "nowhere", &error));
  EXPECT_NE(error.find("nowhere: dataset folder not found"), std::string::npos) << error;
  test::write_text(tmp / "file", "x");
  EXPECT_FALSE(open_dataset(tmp / "file", &error));
  EXPECT_NE(error.find("not a folder"), std::string::npos) << error;
  EXPECT_FALSE(open_dataset(tmp / "nowhere", nullptr));  // no error string wanted
}

TEST(OpenDataset, MalformedGroundTruthLineNamesFileAndLine) {
  test::TempDir tmp;
  const std::string dir = tmp.path();
  test::write_text(dir + "/camera.yaml",
                   "width: 2\nheight: 2\nfx: 1\nfy: 1\ncx: 1\ncy: 1\ndepth_scale: 1000\n");
  fs::create_directories(dir + "/rgb");
  test::write_text(dir + "/groundtruth.txt",
                   "# timestamp tx ty tz qx qy qz qw\n0 0 0 0 0 0 0 1\n0.1 0 0 0 0 0 1\n");
  std::string error;
  EXPECT_FALSE(open_dataset(dir, &error));
  EXPECT_NE(error.find(dir + "/groundtruth.txt:3: expected 8 fields"), std::string::npos)
      << error;

  test::write_text(dir + "/groundtruth.txt", "0 0 0 0 0 0 0 1\n");
  const auto reader = open_dataset(dir, &error);
  ASSERT_TRUE(reader) << error;
  EXPECT_EQ(reader->num_frames(), 1);
  EXPECT_TRUE(reader->info().objects.empty());
  EXPECT_TRUE(reader->info().class_names.empty());
  EXPECT_FALSE(reader->read_frame(0, &error));  // rgb/000000.png is missing
  EXPECT_NE(error.find("rgb/000000.png"), std::string::npos) << error;

  test::write_text(dir + "/camera.yaml", "width: 2\nheight: [\n");
  EXPECT_FALSE(open_dataset(dir, &error));
  EXPECT_NE(error.find("camera.yaml:"), std::string::npos) << error;
}

}  // namespace
}  // namespace dqo
