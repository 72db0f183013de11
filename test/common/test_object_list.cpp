// Object list files (`id class tx ty tz qx qy qz qw a1 a2 a3`): exact round trip, comments,
// errors that name file and line, and a write that leaves no temporary file behind.
#include "dqo_map/common/object_list.h"

#include <cmath>
#include <filesystem>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "../io/io_test_util.h"  // TempDir, write_text, read_text: plain C++, no io/ library

namespace dqo {
namespace {

namespace fs = std::filesystem;

std::vector<ObjectListEntry> random_objects(int n, std::mt19937_64& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> positive(1e-3, 2.0);
  std::vector<ObjectListEntry> objects;
  for (int i = 0; i < n; ++i) {
    ObjectListEntry e;
    e.id = 1 + 7 * static_cast<uint64_t>(i);
    e.class_id = i % 5 - 1;  // negative classes are legal integers too
    // Numbers with full mantissas and a wide range of magnitudes, so a lossy format would show.
    e.centre = Eigen::Vector3d(normal(rng), normal(rng), normal(rng)) * std::pow(10.0, i % 7 - 3);
    e.rotation =
        Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng)).normalized();
    e.semi_axes = Eigen::Vector3d(positive(rng), positive(rng), positive(rng));
    objects.push_back(e);
  }
  objects.back().id = static_cast<uint64_t>(std::numeric_limits<long long>::max());
  objects.back().semi_axes.z() = 0.0;  // flat objects are legal
  return objects;
}

TEST(ObjectList, RoundTripIsExact) {
  test::TempDir tmp;
  std::mt19937_64 rng(11);
  const auto objects = random_objects(25, rng);
  std::string error;
  ASSERT_TRUE(write_object_list(tmp / "objects.txt", objects, &error)) << error;
  const auto back = read_object_list(tmp / "objects.txt", &error);
  ASSERT_TRUE(back) << error;
  ASSERT_EQ(back->size(), objects.size());
  for (size_t i = 0; i < objects.size(); ++i) {
    EXPECT_EQ((*back)[i].id, objects[i].id);
    EXPECT_EQ((*back)[i].class_id, objects[i].class_id);
    EXPECT_EQ((*back)[i].centre, objects[i].centre);
    EXPECT_EQ((*back)[i].rotation.coeffs(), objects[i].rotation.coeffs());  // bit for bit
    EXPECT_EQ((*back)[i].semi_axes, objects[i].semi_axes);
  }
  EXPECT_EQ(test::read_text(tmp / "objects.txt").rfind("# id class tx ty tz qx qy qz qw", 0), 0u);
}

