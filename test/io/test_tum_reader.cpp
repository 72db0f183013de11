// TUM RGB-D reader on a fixture of our own making: timestamps that do not align exactly.
#include <cmath>

#include <gtest/gtest.h>

#include "dqo_map/io/dataset_reader.h"
#include "dqo_map/io/image_io.h"
#include "io_test_util.h"

namespace dqo {
namespace {

constexpr int kWidth = 4;
constexpr int kHeight = 3;

SE3 gt_pose(double x) {
  // Pose k of the fixture: x metres along x, yaw 0.1 x radians.
  return SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.1 * x, Eigen::Vector3d::UnitZ())),
             Eigen::Vector3d(x, 0.0, 0.0));
}

// rgb (ms after 100 s):   0    33    66   100        300
// depth:                  4    30         90    200  301
// rgb 66 has no depth within 20 ms (90 is 24 ms away and 100 is the closer partner of 90).
// Ground truth around each rgb time, so poses are interpolated; none near 300.
class TumFixture : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::string dir = tmp_.path();
    test::write_text(dir + "/camera.yaml",
                     "width: 4\nheight: 3\nfx: 517.3\nfy: 516.5\ncx: 318.6\ncy: 255.3\n");
    const char* rgb_names[] = {"100.000000", "100.033000", "100.066000", "100.100000",
                               "100.300000"};
    std::string rgb_txt = "# color images\n# file: 'rgbd_dataset_test.bag'\n# timestamp filename\n";
    for (int i = 0; i < 5; ++i) {
      ImageRgb8 rgb(kWidth, kHeight, 3);
      for (int y = 0; y < kHeight; ++y) {
        for (int x = 0; x < kWidth; ++x) rgb.at(x, y, 0) = static_cast<uint8_t>(10 * (i + 1));
      }
      const std::string name = std::string("rgb/") + rgb_names[i] + ".png";
      std::filesystem::create_directories(dir + "/rgb");
      ASSERT_TRUE(write_png(dir + "/" + name, rgb));
      rgb_txt += std::string(rgb_names[i]) + " " + name + "\n";
    }
    test::write_text(dir + "/rgb.txt", rgb_txt);

    const char* depth_names[] = {"100.004000", "100.030000", "100.090000", "100.200000",
                                 "100.301000"};
    std::string depth_txt = "# depth maps\n# timestamp filename\n";
    for (int j = 0; j < 5; ++j) {
      Image<uint16_t> depth(kWidth, kHeight, 1, static_cast<uint16_t>(5000 * (j + 1)));
      depth.at(0, 0) = 0;
      depth.at(1, 0) = 5001;
      const std::string name = std::string("depth/") + depth_names[j] + ".png";
      std::filesystem::create_directories(dir + "/depth");
      ASSERT_TRUE(write_png(dir + "/" + name, depth));
      depth_txt += std::string(depth_names[j]) + " " + name + "\n";
    }
    test::write_text(dir + "/depth.txt", depth_txt);

    std::string gt = "# ground truth trajectory\n# timestamp tx ty tz qx qy qz qw\n";
    const double gt_times[] = {99.995, 100.005, 100.025, 100.045, 100.095, 100.105};
    for (int k = 0; k < 6; ++k) {
      const SE3 T = gt_pose(k);
      const Eigen::Quaterniond& q = T.quaternion();
      char line[256];
      std::snprintf(line, sizeof(line), "%.4f %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n",
                    gt_times[k], T.translation().x(), T.translation().y(), T.translation().z(),
                    q.x(), q.y(), q.z(), q.w());
      gt += line;
    }
    test::write_text(dir + "/groundtruth.txt", gt);
  }

  test::TempDir tmp_;
};

