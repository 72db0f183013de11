// The versioned map file: exact round trips (every Gaussian array bit for bit, objects, keyframes,
// next ID, parameter hash), byte-identical files on save → load → save, and every kind of damage
// refused with its own message and nothing returned.

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "../io/io_test_util.h"  // TempDir: plain C++, no io/ library
#include "dqo_map/mapping/map_file.h"

namespace dqo::mapping {
namespace {

using test::TempDir;

using test::read_bytes;
using test::write_bytes;

template <typename T>
void patch(std::string& bytes, size_t offset, T v) {
  std::memcpy(bytes.data() + offset, &v, sizeof(T));
}

Eigen::Quaterniond random_quaternion(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized();
}

// A map of every kind of content: Gaussians over several objects and both types, explicit and
// default opacities, confidences, stable flags, a few special floats (NaN with a payload, -0,
// a subnormal, infinity: the file must keep bits, not values); objects with random valid quadrics
// and boxes and awkward names; keyframes with random poses.
MapFileContents random_contents(uint64_t seed, size_t n_gaussians = 300) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const auto uf = [&] { return static_cast<float>(u(rng)); };
  MapFileContents m;
  const uint32_t ids[] = {0, 1, 2, 5, 9, 4000000000u};
  for (size_t i = 0; i < n_gaussians; ++i) {
    gs::GaussianInit g;
    g.position = Eigen::Vector3f(5 * uf(), 5 * uf(), 5 * uf());
    g.log_scale = Eigen::Vector3f(-4 + uf(), -4 + uf(), -4 + uf());
    g.rotation = Eigen::Vector4f(uf(), uf(), uf(), uf());
    g.colour = Eigen::Vector3f(0.5f + 0.5f * uf(), 0.5f + 0.5f * uf(), 0.5f + 0.5f * uf());
    g.opacity = rng() % 2 ? 0.5f + 0.49f * uf() : -1.f;
    g.object_id = ids[rng() % 6];
    g.type = rng() % 3 == 0 ? gs::GaussianType::kTransparent : gs::GaussianType::kOpaque;
    g.birth_keyframe = static_cast<uint32_t>(rng() % 1000);
    m.gaussians.add(g);
  }
  for (size_t i = 0; i < n_gaussians; ++i) {
    m.gaussians.confidences()[i] = static_cast<float>(rng() % 1000) / 7.f;
    m.gaussians.stable()[i] = static_cast<uint8_t>(rng() % 2);
  }
  if (n_gaussians >= 4) {
    uint32_t nan_bits = 0x7fc12345u;  // a quiet NaN with a payload
    std::memcpy(&m.gaussians.positions()[0], &nan_bits, 4);
    m.gaussians.log_scales()[1] = -0.f;
    m.gaussians.colours()[2] = std::numeric_limits<float>::denorm_min();
    m.gaussians.confidences()[3] = std::numeric_limits<float>::infinity();
    m.gaussians.opacities()[3] = -0.25f;  // what add() would not keep
  }

  const char* names[] = {"chair", "", "potted plant", "caf\xc3\xa9 table"};
  for (int k = 0; k < 4; ++k) {
    ObjectRecord o;
    o.id = (uint64_t{1} << 40) + static_cast<uint64_t>(k) * 3;
    o.class_id = k == 1 ? -1 : 56 + k;
    o.class_name = names[k];
    o.quadric = DualQuadric::from_params(Eigen::Vector3d(u(rng), u(rng), u(rng)),
                                         random_quaternion(rng).toRotationMatrix(),
                                         Eigen::Vector3d(0.1 + std::abs(u(rng)), 0.2 + std::abs(u(rng)),
                                                         0.3 + std::abs(u(rng))));
    o.box = box_from_quadric(o.quadric);
    o.box.half_extents *= 1.0 + 0.1 * u(rng);
    o.observations = static_cast<int>(rng() % 100);
    o.confidence = std::abs(u(rng));
    m.objects.push_back(o);
  }

  for (int k = 0; k < 64; ++k) {
    KeyframePose kf;
    kf.id = static_cast<KeyframeId>(3 * k + 1);
    kf.stamp = 1.6e9 + 0.0333 * k + 1e-7 * u(rng);
    kf.camera.fx = 500 + u(rng);
    kf.camera.fy = 501 + u(rng);
    kf.camera.cx = 319.5 + u(rng);
    kf.camera.cy = 239.5 + u(rng);
    kf.camera.width = 640;
    kf.camera.height = 480;
    // Not normalised here: SE3 normalises once, which leaves about a third of its quaternions ones
    // that a second normalisation (the one loading goes through) would move.
    std::normal_distribution<double> n(0.0, 1.0);
    kf.T_wc = SE3(Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)),
                  Eigen::Vector3d(3 * u(rng), 3 * u(rng), u(rng)));
    m.keyframes.push_back(kf);
  }
  m.next_object_id = (uint64_t{1} << 40) + 12;
  m.params_hash = params_hash("gaussians:\n  budget: 500000\n");
  return m;
}

