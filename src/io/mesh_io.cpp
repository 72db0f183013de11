// The only file of the package that includes Open3D's I/O headers (they are slow to compile).
#include "dqo_map/io/mesh_io.h"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <system_error>

#include <open3d/geometry/TriangleMesh.h>
#include <open3d/io/TriangleMeshIO.h>

#include "text_util.h"

namespace dqo {

using io_detail::fail;
namespace fs = std::filesystem;

namespace {

std::string lower_extension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

}  // namespace

std::optional<TriangleMesh> load_mesh(const std::string& path, std::string* error) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) {
    fail(error, path + ": mesh file not found");
    return std::nullopt;
  }
  const std::string ext = lower_extension(path);
  if (ext != ".ply" && ext != ".obj" && ext != ".stl" && ext != ".off") {
    fail(error, path + ": unsupported mesh format '" + ext + "' (expected .ply or .obj)");
    return std::nullopt;
  }
  open3d::geometry::TriangleMesh o3d;
  bool ok = false;
  try {
    // Open3D's generic path reads OBJ through ASSIMP, which in this build drops every sub-mesh
    // that mixes triangles with quads; its own OBJ reader (tinyobjloader) triangulates them.
    if (ext == ".obj") {
      ok = open3d::io::ReadTriangleMeshFromOBJ(path, o3d, open3d::io::ReadTriangleMeshOptions());
    } else {
      ok = open3d::io::ReadTriangleMesh(path, o3d);
    }
  } catch (const std::exception& e) {
    fail(error, path + ": cannot parse mesh: " + e.what());
    return std::nullopt;
  }
  // Open3D returns true for some files it could not make sense of (a PLY without a face element
  // reads as an empty mesh), so emptiness is checked as well.
  if (!ok) {
    fail(error, path + ": cannot parse mesh (not a valid " + ext.substr(1) + " file)");
    return std::nullopt;
  }
  if (o3d.triangles_.empty()) {
    fail(error, path + ": mesh has no triangles (empty, a point cloud, or unparsable)");
    return std::nullopt;
  }

  TriangleMesh mesh;
  mesh.vertices = o3d.vertices_;
  const int num_vertices = static_cast<int>(mesh.vertices.size());
  for (const Eigen::Vector3d& v : mesh.vertices) {
    if (!v.allFinite()) {
      fail(error, path + ": mesh has a vertex that is not finite");
      return std::nullopt;
    }
  }
  mesh.triangles.reserve(o3d.triangles_.size());
  for (const Eigen::Vector3i& t : o3d.triangles_) {
    for (int k = 0; k < 3; ++k) {
      if (t[k] < 0 || t[k] >= num_vertices) {
        fail(error, path + ": triangle index " + std::to_string(t[k]) + " outside the " +
                        std::to_string(num_vertices) + " vertices");
        return std::nullopt;
      }
    }
    mesh.triangles.push_back({t[0], t[1], t[2]});
  }
  if (o3d.HasVertexColors()) {
    mesh.colours = o3d.vertex_colors_;
    // The OBJ loader gives every vertex the colour (1, 1, 1) when the file has none; that is no
    // colour information, and keeping it would override an object's configured colour.
    if (ext == ".obj" &&
        std::all_of(mesh.colours.begin(), mesh.colours.end(),
                    [](const Eigen::Vector3d& c) { return c == Eigen::Vector3d::Ones(); })) {
      mesh.colours.clear();
    }
  }
  return mesh;
}

bool save_mesh_ply(const std::string& path, const TriangleMesh& mesh, std::string* error) {
  if (lower_extension(path) != ".ply") {
    return fail(error, path + ": save_mesh_ply needs a .ply file name");
  }
  const int num_vertices = static_cast<int>(mesh.vertices.size());
  for (const auto& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      if (t[k] < 0 || t[k] >= num_vertices) {
        return fail(error, path + ": triangle index " + std::to_string(t[k]) +
                               " outside the " + std::to_string(num_vertices) + " vertices");
      }
    }
  }
  if (!mesh.colours.empty() && mesh.colours.size() != mesh.vertices.size()) {
    return fail(error, path + ": mesh has " + std::to_string(mesh.colours.size()) +
                           " colours for " + std::to_string(num_vertices) + " vertices");
  }

  open3d::geometry::TriangleMesh o3d;
  o3d.vertices_ = mesh.vertices;
  o3d.triangles_.reserve(mesh.triangles.size());
  for (const auto& t : mesh.triangles) o3d.triangles_.emplace_back(t[0], t[1], t[2]);
  o3d.vertex_colors_ = mesh.colours;

  // Open3D picks the format from the extension, so the temporary name keeps ".ply".
  const fs::path target(path);
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::string tmp = (dir / ("." + target.stem().string() + ".tmp-XXXXXX.ply")).string();
  const int fd = ::mkstemps(tmp.data(), 4);
  if (fd < 0) return fail(error, path + ": cannot create a temporary file beside it");
  ::close(fd);
  bool ok = false;
  try {
    ok = open3d::io::WriteTriangleMesh(tmp, o3d, /*write_ascii=*/false, /*compressed=*/false,
                                       /*write_vertex_normals=*/false,
                                       /*write_vertex_colors=*/!mesh.colours.empty(),
                                       /*write_triangle_uvs=*/false);
  } catch (const std::exception& e) {
    ::unlink(tmp.c_str());
    return fail(error, path + ": cannot write mesh: " + e.what());
  }
  if (!ok) {
    ::unlink(tmp.c_str());
    return fail(error, path + ": cannot write mesh");
  }
  std::error_code ec;
  fs::permissions(tmp,
                  fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read |
                      fs::perms::others_read,
                  ec);
  fs::rename(tmp, target, ec);
  if (ec) {
    ::unlink(tmp.c_str());
    return fail(error, path + ": cannot rename the temporary file into place: " + ec.message());
  }
  return true;
}

}  // namespace dqo
