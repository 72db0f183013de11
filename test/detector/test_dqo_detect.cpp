// dqo_detect as a user runs it: a small own-format dataset, a -seg model with known outputs; the
// detections come back through the dataset reader as the model gave them, classes.txt names them,
// the masks are written, an existing file is kept unless --force, a conflicting classes.txt stops it.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#ifdef DQO_DETECT_TOOL  // where io/ and the tool are built

#include "dqo_map/io/dataset_reader.h"
#include "dqo_map/io/dataset_writer.h"
#include "dqo_map/io/image_io.h"
#include "yolo_fixture.h"

namespace dqo::detector {
namespace {

using test::TempDir;

// A two-frame 320x240 dataset with poses, colour and depth, no detections (its detections.txt holds
// the header line only: dqo_detect may fill it without --force).
bool write_dataset(const std::string& dir) {
  DatasetInfo info;
  info.camera.fx = info.camera.fy = 300;
  info.camera.cx = 160, info.camera.cy = 120;
  info.camera.width = 320, info.camera.height = 240;
  DatasetWriter w(dir);
  if (!w.write_info(info)) return false;
  for (int f = 0; f < 2; ++f) {
    Frame frame;
    frame.index = f;
    frame.timestamp = 0.1 * f;
    frame.has_pose = true;
    frame.rgb = ImageRgb8(320, 240, 3, static_cast<uint8_t>(40 * f));
    frame.depth = DepthImage(320, 240, 1, 1.5f);
    if (!w.write_frame(frame)) return false;
  }
  return w.finish();
}

int run(const std::string& args) {
  const std::string cmd = std::string(DQO_DETECT_TOOL) + " " + args + " 2>&1";
  std::printf("$ %s\n", cmd.c_str());
  const int rc = std::system(cmd.c_str());
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

TEST(DqoDetect, WritesDetectionsTheDatasetReaderReadsBack) {
  TempDir tmp;
  const std::string data = tmp.file("data");
  ASSERT_TRUE(write_dataset(data));
  test::write_text(tmp.file("names.txt"), "person\ncup\nbook\n");
  // The detector test's scene: cup, book (same box), person; prototypes split left and right.
  const std::vector<test::RawCandidate> scene = {{32, 30, 20, 8, 1, 0.9f, 1.f, {10.f, 0.f}},
                                                 {32, 30, 20, 8, 2, 0.7f, 1.f, {0.f, 10.f}},
                                                 {50, 40, 12, 12, 0, 0.6f, 1.f, {-10.f, 0.f}}};
  std::vector<float> protos(2 * 16 * 16);
  for (int v = 0; v < 16; ++v)
    for (int u = 0; u < 16; ++u) protos[v * 16 + u] = u < 8 ? 1.f : -1.f, protos[256 + v * 16 + u] = 1.f;
  ASSERT_TRUE(test::make_model(tmp, "seg.onnx", 64, 64,
                               {{{1, 9, 10}, test::make_output(scene, 10, 3, 2, false)}, {{1, 2, 16, 16}, protos}}));
  const std::string common = data + " --model " + tmp.file("seg.onnx") + " --classes " + tmp.file("names.txt") +
                             " --input-size 64x64";
  ASSERT_EQ(run(common), 0);

  std::string error;
  const auto reader = open_dataset(data, &error);
  ASSERT_TRUE(reader) << error;
  for (int f = 0; f < 2; ++f) {
    const auto frame = reader->read_frame(f, &error);
    ASSERT_TRUE(frame) << error;
    ASSERT_EQ(frame->detections.size(), 3u) << "frame " << f;
    EXPECT_EQ(frame->detections[0].class_name, "cup");
    EXPECT_EQ(frame->detections[1].class_name, "book");
    EXPECT_EQ(frame->detections[2].class_name, "person");
    EXPECT_NEAR(frame->detections[0].score, 0.9, 1e-4);
    // (x_in - 0) / 0.2, (y_in - 8) / 0.2, written with two decimals.
    EXPECT_NEAR(frame->detections[0].box.x_min, 110, 0.01);
    EXPECT_NEAR(frame->detections[0].box.y_max, 130, 0.01);
    EXPECT_NEAR(frame->detections[2].box.x_max, 280, 0.01);
    const auto mask = read_png_u16(data + "/detections_instance/00000" + std::to_string(f) + ".png", &error);
    ASSERT_TRUE(mask) << error;
    EXPECT_EQ(mask->at(120, 100), 1) << "cup: left of its box";
    EXPECT_EQ(mask->at(200, 100), 2) << "book: the right of the same box";
    EXPECT_EQ(mask->at(250, 160), 3) << "person";
    EXPECT_EQ(mask->at(10, 10), 0);
  }
  EXPECT_EQ(reader->info().class_names.at(2), "book");

  // Once more: the file holds detections now; --force replaces them; a classes.txt that disagrees
  // stops the run.
  EXPECT_EQ(run(common), 1);
  EXPECT_EQ(run(common + " --force --frames 1"), 0);
  EXPECT_EQ(open_dataset(data, &error)->read_frame(1, &error)->detections.size(), 0u) << "only frame 0 now";
  test::write_text(data + "/classes.txt", "0 person\n1 mug\n");
  EXPECT_EQ(run(common + " --force"), 1);
  EXPECT_EQ(run(data + " --model " + tmp.file("missing.onnx")), 1);
  EXPECT_EQ(run(data), 2) << "no --model: usage";
}

}  // namespace
}  // namespace dqo::detector

#endif