template <typename T>
void expect_bits_equal(const std::vector<T>& a, const std::vector<T>& b, const char* what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(T)), 0) << what;
}

void expect_matrix_eq(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b, const std::string& what) {
  EXPECT_TRUE(a == b) << what << ":\n" << a << "\nvs\n" << b;
}

TEST(MapFile, RoundTripIsExact) {
  TempDir tmp;
  const MapFileContents map = random_contents(1);
  const std::string path = tmp / "map.dqomap";
  std::string error;
  ASSERT_TRUE(save_map_file(path, map, &error)) << error;
  const std::optional<MapFileContents> back = load_map_file(path, &error);
  ASSERT_TRUE(back) << error;

  const gs::GaussianMap& a = map.gaussians;
  const gs::GaussianMap& b = back->gaussians;
  ASSERT_EQ(b.size(), a.size());
  expect_bits_equal(a.positions(), b.positions(), "positions");
  expect_bits_equal(a.log_scales(), b.log_scales(), "log_scales");
  expect_bits_equal(a.rotations(), b.rotations(), "rotations");
  expect_bits_equal(a.opacities(), b.opacities(), "opacities");
  expect_bits_equal(a.colours(), b.colours(), "colours");
  expect_bits_equal(a.confidences(), b.confidences(), "confidences");
  expect_bits_equal(a.stable(), b.stable(), "stable");
  expect_bits_equal(a.object_ids_per_gaussian(), b.object_ids_per_gaussian(), "object_ids");
  expect_bits_equal(a.types(), b.types(), "types");
  expect_bits_equal(a.birth_keyframes(), b.birth_keyframes(), "birth_keyframes");

  ASSERT_EQ(back->objects.size(), map.objects.size());
  for (size_t k = 0; k < map.objects.size(); ++k) {
    const ObjectRecord& o = map.objects[k];
    const ObjectRecord& p = back->objects[k];
    EXPECT_EQ(p.id, o.id);
    EXPECT_EQ(p.class_id, o.class_id);
    EXPECT_EQ(p.class_name, o.class_name);
    EXPECT_EQ(p.observations, o.observations);
    EXPECT_EQ(p.confidence, o.confidence);
    expect_matrix_eq(p.quadric.centre(), o.quadric.centre(), "quadric centre");
    expect_matrix_eq(p.quadric.rotation(), o.quadric.rotation(), "quadric rotation");
    expect_matrix_eq(p.quadric.semi_axes(), o.quadric.semi_axes(), "quadric semi-axes");
    expect_matrix_eq(p.box.centre, o.box.centre, "box centre");
    expect_matrix_eq(p.box.rotation, o.box.rotation, "box rotation");
    expect_matrix_eq(p.box.half_extents, o.box.half_extents, "box half extents");
  }

  ASSERT_EQ(back->keyframes.size(), map.keyframes.size());
  int quaternions_exact = 0;
  for (size_t k = 0; k < map.keyframes.size(); ++k) {
    const KeyframePose& o = map.keyframes[k];
    const KeyframePose& p = back->keyframes[k];
    EXPECT_EQ(p.id, o.id);
    EXPECT_EQ(p.stamp, o.stamp);
    EXPECT_EQ(p.camera.fx, o.camera.fx);
    EXPECT_EQ(p.camera.fy, o.camera.fy);
    EXPECT_EQ(p.camera.cx, o.camera.cx);
    EXPECT_EQ(p.camera.cy, o.camera.cy);
    EXPECT_EQ(p.camera.width, o.camera.width);
    EXPECT_EQ(p.camera.height, o.camera.height);
    expect_matrix_eq(p.T_wc.translation(), o.T_wc.translation(), "translation");
    // Exact where SE3 keeps the quaternion as it is; otherwise the stored one is a few ulps away
    // (map_file.h says why).
    const Eigen::Vector4d dq = p.T_wc.quaternion().coeffs() - o.T_wc.quaternion().coeffs();
    EXPECT_LE(dq.cwiseAbs().maxCoeff(), 8 * std::numeric_limits<double>::epsilon()) << k;
    quaternions_exact += dq.isZero(0.0);
  }
  EXPECT_GT(quaternions_exact, 0);
  EXPECT_EQ(back->next_object_id, map.next_object_id);
  EXPECT_EQ(back->params_hash, map.params_hash);
}

