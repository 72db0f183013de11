// Gaussian PLY export/import: the 3DGS layout byte for byte (checked by hand, not by the reader),
// round trips of a random map and of one object's subset, files written by other 3DGS tools (extra
// properties, no object_id, other orders, types and formats), and damaged or foreign files refused
// with a message naming the file.

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "../io/io_test_util.h"  // TempDir: plain C++, no io/ library
#include "dqo_map/gaussians/gaussian_ply.h"

namespace dqo::gs {
namespace {

using test::TempDir;

using test::read_bytes;
using test::write_bytes;

template <typename T>
void append(std::string& out, T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  out.append(b, sizeof(T));
}

template <typename T>
T read_at(const std::string& bytes, size_t offset) {
  T v;
  std::memcpy(&v, bytes.data() + offset, sizeof(T));
  return v;
}

double logit(double p) { return std::log(p / (1.0 - p)); }
double sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }

// A few hundred Gaussians over several objects and both types, half with an explicit opacity, with
// rotations left non-unit (as the trainer leaves them) to check that they are stored as they are.
GaussianMap random_map(uint32_t seed, size_t n) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> pos(-5.f, 5.f), log_scale(-6.f, -1.f), unit(0.f, 1.f),
      opacity(0.01f, 0.99f);
  std::normal_distribution<float> normal(0.f, 1.f);
  const uint32_t ids[] = {0, 1, 2, 3, 7, 4000000000u};
  GaussianMap map;
  for (size_t i = 0; i < n; ++i) {
    GaussianInit g;
    g.position = Eigen::Vector3f(pos(rng), pos(rng), pos(rng));
    g.log_scale = Eigen::Vector3f(log_scale(rng), log_scale(rng), log_scale(rng));
    g.rotation = Eigen::Vector4f(normal(rng), normal(rng), normal(rng), normal(rng));
    g.colour = Eigen::Vector3f(unit(rng), unit(rng), unit(rng));
    g.opacity = rng() % 2 ? opacity(rng) : -1.f;
    g.object_id = ids[rng() % 6];
    g.type = rng() % 3 == 0 ? GaussianType::kTransparent : GaussianType::kOpaque;
    g.birth_keyframe = rng() % 100;
    map.add(g);
  }
  return map;
}

// Gaussian `i` of `a` against Gaussian `j` of `b`: what the PLY keeps, to its precision.
void expect_same_gaussian(const GaussianMap& a, size_t i, const GaussianMap& b, size_t j) {
  for (int c = 0; c < 3; ++c) {
    EXPECT_EQ(a.positions()[3 * i + c], b.positions()[3 * j + c]) << i;
    EXPECT_EQ(a.log_scales()[3 * i + c], b.log_scales()[3 * j + c]) << i;
    EXPECT_NEAR(a.colours()[3 * i + c], b.colours()[3 * j + c], 1e-6) << i;
  }
  for (int c = 0; c < 4; ++c) EXPECT_EQ(a.rotations()[4 * i + c], b.rotations()[4 * j + c]) << i;
  EXPECT_NEAR(a.opacities()[i], b.opacities()[j], 1e-6) << i;
  EXPECT_EQ(a.object_ids_per_gaussian()[i], b.object_ids_per_gaussian()[j]) << i;
}

// The header of the original 3DGS code's files (degree 3: 45 f_rest), without object_id.
std::string original_3dgs_header(size_t n, const char* format = "binary_little_endian") {
  std::string h = "ply\nformat " + std::string(format) + " 1.0\nelement vertex " +
                  std::to_string(n) + "\n";
  for (const char* p : {"x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"})
    h += "property float " + std::string(p) + "\n";
  for (int k = 0; k < 45; ++k) h += "property float f_rest_" + std::to_string(k) + "\n";
  for (const char* p : {"opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2",
                        "rot_3"})
    h += "property float " + std::string(p) + "\n";
  return h + "end_header\n";
}