TEST(ObjectList, ReadsCommentsBlankLinesAndNormalisesQuaternions) {
  test::TempDir tmp;
  test::write_text(tmp / "objects.txt",
                   "# objects of a run\n"
                   "\n"
                   "  # indented comment\n"
                   "3 2 1 2 3 0 0 0.70710678118654757 0.70710678118654757 0.5 0.25 0.125\r\n"
                   "\t5 0 -1 0 0.5 0 0 0 2 1 1 1\n");
  std::string error;
  const auto objects = read_object_list(tmp / "objects.txt", &error);
  ASSERT_TRUE(objects) << error;
  ASSERT_EQ(objects->size(), 2u);
  EXPECT_EQ((*objects)[0].id, 3u);
  EXPECT_EQ((*objects)[0].class_id, 2);
  EXPECT_EQ((*objects)[0].centre, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ((*objects)[0].semi_axes, Eigen::Vector3d(0.5, 0.25, 0.125));
  // Scalar last: 90 degrees about z maps the box's first axis onto world y.
  const OrientedBox box = to_oriented_box((*objects)[0]);
  EXPECT_LT((box.rotation.col(0) - Eigen::Vector3d::UnitY()).norm(), 1e-12);
  EXPECT_EQ(box.half_extents, Eigen::Vector3d(0.5, 0.25, 0.125));
  // (0, 0, 0, 2) is the identity at twice unit length: read as the unit quaternion.
  EXPECT_NEAR((*objects)[1].rotation.w(), 1.0, 1e-15);
  EXPECT_NEAR((*objects)[1].rotation.norm(), 1.0, 1e-15);
}

TEST(ObjectList, BoxConversionRoundTrips) {
  OrientedBox box;
  box.centre = Eigen::Vector3d(0.3, -1.2, 0.8);
  box.rotation =
      Eigen::AngleAxisd(0.9, Eigen::Vector3d(1, -2, 0.5).normalized()).toRotationMatrix();
  box.half_extents = Eigen::Vector3d(0.4, 0.2, 0.1);
  const ObjectListEntry e = make_object_list_entry(42, 7, box);
  EXPECT_EQ(e.id, 42u);
  EXPECT_EQ(e.class_id, 7);
  const OrientedBox back = to_oriented_box(e);
  EXPECT_EQ(back.centre, box.centre);
  EXPECT_LT((back.rotation - box.rotation).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_EQ(back.half_extents, box.half_extents);
}

TEST(ObjectList, MalformedLinesNameFileAndLine) {
  test::TempDir tmp;
  const std::string good = "# header\n1 0 0 0 0 0 0 0 1 1 1 1\n";  // the bad line is line 3
  struct Case {
    const char* line;
    const char* why;  // a word the message must contain
  };
  const Case cases[] = {
      {"2 0 0 0 0 0 0 0 1 1 1", "12 fields"},
      {"2 0 0 0 0 0 0 0 1 1 1 1 1", "12 fields"},
      {"x 0 0 0 0 0 0 0 1 1 1 1", "id"},
      {"-2 0 0 0 0 0 0 0 1 1 1 1", "id"},
      {"0 0 0 0 0 0 0 0 1 1 1 1", "id"},
      {"2.5 0 0 0 0 0 0 0 1 1 1 1", "id"},
      {"2 car 0 0 0 0 0 0 1 1 1 1", "class"},
      {"2 99999999999 0 0 0 0 0 0 1 1 1 1", "class"},
      {"2 0 nan 0 0 0 0 0 1 1 1 1", "tx"},
      {"2 0 0 0 inf 0 0 0 1 1 1 1", "tz"},
      {"2 0 0 0 0 0 0 0 1 1 1 abc", "a3"},
      {"2 0 0 0 0 0 0 0 0 1 1 1", "quaternion"},
      {"2 0 0 0 0 0 0 0 1e-9 1 1 1", "quaternion"},
      {"2 0 0 0 0 0 0 0 1 1 -0.5 1", "negative"},
      {"1 0 0 0 0 0 0 0 1 1 1 1", "twice"},
  };
  for (const Case& c : cases) {
    const std::string path = tmp / "objects.txt";
    test::write_text(path, good + c.line + "\n");
    std::string error;
    EXPECT_FALSE(read_object_list(path, &error)) << c.line;
    EXPECT_EQ(error.rfind(path + ":3:", 0), 0u) << c.line << " -> " << error;
    EXPECT_NE(error.find(c.why), std::string::npos) << c.line << " -> " << error;
  }
}

TEST(ObjectList, MissingFileIsAnError) {
  test::TempDir tmp;
  std::string error;
  EXPECT_FALSE(read_object_list(tmp / "none.txt", &error));
  EXPECT_NE(error.find("none.txt"), std::string::npos) << error;
}

TEST(ObjectList, AtomicWriteReplacesAndLeavesNoTemporaryFile) {
  test::TempDir tmp;
  std::mt19937_64 rng(3);
  const std::string path = tmp / "objects.txt";
  test::write_text(path, "old content\n");
  std::string error;
  ASSERT_TRUE(write_object_list(path, random_objects(4, rng), &error)) << error;
  int files = 0;
  for (const auto& entry : fs::directory_iterator(tmp.path())) {
    ++files;
    EXPECT_EQ(entry.path().filename(), "objects.txt");
  }
  EXPECT_EQ(files, 1);
  const auto back = read_object_list(path, &error);
  ASSERT_TRUE(back) << error;
  EXPECT_EQ(back->size(), 4u);

  // A write into a folder that does not exist fails and says where.
  EXPECT_FALSE(write_object_list(tmp / "missing/objects.txt", *back, &error));
  EXPECT_NE(error.find("missing/objects.txt"), std::string::npos) << error;
}

TEST(ObjectList, WriteRefusesWhatCouldNotBeReadBack) {
  test::TempDir tmp;
  std::mt19937_64 rng(4);
  const std::string path = tmp / "objects.txt";
  const auto objects = random_objects(3, rng);
  auto with = [&](auto change) {
    auto copy = objects;
    change(copy);
    return copy;
  };
  const std::vector<std::vector<ObjectListEntry>> bad = {
      with([](auto& o) { o[1].centre.y() = std::numeric_limits<double>::quiet_NaN(); }),
      with([](auto& o) { o[1].rotation.coeffs().setZero(); }),
      with([](auto& o) { o[1].semi_axes.x() = -1.0; }),
      with([](auto& o) { o[2].id = o[0].id; }),
      with([](auto& o) { o[0].id = 0; }),
  };
  for (const auto& objects_bad : bad) {
    std::string error;
    EXPECT_FALSE(write_object_list(path, objects_bad, &error));
    EXPECT_NE(error.find(path), std::string::npos) << error;
    EXPECT_FALSE(fs::exists(path));
  }
}

}  // namespace
}  // namespace dqo
