// Replica (NICE-SLAM layout) reader on a three-frame fixture.
#include <cstdio>
#include <filesystem>

#include <gtest/gtest.h>

#include "dqo_map/io/dataset_reader.h"
#include "dqo_map/io/image_io.h"
#include "io_test_util.h"

namespace dqo {
namespace {

constexpr int kWidth = 6;
constexpr int kHeight = 4;

SE3 replica_pose(int i) {
  return SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.3 * i, Eigen::Vector3d(1, 1, 0).normalized())),
             Eigen::Vector3d(0.5 * i, -1.25, 2.0 + i));
}

// Writes scene folder `dir` with three frames; cam_params.json goes to `cam_dir`.
void write_replica(const std::string& dir, const std::string& cam_dir) {
  std::filesystem::create_directories(dir + "/results");
  test::write_text(cam_dir + "/cam_params.json",
                   "{\n  \"camera\": {\n    \"w\": 6,\n    \"h\": 4,\n    \"fx\": 600.0,\n"
                   "    \"fy\": 600.5,\n    \"cx\": 2.5,\n    \"cy\": 1.5,\n"
                   "    \"scale\": 6553.5\n  }\n}\n");
  std::string traj;
  for (int i = 0; i < 3; ++i) {
    const Eigen::Matrix4d T = replica_pose(i).matrix();
    for (int r = 0; r < 4; ++r) {
      for (int c = 0; c < 4; ++c) {
        char number[64];
        std::snprintf(number, sizeof(number), "%.18e", T(r, c));
        traj += number;
        traj += (r == 3 && c == 3) ? "\n" : " ";
      }
    }
    char name[64];
    ImageRgb8 rgb(kWidth, kHeight, 3, static_cast<uint8_t>(40 * (i + 1)));
    std::snprintf(name, sizeof(name), "/results/frame%06d.jpg", i);
    ASSERT_TRUE(write_jpeg(dir + name, rgb, 95));
    Image<uint16_t> depth(kWidth, kHeight, 1, static_cast<uint16_t>(6553 * (i + 1)));
    depth.at(0, 0) = 0;
    std::snprintf(name, sizeof(name), "/results/depth%06d.png", i);
    ASSERT_TRUE(write_png(dir + name, depth));
  }
  test::write_text(dir + "/traj.txt", traj);
}

TEST(ReplicaReader, ReadsPosesIntrinsicsAndScaledDepth) {
  test::TempDir tmp;
  const std::string dir = tmp / "room0";
  write_replica(dir, tmp.path());  // NICE-SLAM keeps cam_params.json one folder up
  std::string error;
  const auto reader = open_dataset(dir, &error);
  ASSERT_TRUE(reader) << error;
  EXPECT_EQ(reader->format(), "replica");
  ASSERT_EQ(reader->num_frames(), 3);
  const PinholeCamera& cam = reader->info().camera;
  EXPECT_EQ(cam.width, kWidth);
  EXPECT_EQ(cam.height, kHeight);
  EXPECT_EQ(cam.fx, 600.0);
  EXPECT_EQ(cam.fy, 600.5);
  EXPECT_EQ(cam.cx, 2.5);
  EXPECT_EQ(cam.cy, 1.5);
  EXPECT_EQ(reader->info().depth_scale, 6553.5);
  for (int i = 0; i < 3; ++i) {
    SCOPED_TRACE("frame " + std::to_string(i));
    const auto f = reader->read_frame(i, &error);
    ASSERT_TRUE(f) << error;
    EXPECT_EQ(f->index, i);
    EXPECT_DOUBLE_EQ(f->timestamp, i / 30.0);
    ASSERT_TRUE(f->has_pose);
    EXPECT_LT((f->T_wc.matrix() - replica_pose(i).matrix()).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_EQ(f->depth.at(3, 2), static_cast<float>(6553.0 * (i + 1) / 6553.5));
    EXPECT_EQ(f->depth.at(0, 0), 0.0f);
    EXPECT_EQ(f->rgb.width, kWidth);
    EXPECT_NEAR(f->rgb.at(3, 2, 1), 40 * (i + 1), 3);
  }
}

TEST(ReplicaReader, CamParamsBesideTheSceneWinAndErrorsNameTheFile) {
  test::TempDir tmp;
  const std::string dir = tmp / "office0";
  write_replica(dir, dir);
  std::string error;
  ASSERT_TRUE(open_dataset(dir, &error)) << error;

  const std::string traj = test::read_text(dir + "/traj.txt");
  test::write_text(dir + "/traj.txt", traj + "1 0 0 0 0 1 0 0 0 0 1 0 0 0 0\n");
  EXPECT_FALSE(open_dataset(dir, &error));
  EXPECT_NE(error.find("traj.txt:4:"), std::string::npos) << error;
  test::write_text(dir + "/traj.txt", traj + "2 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n");
  EXPECT_FALSE(open_dataset(dir, &error));
  EXPECT_NE(error.find("traj.txt:4: top-left 3x3 block is not a rotation"), std::string::npos)
      << error;
  test::write_text(dir + "/traj.txt", traj);

  test::write_text(dir + "/cam_params.json", "{\"camera\": {\"w\": 6, \"h\": 4, \"fx\": 600}}");
  EXPECT_FALSE(open_dataset(dir, &error));
  EXPECT_NE(error.find("cam_params.json"), std::string::npos) << error;
  EXPECT_NE(error.find("fy"), std::string::npos) << error;

  std::filesystem::remove(dir + "/cam_params.json");
  EXPECT_FALSE(open_dataset(dir, &error));
  EXPECT_NE(error.find("cam_params.json: missing"), std::string::npos) << error;
}

TEST(ReplicaReader, ReadsDetectionsAndClassesBesideTheScene) {
  // What dqo_detect writes into a Replica folder: detections by frame index, their class names.
  test::TempDir tmp;
  const std::string dir = tmp / "room1";
  write_replica(dir, dir);
  test::write_text(dir + "/classes.txt", "# class_id class_name\n41 cup\n56 chair\n");
  test::write_text(dir + "/detections.txt",
                   "# frame x1 y1 x2 y2 class_id score\n2 1.5 0.5 4.25 3 41 0.875\n0 0 0 2 2 56 0.5\n2 0 1 1 2 56 0.25\n");
  std::string error;
  const auto reader = open_dataset(dir, &error);
  ASSERT_TRUE(reader) << error;
  EXPECT_EQ(reader->info().class_names.at(41), "cup");
  const auto f0 = reader->read_frame(0, &error), f1 = reader->read_frame(1, &error), f2 = reader->read_frame(2, &error);
  ASSERT_TRUE(f0 && f1 && f2) << error;
  ASSERT_EQ(f0->detections.size(), 1u);
  EXPECT_EQ(f0->detections[0].class_name, "chair");
  EXPECT_TRUE(f1->detections.empty());
  ASSERT_EQ(f2->detections.size(), 2u);
  EXPECT_EQ(f2->detections[0].class_id, 41);
  EXPECT_EQ(f2->detections[0].class_name, "cup");
  EXPECT_FLOAT_EQ(f2->detections[0].score, 0.875f);
  EXPECT_DOUBLE_EQ(f2->detections[0].box.x_min, 1.5);
  EXPECT_DOUBLE_EQ(f2->detections[0].box.x_max, 4.25);
  // A frame beyond the trajectory is an error naming the line.
  test::write_text(dir + "/detections.txt", "3 0 0 1 1 41 0.5\n");
  EXPECT_FALSE(open_dataset(dir, &error));
  EXPECT_NE(error.find("detections.txt:1:"), std::string::npos) << error;
}

}  // namespace
}  // namespace dqo