TEST_F(TumFixture, AssociatesByNearestTimestampAndInterpolatesGroundTruth) {
  std::string error;
  const auto reader = open_dataset(tmp_.path(), &error);
  ASSERT_TRUE(reader) << error;
  EXPECT_EQ(reader->format(), "tum");
  EXPECT_EQ(reader->info().depth_scale, 5000.0);
  EXPECT_EQ(reader->info().camera.fx, 517.3);
  EXPECT_EQ(reader->info().camera.cy, 255.3);
  ASSERT_EQ(reader->num_frames(), 4);  // rgb 100.066 has no depth partner

  // frame: rgb file (red = 10 (i + 1)), depth file (metres), timestamp, ground-truth x
  struct Expected {
    int rgb;
    int depth;
    double t;
    double x;  // NaN: no pose
  };
  const Expected expected[] = {{0, 0, 100.000, 0.5},
                               {1, 1, 100.033, 2.4},
                               {3, 2, 100.100, 4.5},
                               {4, 4, 100.300, std::nan("")}};
  for (int i = 0; i < 4; ++i) {
    SCOPED_TRACE("frame " + std::to_string(i));
    const auto f = reader->read_frame(i, &error);
    ASSERT_TRUE(f) << error;
    EXPECT_EQ(f->index, i);
    EXPECT_EQ(f->timestamp, expected[i].t);
    // The depth image's own stamp (depth.txt): the tracker needs it where the two differ.
    const double depth_stamps[] = {100.004, 100.030, 100.090, 100.200, 100.301};
    ASSERT_TRUE(f->depth_timestamp.has_value());
    EXPECT_EQ(*f->depth_timestamp, depth_stamps[expected[i].depth]);
    EXPECT_EQ(f->rgb.at(2, 1, 0), 10 * (expected[i].rgb + 1));
    EXPECT_EQ(f->rgb.at(2, 1, 1), 0);
    EXPECT_EQ(f->depth.at(2, 1), static_cast<float>(expected[i].depth + 1));
    EXPECT_EQ(f->depth.at(0, 0), 0.0f);
    EXPECT_EQ(f->depth.at(1, 0), static_cast<float>(5001.0 / 5000.0));
    EXPECT_TRUE(f->instance.empty());
    EXPECT_TRUE(f->detections.empty());
    if (std::isnan(expected[i].x)) {
      EXPECT_FALSE(f->has_pose);
      continue;
    }
    ASSERT_TRUE(f->has_pose);
    const SE3 want = gt_pose(expected[i].x);
    EXPECT_NEAR((f->T_wc.translation() - want.translation()).norm(), 0.0, 1e-9);
    EXPECT_NEAR(f->T_wc.quaternion().angularDistance(want.quaternion()), 0.0, 1e-9);
  }
}

TEST_F(TumFixture, NearestGroundTruthAndAWiderWindowAreParameters) {
  DatasetReaderParams params;
  params.tum.pose.interpolate = false;
  // With 0.2 s, rgb 100.066 still loses depth 100.090 to rgb 100.100 (10 ms beats 24 ms) and so
  // takes the next free one, 100.200: greedy one-to-one matching as in TUM's associate.py.
  params.tum.max_time_difference = 0.2;
  std::string error;
  const auto reader = open_dataset(tmp_.path(), params, &error);
  ASSERT_TRUE(reader) << error;
  ASSERT_EQ(reader->num_frames(), 5);
  const auto f1 = reader->read_frame(1, &error);
  ASSERT_TRUE(f1) << error;
  ASSERT_TRUE(f1->has_pose);
  EXPECT_NEAR(f1->T_wc.translation().x(), 2.0, 1e-12);  // 100.033: nearest is 100.025
  const auto f2 = reader->read_frame(2, &error);
  ASSERT_TRUE(f2) << error;
  EXPECT_EQ(f2->timestamp, 100.066);
  EXPECT_EQ(f2->depth.at(2, 1), 4.0f);  // depth 100.200
  // The nearest ground truth (100.045) is 21 ms away, beyond pose.max_difference.
  EXPECT_FALSE(f2->has_pose);
  const auto f3 = reader->read_frame(3, &error);
  ASSERT_TRUE(f3) << error;
  EXPECT_EQ(f3->depth.at(2, 1), 3.0f);  // depth 100.090
}