TEST(GaussianPly, WholeMapRoundTrips) {
  TempDir tmp;
  const GaussianMap map = random_map(1, 300);
  const std::string path = tmp / "map.ply";
  std::string error;
  ASSERT_TRUE(save_gaussians_ply(path, map, nullptr, &error)) << error;
  const std::optional<GaussianMap> back = load_gaussians_ply(path, &error);
  ASSERT_TRUE(back) << error;
  ASSERT_EQ(back->size(), map.size());
  for (size_t i = 0; i < map.size(); ++i) expect_same_gaussian(map, i, *back, i);
  EXPECT_EQ(back->object_ids(), map.object_ids());
  // What the layout has no room for comes back as the documented defaults.
  for (size_t i = 0; i < back->size(); ++i) {
    EXPECT_EQ(back->types()[i], uint8_t(GaussianType::kOpaque));
    EXPECT_EQ(back->birth_keyframes()[i], 0u);
  }
}

TEST(GaussianPly, OneObjectsSubsetRoundTrips) {
  TempDir tmp;
  const GaussianMap map = random_map(2, 300);
  const std::vector<uint32_t> indices = map.indices_of(3);
  ASSERT_GT(indices.size(), 10u);
  ASSERT_LT(indices.size(), map.size());
  const std::string path = tmp / "object_3.ply";
  std::string error;
  ASSERT_TRUE(save_gaussians_ply(path, map, &indices, &error)) << error;
  const std::optional<GaussianMap> back = load_gaussians_ply(path, &error);
  ASSERT_TRUE(back) << error;
  ASSERT_EQ(back->size(), indices.size());
  for (size_t k = 0; k < indices.size(); ++k) expect_same_gaussian(map, indices[k], *back, k);
  EXPECT_EQ(back->object_ids(), std::vector<uint32_t>{3});

  // An index past the end is refused, and no file is left behind.
  const std::vector<uint32_t> bad = {0, static_cast<uint32_t>(map.size())};
  EXPECT_FALSE(save_gaussians_ply(tmp / "bad.ply", map, &bad, &error));
  EXPECT_NE(error.find("bad.ply"), std::string::npos) << error;
  EXPECT_NE(error.find("out of range"), std::string::npos) << error;
  EXPECT_FALSE(std::filesystem::exists(tmp / "bad.ply"));
}

// The bytes the writer produces, decoded by hand with the 3DGS encodings: a check of the layout
// that does not go through the reader.
TEST(GaussianPly, WritesThe3dgsLayout) {
  TempDir tmp;
  const GaussianMap map = random_map(3, 20);
  const std::string path = tmp / "layout.ply";
  std::string error;
  ASSERT_TRUE(save_gaussians_ply(path, map, nullptr, &error)) << error;
  const std::string bytes = read_bytes(path);

  const std::string end = "end_header\n";
  ASSERT_NE(bytes.find(end), std::string::npos);
  const size_t data = bytes.find(end) + end.size();
  std::string expected_properties;
  for (const char* p : {"x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
                        "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"})
    expected_properties += "property float " + std::string(p) + "\n";
  expected_properties += "property uint object_id\n";
  const std::string header = bytes.substr(0, data);
  EXPECT_EQ(header.rfind("ply\nformat binary_little_endian 1.0\n", 0), 0u) << header;
  EXPECT_NE(header.find("element vertex 20\n" + expected_properties + end), std::string::npos)
      << header;

  constexpr size_t kStride = 17 * 4 + 4;
  ASSERT_EQ(bytes.size(), data + 20 * kStride);
  for (size_t i = 0; i < map.size(); ++i) {
    const size_t row = data + i * kStride;
    const auto f = [&](int k) { return read_at<float>(bytes, row + 4 * k); };
    for (int c = 0; c < 3; ++c) {
      EXPECT_EQ(f(c), map.positions()[3 * i + c]);
      EXPECT_EQ(f(3 + c), 0.f);  // normals
      EXPECT_NEAR(f(6 + c), (map.colours()[3 * i + c] - 0.5) / 0.28209479177387814, 1e-5);
      EXPECT_EQ(f(10 + c), map.log_scales()[3 * i + c]);
    }
    EXPECT_NEAR(f(9), logit(map.opacities()[i]), 1e-5);
    for (int c = 0; c < 4; ++c) EXPECT_EQ(f(13 + c), map.rotations()[4 * i + c]);
    EXPECT_EQ(read_at<uint32_t>(bytes, row + 68), map.object_ids_per_gaussian()[i]);
  }
}

