// Names under the output folder: what stays inside is resolved, what leads out is refused.

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "../io/io_test_util.h"  // TempDir: plain C++
#include "dqo_map/common/output_path.h"

namespace dqo {
namespace {

namespace fs = std::filesystem;

TEST(OutputPath, NamesInsideResolveUnderTheRoot) {
  test::TempDir dir;
  const std::string root = dir / "out";  // need not exist yet
  std::string error;
  auto p = resolve_output_path(root, "map.dqomap", &error);
  ASSERT_TRUE(p) << error;
  EXPECT_EQ(*p, fs::weakly_canonical(fs::path(root) / "map.dqomap").string());
  p = resolve_output_path(root, "a/b/../c/object_3_mesh.ply", &error);
  ASSERT_TRUE(p) << error;
  EXPECT_EQ(fs::path(*p).filename(), "object_3_mesh.ply");
  EXPECT_EQ(fs::path(*p).parent_path().filename(), "c");
  EXPECT_TRUE(resolve_output_path(root, "./x", &error));
  EXPECT_TRUE(resolve_output_path(root, "", &error, true));  // the folder itself, when allowed
  EXPECT_FALSE(fs::exists(root)) << "nothing is created";
}

TEST(OutputPath, EscapesAreRefused) {
  test::TempDir dir;
  const std::string root = dir / "out";
  fs::create_directories(root);
  std::string error;
  EXPECT_FALSE(resolve_output_path(root, "../x", &error));
  EXPECT_NE(error.find("outside the output folder"), std::string::npos) << error;
  EXPECT_FALSE(resolve_output_path(root, "a/../../x", &error));
  EXPECT_FALSE(resolve_output_path(root, "/etc/passwd", &error));
  EXPECT_NE(error.find("absolute"), std::string::npos) << error;
  EXPECT_FALSE(resolve_output_path(root, "", &error));
  EXPECT_FALSE(resolve_output_path(root, ".", &error));  // the folder itself is no file
  // A sibling whose name starts like the root's is outside it.
  fs::create_directories(dir / "out2");
  EXPECT_FALSE(resolve_output_path(root, "../out2/x", &error));
  // A symlink inside the root that leads out.
  fs::create_directory_symlink(dir.path(), fs::path(root) / "up");
  EXPECT_FALSE(resolve_output_path(root, "up/x", &error));
  EXPECT_NE(error.find("outside"), std::string::npos) << error;
  // A symlink that stays inside is fine.
  fs::create_directories(fs::path(root) / "real");
  fs::create_directory_symlink(fs::path(root) / "real", fs::path(root) / "alias");
  EXPECT_TRUE(resolve_output_path(root, "alias/x", &error)) << error;
  EXPECT_FALSE(resolve_output_path("", "x", &error));
}

}  // namespace
}  // namespace dqo