TEST_F(TumFixture, DepthScaleFromCameraYaml) {
  test::write_text(tmp_ / "camera.yaml",
                   "width: 4\nheight: 3\nfx: 1\nfy: 1\ncx: 2\ncy: 1.5\ndepth_scale: 1000\n");
  std::string error;
  const auto reader = open_dataset(tmp_.path(), &error);
  ASSERT_TRUE(reader) << error;
  const auto f = reader->read_frame(0, &error);
  ASSERT_TRUE(f) << error;
  EXPECT_EQ(f->depth.at(2, 1), 5.0f);
}

TEST_F(TumFixture, ErrorsNameFileAndLine) {
  std::string error;
  const std::string gt = test::read_text(tmp_ / "groundtruth.txt");
  test::write_text(tmp_ / "groundtruth.txt", gt + "100.2 1 2 3\n");
  EXPECT_FALSE(open_dataset(tmp_.path(), &error));
  EXPECT_NE(error.find(tmp_ / "groundtruth.txt:9:"), std::string::npos) << error;
  test::write_text(tmp_ / "groundtruth.txt", gt);

  const std::string rgb = test::read_text(tmp_ / "rgb.txt");
  test::write_text(tmp_ / "rgb.txt", rgb + "abc rgb/x.png\n");
  EXPECT_FALSE(open_dataset(tmp_.path(), &error));
  EXPECT_NE(error.find(tmp_ / "rgb.txt:9:"), std::string::npos) << error;
  test::write_text(tmp_ / "rgb.txt", rgb);

  std::filesystem::remove(tmp_ / "camera.yaml");
  EXPECT_FALSE(open_dataset(tmp_.path(), &error));
  EXPECT_NE(error.find("camera.yaml"), std::string::npos) << error;
  test::write_text(tmp_ / "camera.yaml", "width: 5\nheight: 3\nfx: 1\nfy: 1\ncx: 2\ncy: 1.5\n");

  // Image size against the camera: caught when the frame is read.
  const auto reader = open_dataset(tmp_.path(), &error);
  ASSERT_TRUE(reader) << error;
  EXPECT_FALSE(reader->read_frame(0, &error));
  EXPECT_NE(error.find("rgb/100.000000.png"), std::string::npos) << error;
}

TEST_F(TumFixture, WithoutGroundTruthFramesHaveNoPose) {
  std::filesystem::remove(tmp_ / "groundtruth.txt");
  std::string error;
  const auto reader = open_dataset(tmp_.path(), &error);
  ASSERT_TRUE(reader) << error;
  ASSERT_EQ(reader->num_frames(), 4);
  const auto f = reader->read_frame(0, &error);
  ASSERT_TRUE(f) << error;
  EXPECT_FALSE(f->has_pose);
}