// A file as the original 3DGS code writes it: 45 f_rest properties, no object_id.
TEST(GaussianPly, ReadsOriginal3dgsFiles) {
  TempDir tmp;
  std::string bytes = original_3dgs_header(3);
  for (int i = 0; i < 3; ++i) {
    const float v = float(i + 1);
    for (float x : {v, -v, 2 * v}) append(bytes, x);                 // x y z
    for (int k = 0; k < 3; ++k) append(bytes, 0.f);                  // normals
    for (float x : {0.1f * v, -0.2f * v, 0.f}) append(bytes, x);     // f_dc
    for (int k = 0; k < 45; ++k) append(bytes, 100.f + float(k));    // f_rest: ignored
    append(bytes, -1.f + v);                                         // opacity (logit)
    for (float x : {-3.f, -4.f, -5.f * v}) append(bytes, x);         // log scales
    for (float x : {1.f, 0.f, 0.5f * v, -2.f}) append(bytes, x);     // rot w x y z, not unit
  }
  const std::string path = tmp / "point_cloud.ply";
  write_bytes(path, bytes);
  std::string error;
  const std::optional<GaussianMap> map = load_gaussians_ply(path, &error);
  ASSERT_TRUE(map) << error;
  ASSERT_EQ(map->size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    const float v = float(i + 1);
    EXPECT_EQ(map->positions()[3 * i + 0], v);
    EXPECT_EQ(map->positions()[3 * i + 1], -v);
    EXPECT_EQ(map->positions()[3 * i + 2], 2 * v);
    EXPECT_NEAR(map->colours()[3 * i + 0], 0.5 + kShC0 * 0.1 * v, 1e-6);
    EXPECT_NEAR(map->colours()[3 * i + 1], 0.5 - kShC0 * 0.2 * v, 1e-6);
    EXPECT_NEAR(map->colours()[3 * i + 2], 0.5, 1e-7);
    EXPECT_NEAR(map->opacities()[i], sigmoid(-1.0 + v), 1e-7);
    EXPECT_EQ(map->log_scales()[3 * i + 2], -5.f * v);
    EXPECT_EQ(map->rotations()[4 * i + 0], 1.f);
    EXPECT_EQ(map->rotations()[4 * i + 2], 0.5f * v);
    EXPECT_EQ(map->rotations()[4 * i + 3], -2.f);
    EXPECT_EQ(map->object_ids_per_gaussian()[i], 0u);
  }
}