TEST(MapFile, SaveLoadSaveIsByteIdentical) {
  TempDir tmp;
  std::string error;
  for (uint64_t seed : {2, 3, 4}) {
    const MapFileContents map = random_contents(seed);
    // The case the test is about: poses whose quaternion SE3 would move when renormalising it.
    int moved = 0;
    for (const KeyframePose& kf : map.keyframes) {
      const Eigen::Quaterniond& q = kf.T_wc.quaternion();
      moved += SE3(q, Eigen::Vector3d::Zero()).quaternion().coeffs() != q.coeffs();
    }
    EXPECT_GT(moved, 5) << "seed " << seed;
    ASSERT_TRUE(save_map_file(tmp / "a", map, &error)) << error;
    const std::optional<MapFileContents> once = load_map_file(tmp / "a", &error);
    ASSERT_TRUE(once) << error;
    ASSERT_TRUE(save_map_file(tmp / "b", *once, &error)) << error;
    const std::optional<MapFileContents> twice = load_map_file(tmp / "b", &error);
    ASSERT_TRUE(twice) << error;
    ASSERT_TRUE(save_map_file(tmp / "c", *twice, &error)) << error;
    const std::string a = read_bytes(tmp / "a");
    EXPECT_GT(a.size(), 300u * 70u);
    EXPECT_TRUE(a == read_bytes(tmp / "b")) << "seed " << seed;
    EXPECT_TRUE(a == read_bytes(tmp / "c")) << "seed " << seed;
  }
}

TEST(MapFile, EmptyMapRoundTrips) {
  TempDir tmp;
  std::string error;
  MapFileContents empty;
  ASSERT_TRUE(save_map_file(tmp / "empty", empty, &error)) << error;
  EXPECT_EQ(read_bytes(tmp / "empty").size(), 88u);  // header and checksum only
  const std::optional<MapFileContents> back = load_map_file(tmp / "empty", &error);
  ASSERT_TRUE(back) << error;
  EXPECT_TRUE(back->gaussians.empty());
  EXPECT_TRUE(back->objects.empty());
  EXPECT_TRUE(back->keyframes.empty());
  EXPECT_EQ(back->next_object_id, 1u);
}

void expect_rejected(const std::string& path, const std::string& why) {
  std::string error;
  EXPECT_FALSE(load_map_file(path, &error)) << path;
  EXPECT_NE(error.find(path), std::string::npos) << error;
  EXPECT_NE(error.find(why), std::string::npos) << "expected \"" << why << "\" in: " << error;
}

TEST(MapFile, RejectsTruncatedFiles) {
  TempDir tmp;
  std::string error;
  ASSERT_TRUE(save_map_file(tmp / "map", random_contents(5), &error)) << error;
  const std::string bytes = read_bytes(tmp / "map");
  // Every cut in and just past the header, then a sample through the sections, and one byte short.
  std::vector<size_t> cuts;
  for (size_t n = 0; n <= 100; ++n) cuts.push_back(n);
  for (size_t n = 101; n < bytes.size(); n += 211) cuts.push_back(n);
  for (size_t n = bytes.size() - 9; n < bytes.size(); ++n) cuts.push_back(n);
  const std::string cut_path = tmp / "cut";
  for (const size_t n : cuts) {
    write_bytes(cut_path, bytes.substr(0, n));
    SCOPED_TRACE("cut at " + std::to_string(n) + " of " + std::to_string(bytes.size()));
    expect_rejected(cut_path, "truncated");
  }
  // Trailing bytes are damage too.
  write_bytes(cut_path, bytes + "x");
  expect_rejected(cut_path, "trailing data");
}

TEST(MapFile, RejectsFlippedBytes) {
  TempDir tmp;
  std::string error;
  ASSERT_TRUE(save_map_file(tmp / "map", random_contents(6), &error)) << error;
  const std::string bytes = read_bytes(tmp / "map");
  // The parameter hash and next ID in the header, the Gaussian, object and keyframe sections, and
  // the checksum itself.
  const size_t n = bytes.size();
  for (const size_t at : {size_t{17}, size_t{30}, size_t{80}, size_t{5000}, size_t{80 + 300 * 70 + 5},
                          n - 200, n - 9, n - 1}) {
    for (const unsigned char mask : {0x01, 0x80}) {
      std::string damaged = bytes;
      damaged[at] = static_cast<char>(damaged[at] ^ mask);
      write_bytes(tmp / "flipped", damaged);
      SCOPED_TRACE("byte " + std::to_string(at));
      expect_rejected(tmp / "flipped", "checksum mismatch");
    }
  }
}