// The own format's side files beside rgb.txt: a real sequence with boxes runs the object stage.
// Frames of the fixture: 0 = 100.000, 1 = 100.033, 2 = 100.100, 3 = 100.300.
TEST_F(TumFixture, ReadsTheSideFilesOfTheOwnFormat) {
  test::write_text(tmp_ / "classes.txt", "41 cup\n60 dining table\n");
  // By frame index, by a timestamp 0.4 ms off frame 2's, and one more on frame 1.
  test::write_text(tmp_ / "detections.txt",
                   "1 0.5 0.5 2.5 2 41 0.9 7\n"
                   "100.1004 1 0 3 2 60 0.75\n"
                   "1 0 0 1 1 60 0.5\n");
  test::write_text(tmp_ / "objects_gt.txt", "7 41 0.1 0.2 0.3 0 0 0 1 0.05 0.04 0.06\n");
  std::filesystem::create_directories(tmp_ / "instance");
  Image<uint16_t> by_name(kWidth, kHeight, 1, 0), by_index(kWidth, kHeight, 1, 0);
  by_name.at(1, 1) = 7;
  by_index.at(2, 2) = 9;
  ASSERT_TRUE(write_png(tmp_ / "instance/100.033000.png", by_name));  // the colour image's name
  ASSERT_TRUE(write_png(tmp_ / "instance/000003.png", by_index));     // frame 3 by index

  std::string error;
  const auto reader = open_dataset(tmp_.path(), &error);
  ASSERT_TRUE(reader) << error;
  EXPECT_EQ(reader->info().class_names.at(60), "dining table");
  ASSERT_EQ(reader->info().objects.size(), 1u);
  EXPECT_EQ(reader->info().objects[0].id, 7u);
  EXPECT_EQ(reader->info().objects[0].class_name, "cup");
  EXPECT_NEAR(reader->info().objects[0].box.centre.y(), 0.2, 1e-12);

  std::vector<Frame> frames;
  for (int i = 0; i < 4; ++i) {
    auto f = reader->read_frame(i, &error);
    ASSERT_TRUE(f) << error;
    frames.push_back(std::move(*f));
  }
  EXPECT_TRUE(frames[0].detections.empty());
  ASSERT_EQ(frames[1].detections.size(), 2u);
  EXPECT_EQ(frames[1].detections[0].class_name, "cup");
  EXPECT_EQ(frames[1].detections[0].gt_id, 7u);
  EXPECT_FLOAT_EQ(frames[1].detections[0].score, 0.9f);
  EXPECT_EQ(frames[1].detections[0].box.x_min, 0.5);
  ASSERT_EQ(frames[2].detections.size(), 1u);
  EXPECT_EQ(frames[2].detections[0].class_id, 60);
  EXPECT_EQ(frames[2].detections[0].box.x_max, 3.0);
  EXPECT_TRUE(frames[3].detections.empty());

  EXPECT_TRUE(frames[0].instance.empty());
  ASSERT_FALSE(frames[1].instance.empty());
  EXPECT_EQ(frames[1].instance.at(1, 1), 7);
  EXPECT_EQ(frames[1].instance.at(2, 2), 0);
  EXPECT_TRUE(frames[2].instance.empty());
  ASSERT_FALSE(frames[3].instance.empty());
  EXPECT_EQ(frames[3].instance.at(2, 2), 9);
}

TEST_F(TumFixture, SideFileErrorsNameFileAndLine) {
  std::string error;
  // 100.2 is 100 ms from the nearest frame: beyond max_time_difference (20 ms).
  test::write_text(tmp_ / "detections.txt", "1 0 0 1 1 1 0.5\n100.2 0 0 1 1 1 0.5\n");
  EXPECT_FALSE(open_dataset(tmp_.path(), &error));
  EXPECT_NE(error.find(tmp_ / "detections.txt:2:"), std::string::npos) << error;
  test::write_text(tmp_ / "detections.txt", "4 0 0 1 1 1 0.5\n");  // frame index out of range
  EXPECT_FALSE(open_dataset(tmp_.path(), &error));
  EXPECT_NE(error.find(tmp_ / "detections.txt:1:"), std::string::npos) << error;
  std::filesystem::remove(tmp_ / "detections.txt");

  Image<uint16_t> wrong(kWidth + 1, kHeight, 1, 0);
  std::filesystem::create_directories(tmp_ / "instance");
  ASSERT_TRUE(write_png(tmp_ / "instance/000000.png", wrong));
  const auto reader = open_dataset(tmp_.path(), &error);
  ASSERT_TRUE(reader) << error;
  EXPECT_FALSE(reader->read_frame(0, &error));
  EXPECT_NE(error.find("instance/000000.png"), std::string::npos) << error;
}