// ascii, CRLF line ends, properties in another order and of other types (double, uchar, int),
// comments, an element before the vertices and a face element after them.
TEST(GaussianPly, ReadsAsciiInAnyPropertyOrderAndType) {
  TempDir tmp;
  const std::string text =
      "ply\r\nformat ascii 1.0\r\ncomment made by hand\r\n"
      "element camera 2\r\nproperty float fx\r\nproperty list uchar int junk\r\n"
      "element vertex 2\r\n"
      "property double rot_0\r\nproperty double rot_1\r\nproperty double rot_2\r\n"
      "property double rot_3\r\nproperty uchar object_id\r\nproperty double opacity\r\n"
      "property float f_dc_2\r\nproperty float f_dc_1\r\nproperty float f_dc_0\r\n"
      "property int scale_0\r\nproperty float scale_1\r\nproperty float scale_2\r\n"
      "property float z\r\nproperty float y\r\nproperty float x\r\nproperty float f_rest_0\r\n"
      "element face 1\r\nproperty list uchar int vertex_indices\r\n"
      "end_header\r\n"
      "500 3 1 2 3\r\n501 0\r\n"
      "1 0 0 0 5 0 0 0 0 -3 -4 -5 3 2 1 9\r\n"
      "0.5 0.5 0.5 0.5 255 2.5 1 -1 0.5 -2 -2.5 -3.5 -3 -2 -1 9\r\n"
      "3 0 1 1\r\n";
  const std::string path = tmp / "ascii.ply";
  write_bytes(path, text);
  std::string error;
  const std::optional<GaussianMap> map = load_gaussians_ply(path, &error);
  ASSERT_TRUE(map) << error;
  ASSERT_EQ(map->size(), 2u);
  EXPECT_EQ(map->object_ids_per_gaussian(), (std::vector<uint32_t>{5, 255}));
  EXPECT_EQ(map->positions(), (std::vector<float>{1, 2, 3, -1, -2, -3}));
  EXPECT_EQ(map->log_scales(), (std::vector<float>{-3, -4, -5, -2, -2.5f, -3.5f}));
  EXPECT_EQ(map->rotations(), (std::vector<float>{1, 0, 0, 0, 0.5f, 0.5f, 0.5f, 0.5f}));
  EXPECT_NEAR(map->opacities()[0], 0.5, 1e-7);
  EXPECT_NEAR(map->opacities()[1], sigmoid(2.5), 1e-7);
  EXPECT_NEAR(map->colours()[3], 0.5 + kShC0 * 0.5, 1e-7);   // f_dc_0 of vertex 1
  EXPECT_NEAR(map->colours()[4], 0.5 - kShC0 * 1.0, 1e-7);   // f_dc_1
  EXPECT_NEAR(map->colours()[5], 0.5 + kShC0 * 1.0, 1e-7);   // f_dc_2
}

TEST(GaussianPly, ReadsBigEndianDoubles) {
  TempDir tmp;
  std::string bytes = "ply\nformat binary_big_endian 1.0\nelement vertex 1\n";
  for (const char* p : {"x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0",
                        "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"})
    bytes += "property double " + std::string(p) + "\n";
  bytes += "property uint object_id\nend_header\n";
  const auto append_big = [&](auto v) {
    char b[sizeof(v)];
    std::memcpy(b, &v, sizeof(v));
    for (size_t k = sizeof(v); k-- > 0;) bytes.push_back(b[k]);
  };
  for (double v : {1.5, -2.25, 3.0, 0.0, 1.0, -1.0, 0.0, -3.0, -4.0, -5.0, 0.0, 1.0, 0.0, 0.0})
    append_big(v);
  append_big(uint32_t{70000});
  const std::string path = tmp / "big.ply";
  write_bytes(path, bytes);
  std::string error;
  const std::optional<GaussianMap> map = load_gaussians_ply(path, &error);
  ASSERT_TRUE(map) << error;
  ASSERT_EQ(map->size(), 1u);
  EXPECT_EQ(map->positions(), (std::vector<float>{1.5f, -2.25f, 3.f}));
  EXPECT_EQ(map->rotations(), (std::vector<float>{0, 1, 0, 0}));
  EXPECT_EQ(map->object_ids_per_gaussian()[0], 70000u);
  EXPECT_NEAR(map->colours()[1], 0.5 + kShC0, 1e-7);
  EXPECT_NEAR(map->opacities()[0], 0.5, 1e-7);
}

void expect_rejected(const std::string& path, const std::string& why) {
  std::string error;
  EXPECT_FALSE(load_gaussians_ply(path, &error)) << path;
  EXPECT_NE(error.find(path), std::string::npos) << error;
  EXPECT_NE(error.find(why), std::string::npos) << "expected \"" << why << "\" in: " << error;
}