TEST(MapFile, RejectsForeignFilesAndOtherVersions) {
  TempDir tmp;
  std::string error;
  ASSERT_TRUE(save_map_file(tmp / "map", random_contents(7, 20), &error)) << error;
  const std::string bytes = read_bytes(tmp / "map");

  write_bytes(tmp / "ply", "ply\nformat binary_little_endian 1.0\nelement vertex 0\nend_header\n");
  expect_rejected(tmp / "ply", "not a dqo_map map file");
  write_bytes(tmp / "short_text", "DQO");
  expect_rejected(tmp / "short_text", "not a dqo_map map file");
  std::string magic_off = bytes;
  magic_off[1] = 'd';
  write_bytes(tmp / "magic", magic_off);
  expect_rejected(tmp / "magic", "not a dqo_map map file");

  std::string newer = bytes;
  patch<uint32_t>(newer, 8, 2);
  write_bytes(tmp / "v2", newer);
  expect_rejected(tmp / "v2", "map file version 2, this build reads version 1");
  // Only the version field counts: even a v2 file cut short says it is v2.
  write_bytes(tmp / "v2_short", newer.substr(0, 12));
  expect_rejected(tmp / "v2_short", "map file version 2, this build reads version 1");

  expect_rejected(tmp / "no_such_file", "cannot open");
  expect_rejected(tmp.path(), "is a folder");
}

// Counts that cannot be right are refused from the header, before anything is allocated.
TEST(MapFile, RejectsAbsurdSizes) {
  TempDir tmp;
  std::string error;
  ASSERT_TRUE(save_map_file(tmp / "map", random_contents(8, 40), &error)) << error;
  const std::string bytes = read_bytes(tmp / "map");
  constexpr size_t kGaussianCount = 32, kGaussianBytes = 40, kObjectCount = 48,
                   kKeyframeCount = 64;

  std::string a = bytes;
  patch<uint64_t>(a, kGaussianCount, uint64_t{1} << 60);  // count against its section size
  write_bytes(tmp / "a", a);
  expect_rejected(tmp / "a", "corrupt header: 1152921504606846976 Gaussian records cannot take");

  std::string b = bytes;  // count and size agree, but not with the file
  patch<uint64_t>(b, kGaussianCount, uint64_t{1} << 50);
  patch<uint64_t>(b, kGaussianBytes, (uint64_t{1} << 50) * 70);
  write_bytes(tmp / "b", b);
  expect_rejected(tmp / "b", "truncated");

  std::string c = bytes;  // a product that would overflow 64 bits
  patch<uint64_t>(c, kGaussianCount, std::numeric_limits<uint64_t>::max() / 35);
  patch<uint64_t>(c, kGaussianBytes, (std::numeric_limits<uint64_t>::max() / 35) * 70);
  write_bytes(tmp / "c", c);
  expect_rejected(tmp / "c", "corrupt header");

  for (const size_t field : {kObjectCount, kKeyframeCount}) {
    std::string d = bytes;
    patch<uint64_t>(d, field, uint64_t{1} << 40);
    write_bytes(tmp / "d", d);
    expect_rejected(tmp / "d", "corrupt header");
  }
}

TEST(MapFile, SaveIsAtomicAndFailsCleanly) {
  TempDir tmp;
  std::string error;
  const std::string path = tmp / "map.dqomap";
  ASSERT_TRUE(save_map_file(path, random_contents(9, 10), &error)) << error;
  const MapFileContents bigger = random_contents(10);
  ASSERT_TRUE(save_map_file(path, bigger, &error)) << error;  // replaces the old file
  const std::optional<MapFileContents> back = load_map_file(path, &error);
  ASSERT_TRUE(back) << error;
  EXPECT_EQ(back->gaussians.size(), bigger.gaussians.size());
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(tmp.path()))
    names.push_back(e.path().filename().string());
  EXPECT_EQ(names, std::vector<std::string>{"map.dqomap"});  // no temporary left

  const std::string missing = tmp / "no_such_folder/map.dqomap";
  EXPECT_FALSE(save_map_file(missing, bigger, &error));
  EXPECT_NE(error.find(missing), std::string::npos) << error;
  EXPECT_FALSE(std::filesystem::exists(tmp / "no_such_folder"));
}

TEST(MapFile, ParamsHashIsFnv1a64) {
  // Published FNV-1a 64 test vectors.
  EXPECT_EQ(params_hash(""), 0xcbf29ce484222325ull);
  EXPECT_EQ(params_hash("a"), 0xaf63dc4c8601ec8cull);
  EXPECT_EQ(params_hash("foobar"), 0x85944171f73967e8ull);
  EXPECT_NE(params_hash("budget: 500000\n"), params_hash("budget: 500001\n"));
}

}  // namespace
}  // namespace dqo::mapping
