// The package's own dataset folder: writer -> reader round trip and the all-or-nothing writer.
#include <cmath>
#include <filesystem>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "dqo_map/io/dataset_reader.h"
#include "dqo_map/io/dataset_writer.h"
#include "dqo_map/io/image_io.h"
#include "io_test_util.h"

namespace dqo {
namespace {

namespace fs = std::filesystem;

constexpr int kWidth = 8;
constexpr int kHeight = 6;
constexpr double kDepthScale = 1000.0;

DatasetInfo make_info() {
  DatasetInfo info;
  info.camera.width = kWidth;
  info.camera.height = kHeight;
  info.camera.fx = 525.1234567890123;
  info.camera.fy = 524.9;
  info.camera.cx = 3.5;
  info.camera.cy = 2.0 / 3.0;
  info.depth_scale = kDepthScale;
  info.class_names = {{1, "cup"}, {7, "dining table"}};

  GtObject cup;
  cup.id = 4;
  cup.class_id = 1;
  cup.class_name = "cup";
  cup.box.centre = Eigen::Vector3d(0.1, -0.2, 1.0 / 3.0);
  cup.box.rotation = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).matrix();
  cup.box.half_extents = Eigen::Vector3d(0.04, 0.04, 0.05);
  cup.mesh.vertices = {{0, 0, 0}, {0.1, 0, 0}, {0, 0.1, 0}, {0, 0, 0.1 / 3}};
  cup.mesh.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  GtObject table;
  table.id = 12;
  table.class_id = 7;  // its name comes from info.class_names
  table.box.centre = Eigen::Vector3d(1, 2, 3);
  table.box.half_extents = Eigen::Vector3d(0.6, 0.4, 0.0);
  info.objects = {cup, table};
  return info;
}

Frame make_frame(int index, std::mt19937_64& rng) {
  std::uniform_int_distribution<int> byte(0, 255);
  std::uniform_real_distribution<float> metres(0.2f, 9.0f);
  std::normal_distribution<double> normal(0.0, 1.0);
  Frame f;
  f.index = index;
  f.timestamp = 1700000000.0 + index / 30.0;
  f.T_wc = SE3(Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng)),
               Eigen::Vector3d(normal(rng), normal(rng), normal(rng)));
  f.has_pose = true;
  f.rgb = ImageRgb8(kWidth, kHeight, 3);
  for (auto& v : f.rgb.data) v = static_cast<uint8_t>(byte(rng));
  f.depth = DepthImage(kWidth, kHeight, 1);
  for (auto& d : f.depth.data) d = metres(rng);
  f.depth.at(0, 0) = 0.0f;
  f.depth.at(1, 0) = std::numeric_limits<float>::quiet_NaN();
  f.depth.at(2, 0) = 80.0f;  // beyond 65.535 m at scale 1000: stored as invalid
  if (index != 1) {  // frame 1 has no instance image
    f.instance = InstanceImage(kWidth, kHeight, 1);
    for (int x = 2; x < 5; ++x) f.instance.at(x, 3) = 4;
    f.instance.at(7, 5) = 65535;
  }
  if (index == 0) {
    Detection2d a;
    a.class_id = 1;
    a.class_name = "cup";
    a.score = 0.9f;
    a.box = {1.5, 2.25, 6.0, 5.0};
    a.gt_id = 4;
    Detection2d b;  // a false positive: no gt_id; its class name only appears here
    b.class_id = 3;
    b.class_name = "book";
    b.score = 0.3333333f;
    b.box = {0.1, 0.2, 0.30000000000000004, 1e-7};
    f.detections = {a, b};
    FrameObject o;
    o.id = 4;
    o.box = {2, 3, 5, 4};
    o.visible_fraction = 0.123456789012345;
    FrameObject p;
    p.id = 12;
    p.box = {0, 0, 8, 6};
    p.visible_fraction = 1.0;
    f.objects = {o, p};
  }
  if (index == 2) {
    Detection2d c;
    c.class_id = 7;
    c.score = 1.0f;
    c.box = {-3.5, 0, 8, 6.5};
    c.gt_id = 12;
    f.detections = {c};
  }
  return f;
}