TEST(GaussianPly, RejectsDamagedAndForeignFiles) {
  TempDir tmp;
  const GaussianMap map = random_map(4, 50);
  const std::string path = tmp / "good.ply";
  std::string error;
  ASSERT_TRUE(save_gaussians_ply(path, map, nullptr, &error)) << error;
  const std::string bytes = read_bytes(path);
  const size_t data = bytes.find("end_header\n") + 11;

  // Cut in the header, at the first data byte, inside a vertex, one byte short.
  for (const size_t cut : {size_t{20}, data - 3, data, data + 100, bytes.size() - 1}) {
    const std::string cut_path = tmp / ("cut_" + std::to_string(cut) + ".ply");
    write_bytes(cut_path, bytes.substr(0, cut));
    expect_rejected(cut_path, "truncated");
  }

  write_bytes(tmp / "text.ply", "hello, world\n");
  expect_rejected(tmp / "text.ply", "not a PLY file");
  write_bytes(tmp / "empty.ply", "");
  expect_rejected(tmp / "empty.ply", "not a PLY file");
  std::string junk(4096, '\0');
  std::mt19937 rng(5);
  for (char& c : junk) c = static_cast<char>(rng());
  junk[0] = 'p';  // starts almost like a PLY
  write_bytes(tmp / "junk.ply", junk);
  expect_rejected(tmp / "junk.ply", "not a PLY file");
  // A PLY that is not a Gaussian PLY: a mesh.
  write_bytes(tmp / "mesh.ply",
              "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
              "property float z\nend_header\n0 0 0\n");
  expect_rejected(tmp / "mesh.ply", "missing: f_dc_0 f_dc_1 f_dc_2 opacity");
  // One required property gone from an otherwise 3DGS header.
  std::string no_rot3 = original_3dgs_header(0);
  no_rot3.erase(no_rot3.find("property float rot_3\n"), 21);
  write_bytes(tmp / "no_rot3.ply", no_rot3);
  expect_rejected(tmp / "no_rot3.ply", "missing: rot_3");
  // Fewer ascii rows than the header says.
  write_bytes(tmp / "short.ply", original_3dgs_header(2, "ascii") + std::string(61 * 2, '1'));
  expect_rejected(tmp / "short.ply", "vertex 0: expected 62 numbers, found 1");
  std::string one_row;
  for (int k = 0; k < 62; ++k) one_row += "1 ";
  write_bytes(tmp / "short2.ply", original_3dgs_header(2, "ascii") + one_row + "\n");
  expect_rejected(tmp / "short2.ply", "truncated: 1 of 2 vertices");
  expect_rejected(tmp / "missing.ply", "cannot open");
  expect_rejected(tmp.path(), "is a folder");
}

TEST(GaussianPly, SaveReplacesAtomicallyAndFailsCleanly) {
  TempDir tmp;
  const GaussianMap map = random_map(6, 30);
  const std::string path = tmp / "map.ply";
  std::string error;
  ASSERT_TRUE(save_gaussians_ply(path, random_map(7, 5), nullptr, &error)) << error;
  ASSERT_TRUE(save_gaussians_ply(path, map, nullptr, &error)) << error;  // over an existing file
  const std::optional<GaussianMap> back = load_gaussians_ply(path, &error);
  ASSERT_TRUE(back) << error;
  EXPECT_EQ(back->size(), map.size());
  // Only the file itself: no temporary left beside it.
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(tmp.path()))
    names.push_back(e.path().filename().string());
  EXPECT_EQ(names, std::vector<std::string>{"map.ply"});

  const std::string missing = tmp / "no_such_folder/map.ply";
  EXPECT_FALSE(save_gaussians_ply(missing, map, nullptr, &error));
  EXPECT_NE(error.find(missing), std::string::npos) << error;
  EXPECT_FALSE(std::filesystem::exists(tmp / "no_such_folder"));

  // An empty map is a valid file with no vertices.
  ASSERT_TRUE(save_gaussians_ply(tmp / "empty.ply", GaussianMap(), nullptr, &error)) << error;
  const std::optional<GaussianMap> empty = load_gaussians_ply(tmp / "empty.ply", &error);
  ASSERT_TRUE(empty) << error;
  EXPECT_TRUE(empty->empty());
}

}  // namespace
}  // namespace dqo::gs