TEST_F(TumFixture, LensDistortionFromCameraYaml) {
  const std::string pinhole = "width: 4\nheight: 3\nfx: 517.3\nfy: 516.5\ncx: 318.6\ncy: 255.3\n";
  std::string error;
  {
    const auto reader = open_dataset(tmp_.path(), &error);
    ASSERT_TRUE(reader) << error;
    EXPECT_TRUE(reader->info().distortion_model.empty());
    EXPECT_TRUE(reader->info().distortion.empty());
  }
  // Fewer coefficients than the model takes are padded with zeros (OpenCV's rule).
  test::write_text(tmp_ / "camera.yaml",
                   pinhole + "distortion_model: plumb_bob\ndistortion: [0.2624, -0.9531, -0.0054, 0.0026]\n");
  {
    const auto reader = open_dataset(tmp_.path(), &error);
    ASSERT_TRUE(reader) << error;
    EXPECT_EQ(reader->info().distortion_model, "plumb_bob");
    EXPECT_EQ(reader->info().distortion,
              (std::vector<double>{0.2624, -0.9531, -0.0054, 0.0026, 0.0}));
  }
  test::write_text(tmp_ / "camera.yaml",
                   pinhole + "distortion_model: rational_polynomial\ndistortion: [1, 2, 3, 4, 5, 6, 7, 8]\n");
  {
    const auto reader = open_dataset(tmp_.path(), &error);
    ASSERT_TRUE(reader) << error;
    EXPECT_EQ(reader->info().distortion.size(), 8u);
    EXPECT_EQ(reader->info().distortion[7], 8.0);
  }
  // A calibration kept apart from the data takes the place of the folder's camera.yaml.
  test::write_text(tmp_ / "fr1.yaml",
                   pinhole + "distortion_model: plumb_bob\ndistortion: [0.5, 0, 0, 0, 0]\n");
  {
    DatasetReaderParams params;
    params.tum.camera_file = tmp_ / "fr1.yaml";
    const auto reader = open_dataset(tmp_.path(), params, &error);
    ASSERT_TRUE(reader) << error;
    EXPECT_EQ(reader->info().distortion_model, "plumb_bob");
    EXPECT_EQ(reader->info().distortion[0], 0.5);
  }

  const std::pair<std::string, std::string> bad[] = {
      {"distortion_model: plumb_bob\ndistortion: [1, 2, 3, 4, 5, 6]\n", "at most 5"},
      {"distortion_model: fisheye\ndistortion: [1, 2, 3, 4]\n", "unknown distortion_model"},
      {"distortion_model: plumb_bob\n", "go together"},
      {"distortion: [1, 2, 3, 4, 5]\n", "go together"},
      {"distortion_model: plumb_bob\ndistortion: [1, x, 3, 4, 5]\n", "finite number"},
      {"distortion_model: plumb_bob\ndistortion: 0.1\n", "list of numbers"},
  };
  for (const auto& [text, message] : bad) {
    SCOPED_TRACE(text);
    test::write_text(tmp_ / "camera.yaml", pinhole + text);
    EXPECT_FALSE(open_dataset(tmp_.path(), &error));
    EXPECT_NE(error.find(message), std::string::npos) << error;
    EXPECT_NE(error.find("camera.yaml:"), std::string::npos) << error;
  }
}

TEST_F(TumFixture, RollingShutterReadoutFromCameraYaml) {
  const std::string pinhole = "width: 4\nheight: 3\nfx: 517.3\nfy: 516.5\ncx: 318.6\ncy: 255.3\n";
  std::string error;
  {
    const auto reader = open_dataset(tmp_.path(), &error);
    ASSERT_TRUE(reader) << error;
    EXPECT_EQ(reader->info().rolling_shutter_s, 0.0);  // absent: a global shutter
  }
  test::write_text(tmp_ / "camera.yaml", pinhole + "rolling_shutter_s: 0.02\n");
  {
    const auto reader = open_dataset(tmp_.path(), &error);
    ASSERT_TRUE(reader) << error;
    EXPECT_EQ(reader->info().rolling_shutter_s, 0.02);
    EXPECT_TRUE(reader->info().distortion_model.empty());
  }
  for (const std::string bad : {"rolling_shutter_s: -0.01\n", "rolling_shutter_s: 2\n"}) {
    SCOPED_TRACE(bad);
    test::write_text(tmp_ / "camera.yaml", pinhole + bad);
    EXPECT_FALSE(open_dataset(tmp_.path(), &error));
    EXPECT_NE(error.find("[0, 1] seconds"), std::string::npos) << error;
    EXPECT_NE(error.find("camera.yaml:"), std::string::npos) << error;
  }
}

}  // namespace
}  // namespace dqo