std::vector<Frame> write_dataset(const std::string& dir, int num_frames) {
  std::mt19937_64 rng(11);
  std::vector<Frame> frames;
  DatasetWriter writer(dir);
  std::string error;
  EXPECT_TRUE(writer.write_info(make_info(), &error)) << error;
  for (int i = 0; i < num_frames; ++i) {
    frames.push_back(make_frame(i, rng));
    EXPECT_TRUE(writer.write_frame(frames.back(), &error)) << error;
  }
  EXPECT_TRUE(writer.finish(&error)) << error;
  return frames;
}

int count_entries(const std::string& dir) {
  int n = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    (void)entry;
    ++n;
  }
  return n;
}

TEST(OwnDataset, RoundTripIsExact) {
  test::TempDir tmp;
  const std::string dir = tmp / "data";
  const std::vector<Frame> frames = write_dataset(dir, 3);
  const DatasetInfo info = make_info();

  std::string error;
  const auto reader = open_dataset(dir, &error);
  ASSERT_TRUE(reader) << error;
  EXPECT_EQ(reader->format(), "dqo");
  ASSERT_EQ(reader->num_frames(), 3);

  const DatasetInfo& got = reader->info();
  EXPECT_EQ(got.camera.width, kWidth);
  EXPECT_EQ(got.camera.height, kHeight);
  EXPECT_EQ(got.camera.fx, info.camera.fx);
  EXPECT_EQ(got.camera.fy, info.camera.fy);
  EXPECT_EQ(got.camera.cx, info.camera.cx);
  EXPECT_EQ(got.camera.cy, info.camera.cy);
  EXPECT_EQ(got.depth_scale, kDepthScale);
  const std::map<int, std::string> classes = {{1, "cup"}, {3, "book"}, {7, "dining table"}};
  EXPECT_EQ(got.class_names, classes);

  ASSERT_EQ(got.objects.size(), 2u);
  for (size_t k = 0; k < 2; ++k) {
    const GtObject& a = info.objects[k];
    const GtObject& b = got.objects[k];
    EXPECT_EQ(b.id, a.id);
    EXPECT_EQ(b.class_id, a.class_id);
    EXPECT_EQ(b.box.centre, a.box.centre);
    EXPECT_EQ(b.box.half_extents, a.box.half_extents);
    EXPECT_LT((b.box.rotation - a.box.rotation).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_EQ(b.mesh.vertices, a.mesh.vertices);
    EXPECT_EQ(b.mesh.triangles, a.mesh.triangles);
  }
  EXPECT_EQ(got.objects[0].class_name, "cup");
  EXPECT_EQ(got.objects[1].class_name, "dining table");
  EXPECT_TRUE(got.objects[1].mesh.empty());

  for (int i = 0; i < 3; ++i) {
    SCOPED_TRACE("frame " + std::to_string(i));
    const auto f = reader->read_frame(i, &error);
    ASSERT_TRUE(f) << error;
    const Frame& w = frames[i];
    EXPECT_EQ(f->index, i);
    EXPECT_EQ(f->timestamp, w.timestamp);
    EXPECT_TRUE(f->has_pose);
    EXPECT_EQ(f->T_wc.translation(), w.T_wc.translation());
    EXPECT_LT((f->T_wc.quaternion().coeffs() - w.T_wc.quaternion().coeffs()).cwiseAbs().maxCoeff(),
              1e-9);
    EXPECT_EQ(f->rgb.data, w.rgb.data);
    EXPECT_EQ(f->rgb.width, kWidth);
    // Exactly the writer's quantised depth, and within half a step of what it was given.
    const DepthImage expected = quantise_depth(w.depth, kDepthScale);
    EXPECT_EQ(f->depth.data, expected.data);
    EXPECT_EQ(f->depth.at(0, 0), 0.0f);
    EXPECT_EQ(f->depth.at(1, 0), 0.0f);
    EXPECT_EQ(f->depth.at(2, 0), 0.0f);
    EXPECT_NEAR(f->depth.at(3, 0), w.depth.at(3, 0), 0.5 / kDepthScale + 1e-6);
    EXPECT_EQ(f->instance.data, w.instance.data);
    EXPECT_EQ(f->instance.empty(), i == 1);

    ASSERT_EQ(f->detections.size(), w.detections.size());
    for (size_t k = 0; k < w.detections.size(); ++k) {
      const Detection2d& a = w.detections[k];
      const Detection2d& b = f->detections[k];
      EXPECT_EQ(b.class_id, a.class_id);
      EXPECT_EQ(b.score, a.score);
      EXPECT_EQ(b.box.x_min, a.box.x_min);
      EXPECT_EQ(b.box.y_min, a.box.y_min);
      EXPECT_EQ(b.box.x_max, a.box.x_max);
      EXPECT_EQ(b.box.y_max, a.box.y_max);
      EXPECT_EQ(b.gt_id, a.gt_id);
      EXPECT_EQ(b.class_name, classes.at(a.class_id));
    }
    ASSERT_EQ(f->objects.size(), w.objects.size());
    for (size_t k = 0; k < w.objects.size(); ++k) {
      const FrameObject& a = w.objects[k];
      const FrameObject& b = f->objects[k];
      EXPECT_EQ(b.id, a.id);
      EXPECT_EQ(b.box.x_min, a.box.x_min);
      EXPECT_EQ(b.box.y_min, a.box.y_min);
      EXPECT_EQ(b.box.x_max, a.box.x_max);
      EXPECT_EQ(b.box.y_max, a.box.y_max);
      EXPECT_EQ(b.visible_fraction, a.visible_fraction);
    }
  }
  EXPECT_FALSE(reader->read_frame(3, &error));
  EXPECT_NE(error.find("out of range"), std::string::npos) << error;
  EXPECT_FALSE(reader->read_frame(-1, &error));
}

TEST(OwnDataset, FilesHaveTheDocumentedLayout) {
  test::TempDir tmp;
  const std::string dir = tmp / "data";
  write_dataset(dir, 3);
  for (const char* name : {"camera.yaml", "classes.txt", "groundtruth.txt", "detections.txt",
                           "frame_objects.txt", "objects_gt.txt", "rgb/000000.png",
                           "rgb/000002.png", "depth/000001.png", "instance/000000.png",
                           "meshes_gt/4.ply"}) {
    EXPECT_TRUE(fs::is_regular_file(dir + "/" + name)) << name;
  }
  EXPECT_FALSE(fs::exists(dir + "/instance/000001.png"));
  EXPECT_FALSE(fs::exists(dir + "/meshes_gt/12.ply"));
  EXPECT_EQ(test::read_text(dir + "/detections.txt"),
            "# frame x1 y1 x2 y2 class_id score [gt_id]\n"
            "0 1.5 2.25 6 5 1 0.9 4\n"
            "0 0.1 0.2 0.30000000000000004 1e-07 3 0.3333333\n"
            "2 -3.5 0 8 6.5 7 1 12\n");
  EXPECT_EQ(test::read_text(dir + "/frame_objects.txt"),
            "# frame id x1 y1 x2 y2 visible_fraction\n"
            "0 4 2 3 5 4 0.123456789012345\n"
            "0 12 0 0 8 6 1\n");
  EXPECT_EQ(test::read_text(dir + "/classes.txt"),
            "# class_id class_name\n1 cup\n3 book\n7 dining table\n");
  const std::string camera = test::read_text(dir + "/camera.yaml");
  EXPECT_NE(camera.find("\nfx: 525.1234567890123\n"), std::string::npos) << camera;
  EXPECT_NE(camera.find("\ndepth_scale: 1000\n"), std::string::npos) << camera;
  const std::string objects = test::read_text(dir + "/objects_gt.txt");
  EXPECT_EQ(objects.rfind("# id class_id cx cy cz qx qy qz qw hx hy hz\n4 1 0.1 -0.2 ", 0), 0u)
      << objects;
  EXPECT_NE(objects.find("\n12 7 1 2 3 0 0 0 1 0.6 0.4 0\n"), std::string::npos) << objects;
  // The depth PNG holds round(d * scale), 0 for invalid.
  std::string error;
  const auto stored = read_png_u16(dir + "/depth/000000.png", &error);
  ASSERT_TRUE(stored) << error;
  EXPECT_EQ(stored->at(0, 0), 0);
  EXPECT_EQ(stored->at(2, 0), 0);
  // No temporary folder is left beside the dataset.
  EXPECT_EQ(count_entries(tmp.path()), 1);
}

TEST(OwnDataset, FailureMidWriteLeavesNoOutput) {
  test::TempDir tmp;
  const std::string dir = tmp / "data";
  std::mt19937_64 rng(2);
  {
    DatasetWriter writer(dir);
    std::string error;
    ASSERT_TRUE(writer.write_info(make_info(), &error)) << error;
    ASSERT_TRUE(writer.write_frame(make_frame(0, rng), &error)) << error;
    Frame bad = make_frame(1, rng);
    bad.depth = DepthImage(kWidth + 1, kHeight, 1);  // wrong size
    EXPECT_FALSE(writer.write_frame(bad, &error));
    EXPECT_NE(error.find("depth"), std::string::npos) << error;
    EXPECT_TRUE(writer.failed());
    EXPECT_EQ(count_entries(tmp.path()), 0) << "the temporary folder must go at once";
    // Every later call fails with the first error and nothing appears.
    std::string later;
    EXPECT_FALSE(writer.write_frame(make_frame(1, rng), &later));
    EXPECT_FALSE(writer.finish(&later));
    EXPECT_EQ(later, error);
  }
  EXPECT_FALSE(fs::exists(dir));
  EXPECT_EQ(count_entries(tmp.path()), 0);
}

TEST(OwnDataset, WriterDestroyedBeforeFinishLeavesNoOutput) {
  test::TempDir tmp;
  const std::string dir = tmp / "data";
  std::mt19937_64 rng(3);
  {
    DatasetWriter writer(dir);
    std::string error;
    ASSERT_TRUE(writer.write_info(make_info(), &error)) << error;
    ASSERT_TRUE(writer.write_frame(make_frame(0, rng), &error)) << error;
    EXPECT_EQ(count_entries(tmp.path()), 1);  // the hidden temporary folder
    EXPECT_FALSE(fs::exists(dir));
  }
  EXPECT_FALSE(fs::exists(dir));
  EXPECT_EQ(count_entries(tmp.path()), 0);
}

TEST(OwnDataset, WriterRejectsBadFrames) {
  test::TempDir tmp;
  std::mt19937_64 rng(4);
  std::string error;
  {
    DatasetWriter writer(tmp / "a");
    EXPECT_FALSE(writer.write_frame(make_frame(0, rng), &error));  // no write_info yet
    EXPECT_NE(error.find("write_info"), std::string::npos) << error;
  }
  {
    DatasetWriter writer(tmp / "b");
    ASSERT_TRUE(writer.write_info(make_info(), &error)) << error;
    EXPECT_FALSE(writer.write_frame(make_frame(1, rng), &error));  // must start at 0
    EXPECT_NE(error.find("expected frame index 0"), std::string::npos) << error;
  }
  {
    DatasetWriter writer(tmp / "c");
    ASSERT_TRUE(writer.write_info(make_info(), &error)) << error;
    Frame f = make_frame(0, rng);
    f.has_pose = false;
    EXPECT_FALSE(writer.write_frame(f, &error));
  }
  {
    DatasetWriter writer(tmp / "d");
    ASSERT_TRUE(writer.write_info(make_info(), &error)) << error;
    Frame f = make_frame(0, rng);
    f.detections[1].class_id = 1;  // class 1 is "cup": a second name for it is a conflict
    f.detections[1].class_name = "mug";
    EXPECT_FALSE(writer.write_frame(f, &error));
    EXPECT_NE(error.find("'cup'"), std::string::npos) << error;
  }
  {
    DatasetInfo info = make_info();
    info.camera.fx = 0.0;
    DatasetWriter writer(tmp / "e");
    EXPECT_FALSE(writer.write_info(info, &error));
  }
  EXPECT_EQ(count_entries(tmp.path()), 0);
}

TEST(OwnDataset, ExistingFoldersAreOnlyReplacedWhenAskedAndWhenTheyAreDatasets) {
  test::TempDir tmp;
  const std::string dir = tmp / "data";
  std::string error;

  // An empty folder is fine.
  fs::create_directory(dir);
  write_dataset(dir, 1);
  EXPECT_TRUE(fs::exists(dir + "/rgb/000000.png"));

  // A non-empty one needs overwrite.
  {
    DatasetWriter writer(dir);
    EXPECT_FALSE(writer.write_info(make_info(), &error));
    EXPECT_NE(error.find("not empty"), std::string::npos) << error;
  }
  // With overwrite, the old dataset is replaced as a whole.
  {
    DatasetWriter::Params params;
    params.overwrite = true;
    DatasetWriter writer(dir, params);
    ASSERT_TRUE(writer.write_info(make_info(), &error)) << error;
    std::mt19937_64 rng(9);
    Frame f = make_frame(0, rng);
    f.instance = InstanceImage();
    ASSERT_TRUE(writer.write_frame(f, &error)) << error;
    ASSERT_TRUE(writer.finish(&error)) << error;
  }
  EXPECT_FALSE(fs::exists(dir + "/instance/000000.png")) << "old files must not survive";
  EXPECT_EQ(count_entries(tmp.path()), 1);

  // A folder that is not a dataset is never replaced.
  const std::string other = tmp / "other";
  test::write_text(other + "/notes.txt", "precious\n");
  {
    DatasetWriter::Params params;
    params.overwrite = true;
    DatasetWriter writer(other, params);
    EXPECT_FALSE(writer.write_info(make_info(), &error));
    EXPECT_NE(error.find("not a dataset"), std::string::npos) << error;
  }
  EXPECT_EQ(test::read_text(other + "/notes.txt"), "precious\n");
}

TEST(OwnDataset, MalformedFilesNameFileAndLine) {
  test::TempDir tmp;
  const std::string dir = tmp / "data";
  write_dataset(dir, 2);
  std::string error;

  const std::string detections = test::read_text(dir + "/detections.txt");
  test::write_text(dir + "/detections.txt", detections + "5 0 0 1 1 1 0.5\n");  // no frame 5
  EXPECT_FALSE(open_dataset(dir, &error));
  EXPECT_NE(error.find("detections.txt:4:"), std::string::npos) << error;
  test::write_text(dir + "/detections.txt", detections);

  const std::string objects = test::read_text(dir + "/objects_gt.txt");
  test::write_text(dir + "/objects_gt.txt", objects + "9 1 0 0 0 0 0 0 1 1 1\n");  // 11 fields
  EXPECT_FALSE(open_dataset(dir, &error));
  EXPECT_NE(error.find("objects_gt.txt:4:"), std::string::npos) << error;
  test::write_text(dir + "/objects_gt.txt", objects);

  const std::string camera = test::read_text(dir + "/camera.yaml");
  test::write_text(dir + "/camera.yaml", camera + "k1: 0.1\n");
  EXPECT_FALSE(open_dataset(dir, &error));
  EXPECT_NE(error.find("camera.yaml:9:"), std::string::npos) << error;
  EXPECT_NE(error.find("k1"), std::string::npos) << error;
  test::write_text(dir + "/camera.yaml", camera);

  test::write_text(dir + "/meshes_gt/4.ply", "garbage");
  EXPECT_FALSE(open_dataset(dir, &error));
  EXPECT_NE(error.find("meshes_gt/4.ply"), std::string::npos) << error;
  DatasetReaderParams no_meshes;
  no_meshes.load_meshes = false;
  EXPECT_TRUE(open_dataset(dir, no_meshes, &error)) << error;

  fs::remove(dir + "/rgb/000001.png");
  const auto reader = open_dataset(dir, no_meshes, &error);
  ASSERT_TRUE(reader) << error;
  EXPECT_TRUE(reader->read_frame(0, &error)) << error;
  EXPECT_FALSE(reader->read_frame(1, &error));
  EXPECT_NE(error.find("rgb/000001.png"), std::string::npos) << error;
}

}  // namespace
}  // namespace dqo
