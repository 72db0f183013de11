#include "dqo_map/io/mesh_io.h"

#include <functional>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "io_test_util.h"

namespace dqo {
namespace {

// A tetrahedron with faces counter-clockwise seen from outside.
TriangleMesh tetrahedron() {
  TriangleMesh mesh;
  mesh.vertices = {{0.1, 0.2, 0.3}, {1.0 / 3.0, 0.0, 0.0}, {0.0, 2.0 / 7.0, 0.0},
                   {0.0, 0.0, 1e-7}};
  mesh.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  return mesh;
}

TEST(MeshIo, PlyRoundTripIsExact) {
  test::TempDir tmp;
  const TriangleMesh mesh = tetrahedron();
  std::string error;
  ASSERT_TRUE(save_mesh_ply(tmp / "tet.ply", mesh, &error)) << error;
  const auto loaded = load_mesh(tmp / "tet.ply", &error);
  ASSERT_TRUE(loaded) << error;
  ASSERT_EQ(loaded->vertices.size(), mesh.vertices.size());
  for (size_t i = 0; i < mesh.vertices.size(); ++i) {
    EXPECT_EQ(loaded->vertices[i], mesh.vertices[i]) << "vertex " << i;  // doubles in the file
  }
  EXPECT_EQ(loaded->triangles, mesh.triangles);
  EXPECT_TRUE(loaded->colours.empty());
  // Nothing but the mesh is left in the folder (the temporary file was renamed).
  int files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(tmp.path())) {
    (void)entry;
    ++files;
  }
  EXPECT_EQ(files, 1);
}

TEST(MeshIo, PlyKeepsVertexColoursToEightBits) {
  test::TempDir tmp;
  TriangleMesh mesh = tetrahedron();
  mesh.colours = {{1.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, {0.0, 0.0, 1.0}, {0.2, 0.4, 0.6}};
  std::string error;
  ASSERT_TRUE(save_mesh_ply(tmp / "c.ply", mesh, &error)) << error;
  const auto loaded = load_mesh(tmp / "c.ply", &error);
  ASSERT_TRUE(loaded) << error;
  ASSERT_EQ(loaded->colours.size(), 4u);
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_LT((loaded->colours[i] - mesh.colours[i]).cwiseAbs().maxCoeff(), 0.5 / 255 + 1e-9);
  }
}

TEST(MeshIo, ObjIsLoadedWithItsVerticesAndTriangles) {
  test::TempDir tmp;
  // A unit square as two triangles and a quad face that must be split in two.
  test::write_text(tmp / "sq.obj",
                   "# square\n"
                   "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                   "v 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
                   "f 1 2 3\nf 1 3 4\n"
                   "f 5 6 7 8\n");
  std::string error;
  const auto mesh = load_mesh(tmp / "sq.obj", &error);
  ASSERT_TRUE(mesh) << error;
  ASSERT_EQ(mesh->triangles.size(), 4u);
  // The loader may reorder or duplicate vertices: compare triangles by their corner positions.
  const Eigen::Vector3d expected[4][3] = {{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}},
                                          {{0, 0, 0}, {1, 1, 0}, {0, 1, 0}},
                                          {{0, 0, 1}, {1, 0, 1}, {1, 1, 1}},
                                          {{0, 0, 1}, {1, 1, 1}, {0, 1, 1}}};
  double total_area = 0.0;
  for (int t = 0; t < 4; ++t) {
    const auto& tri = mesh->triangles[t];
    const Eigen::Vector3d a = mesh->vertices[tri[0]], b = mesh->vertices[tri[1]],
                          c = mesh->vertices[tri[2]];
    const Eigen::Vector3d n = (b - a).cross(c - a);
    EXPECT_GT(n.z(), 0.0) << "triangle " << t << " lost its counter-clockwise order";
    total_area += 0.5 * n.norm();
    if (t < 2) {
      for (int k = 0; k < 3; ++k) EXPECT_EQ(mesh->vertices[tri[k]], expected[t][k]);
    }
  }
  EXPECT_DOUBLE_EQ(total_area, 2.0);
  EXPECT_TRUE(mesh->colours.empty()) << "an OBJ without colours must give none";
}

TEST(MeshIo, GarbagePlyIsAnErrorNamingTheFile) {
  test::TempDir tmp;
  test::write_text(tmp / "bad.ply", "this is not a ply file\n\x01\x02\x03 garbage\n");
  std::string error;
  EXPECT_FALSE(load_mesh(tmp / "bad.ply", &error));
  EXPECT_NE(error.find(tmp / "bad.ply"), std::string::npos) << error;
}

TEST(MeshIo, TruncatedPlyIsAnError) {
  test::TempDir tmp;
  test::write_text(tmp / "cut.ply",
                   "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                   "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                   "end_header\n0 0 0\n1 0 0\n");
  std::string error;
  EXPECT_FALSE(load_mesh(tmp / "cut.ply", &error));
  EXPECT_NE(error.find("cut.ply"), std::string::npos) << error;
}

TEST(MeshIo, PointCloudPlyHasNoTrianglesAndIsAnError) {
  test::TempDir tmp;
  test::write_text(tmp / "pts.ply",
                   "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                   "property float z\nend_header\n0 0 0\n1 0 0\n");
  std::string error;
  EXPECT_FALSE(load_mesh(tmp / "pts.ply", &error));
  EXPECT_NE(error.find("no triangles"), std::string::npos) << error;
}

TEST(MeshIo, MissingFileAndUnknownExtensionAreErrors) {
  test::TempDir tmp;
  std::string error;
  EXPECT_FALSE(load_mesh(tmp / "none.ply", &error));
  EXPECT_NE(error.find("none.ply"), std::string::npos) << error;
  test::write_text(tmp / "mesh.xyz", "0 0 0\n");
  EXPECT_FALSE(load_mesh(tmp / "mesh.xyz", &error));
  EXPECT_NE(error.find("mesh.xyz"), std::string::npos) << error;
}

TEST(MeshIo, SaveRejectsBadIndicesAndLeavesNoFile) {
  test::TempDir tmp;
  TriangleMesh mesh = tetrahedron();
  mesh.triangles.push_back({0, 1, 4});
  std::string error;
  EXPECT_FALSE(save_mesh_ply(tmp / "bad.ply", mesh, &error));
  EXPECT_FALSE(std::filesystem::exists(tmp / "bad.ply"));
}

TEST(MeshIo, LoadMeshFitsTheMeshLoaderSignature) {
  // sim/'s hook type (sim/scene_loader.h).
  using MeshLoader =
      std::function<std::optional<TriangleMesh>(const std::string& path, std::string* error)>;
  const MeshLoader loader = &load_mesh;
  std::string error;
  EXPECT_FALSE(loader("/nonexistent/mesh.ply", &error));
}

}  // namespace
}  // namespace dqo
